// The flake material in whole renders: the average brightness does not depend on resolution
// (the footprint logic must not change the mean), and glints stay on the same surface points when
// the camera moves by a fraction of a pixel (no flicker between frames).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_flake_render {
namespace {

FrameResult render_plane(const std::string& scene, uint32_t size) {
    FrameRequest req = test::quiet_request(scene);
    req.options.width_override = req.options.height_override = size;
    return render_frame(req);
}

std::vector<double> luminance_of(const FrameResult& r) {
    std::vector<double> l(r.image.size() / 3);
    for (std::size_t i = 0; i < l.size(); ++i)
        l[i] = 0.2126 * r.image[3 * i] + 0.7152 * r.image[3 * i + 1] + 0.0722 * r.image[3 * i + 2];
    return l;
}

std::pair<double, double> mean_and_se(const std::vector<double>& v) {
    double s = 0, s2 = 0;
    for (double x : v) {
        s += x;
        s2 += x * x;
    }
    const double n = static_cast<double>(v.size()), m = s / n;
    return {m, std::sqrt(std::max(0.0, s2 / n - m * m) / n)};
}

TEST(FlakeRender, MeanBrightnessDoesNotDependOnResolution) {
    const std::string scene = test::test_dir() + "/scenes/flake_plane.toml";
    const auto [m_lo, se_lo] = mean_and_se(luminance_of(render_plane(scene, 64)));
    const auto [m_hi, se_hi] = mean_and_se(luminance_of(render_plane(scene, 128)));
    ASSERT_GT(m_lo, 0.05) << "the plane glitters";
    // Independent-noise standard error (conservative: both images see the same flakes), plus 2%
    // for the O(1 / lambda) bias of normalising by the actual flake weights (lambda 150 to 600).
    // The seed report's implementation changed the mean 4.8x between two resolutions.
    EXPECT_NEAR(m_lo, m_hi, 4.0 * std::hypot(se_lo, se_hi) + 0.02 * m_hi) << "64^2 vs 128^2";
}

/** The plane scene with the camera (and its target) moved sideways by dx metres, or another seed.
 */
std::string variant(const std::string& dir, double dx, int seed) {
    std::ifstream in(test::test_dir() + "/scenes/flake_plane.toml");
    std::stringstream ss;
    ss << in.rdbuf();
    std::string s = ss.str();
    const auto replace = [&](const std::string& from, const std::string& to) {
        const std::size_t at = s.find(from);
        if (at != std::string::npos) s.replace(at, from.size(), to);
    };
    replace("position = [0, 0, 3]", fmt::format("position = [{}, 0, 3]", dx));
    replace("look_at = [0, 0, 0]", fmt::format("look_at = [{}, 0, 0]", dx));
    replace("max_flakes = 10000 }", fmt::format("max_flakes = 10000, seed = {} }}", seed));
    replace("../../assets/", test::asset_dir() + "/");
    const std::string path = fmt::format("{}/plane_{}_{}.toml", dir, dx, seed);
    std::ofstream(path) << s;
    return path;
}

/** Bright-pixel mask: pixels above 3x the image's median luminance. */
std::vector<uint8_t> bright(const std::vector<double>& lum) {
    std::vector<double> sorted(lum);
    std::nth_element(sorted.begin(),
                     sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double median = sorted[sorted.size() / 2];
    std::vector<uint8_t> m(lum.size());
    for (std::size_t i = 0; i < lum.size(); ++i) m[i] = lum[i] > 3.0 * median;
    return m;
}

/** Resamples an image shifted by `shift` pixels to the right (bilinear in x). */
std::vector<double> reproject(const std::vector<double>& lum, int w, int h, double shift) {
    std::vector<double> out(lum.size(), 0.0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double sx = x - shift;
            const int x0 = static_cast<int>(std::floor(sx));
            const double t = sx - x0;
            const auto at = [&](int xx) {
                return lum[static_cast<std::size_t>(y * w + std::clamp(xx, 0, w - 1))];
            };
            out[static_cast<std::size_t>(y * w + x)] = at(x0) * (1.0 - t) + at(x0 + 1) * t;
        }
    return out;
}

double jaccard(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b, int w, int h) {
    // Ignore a 2-pixel border, where reprojection clamps.
    int both = 0, either = 0;
    for (int y = 2; y < h - 2; ++y)
        for (int x = 2; x < w - 2; ++x) {
            const std::size_t i = static_cast<std::size_t>(y * w + x);
            both += a[i] && b[i];
            either += a[i] || b[i];
        }
    return either ? static_cast<double>(both) / either : 0.0;
}

double correlation(const std::vector<double>& a, const std::vector<double>& b, int w) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = 0;
    for (int y = 2; y < w - 2; ++y)
        for (int x = 2; x < w - 2; ++x) {
            const std::size_t i = static_cast<std::size_t>(y * w + x);
            sa += a[i];
            sb += b[i];
            saa += a[i] * a[i];
            sbb += b[i] * b[i];
            sab += a[i] * b[i];
            n += 1;
        }
    const double cov = sab / n - sa / n * sb / n;
    return cov / std::sqrt((saa / n - sa / n * sa / n) * (sbb / n - sb / n * sb / n));
}

TEST(FlakeRender, GlintsStayPutWhenTheCameraMovesByAFractionOfAPixel) {
    test::TempDir dir("flake_frames");
    constexpr int kSize = 96;
    // One pixel at distance 3 with a 20 degree field of view, 96 pixels high.
    const double pixel = 2.0 * 3.0 * std::tan(10.0 * M_PI / 180.0) / kSize;
    const double step = 0.3;  // pixels per frame
    std::vector<std::vector<double>> frames;
    for (int k = 0; k < 3; ++k)
        frames.push_back(
            luminance_of(render_plane(variant(dir.path().string(), k * step * pixel, 0), kSize)));
    const auto other_seed = luminance_of(render_plane(variant(dir.path().string(), 0.0, 1), kSize));
    const auto mask0 = bright(frames[0]);
    const double control = jaccard(mask0, bright(other_seed), kSize, kSize);
    for (int k = 1; k < 3; ++k) {
        // Moving the camera right moves the image of the plane left by k * step pixels.
        const auto back = reproject(frames[static_cast<std::size_t>(k)], kSize, kSize, k * step);
        const double j = jaccard(mask0, bright(back), kSize, kSize);
        const double corr = correlation(frames[0], back, kSize);
        const double corr_control = correlation(frames[0], other_seed, kSize);
        // Glints that stay on their surface points correlate strongly after reprojection (about
        // 0.9 measured); another realisation of flakes does not (about 0.1). The overlap of
        // thresholded bright masks is a noisier statistic (16 spp, bilinear reprojection): it
        // must still beat another realisation's overlap several times over.
        EXPECT_GT(corr, 0.8) << "frame " << k << ": glints moved";
        EXPECT_GT(corr, 4.0 * corr_control) << "frame " << k;
        EXPECT_GT(j, 4.0 * control)
            << "frame " << k << " vs another realisation of flakes: " << control;
        RecordProperty(fmt::format("frame{}", k),
                       fmt::format("correlation {:.3f} jaccard {:.3f}", corr, j));
    }
    RecordProperty("jaccard_other_seed", fmt::format("{:.3f}", control));
}

/** A copy of a test scene in `dir` with each (from, to) replaced once (all must be found), mesh
 *  paths made absolute. */
std::string edited_scene(const std::string& dir, const std::string& scene, const std::string& tag,
                         const std::vector<std::pair<std::string, std::string>>& edits) {
    std::ifstream in(test::test_dir() + "/scenes/" + scene);
    std::stringstream ss;
    ss << in.rdbuf();
    std::string s = ss.str();
    for (const auto& [from, to] : edits) {
        const std::size_t at = s.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        if (at != std::string::npos) s.replace(at, from.size(), to);
    }
    const auto abs = [&](const std::string& from, const std::string& to) {
        for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + 1))
            s.replace(at, from.size(), to);
    };
    abs("mesh = \"uvless_ball.obj\"", "mesh = \"" + test::test_dir() + "/scenes/uvless_ball.obj\"");
    abs("../../assets/", test::asset_dir() + "/");
    const std::string path = fmt::format("{}/{}_{}.toml", dir, scene, tag);
    std::ofstream(path) << s;
    return path;
}

/** The ratio of a's mean to b's over the pixels of rows [y0, y1) of a w-wide image where
 *  mask > 0, with its standard error: of a ratio estimator, from the residuals a - ratio b summed
 *  over 8 x 8 blocks (so that the highlight's shape does not count as noise, and neighbouring
 *  pixels, which share flakes and aggregated cells, are not counted as independent). */
struct Ratio {
    double ratio = 0, se = 0;
    std::size_t pixels = 0;
};
Ratio mean_ratio(const std::vector<double>& a, const std::vector<double>& b,
                 const std::vector<double>& mask, int w, int y0, int y1) {
    constexpr int kBlock = 8;
    double sa = 0, sb = 0;
    std::size_t n = 0;
    const auto at = [&](int x, int y) { return static_cast<std::size_t>(y * w + x); };
    for (int y = y0; y < y1; ++y)
        for (int x = 0; x < w; ++x) {
            if (!(mask[at(x, y)] > 1e-6)) continue;
            sa += a[at(x, y)];
            sb += b[at(x, y)];
            ++n;
        }
    Ratio r;
    r.pixels = n;
    if (n == 0 || !(sb > 0)) return r;
    r.ratio = sa / sb;
    double d2 = 0;
    for (int by = y0; by < y1; by += kBlock)
        for (int bx = 0; bx < w; bx += kBlock) {
            double d = 0;
            for (int y = by; y < std::min(by + kBlock, y1); ++y)
                for (int x = bx; x < std::min(bx + kBlock, w); ++x)
                    if (mask[at(x, y)] > 1e-6) d += a[at(x, y)] - r.ratio * b[at(x, y)];
            d2 += d * d;
        }
    r.se = std::sqrt(d2) / sb;
    return r;
}

TEST(FlakeRender, MeshWithoutUvsGlittersInObjectSpace) {
    // A ball whose mesh has no uvs, flakes laid out by object-space position. It glitters (many
    // pixels far above the smooth render), its mean is the smooth limit's, and the same glints
    // come back when the ball, the camera and the light all move together.
    test::TempDir dir("flake_uvless");
    constexpr int kSize = 96;
    const auto render = [&](const std::string& tag,
                            const std::vector<std::pair<std::string, std::string>>& edits) {
        return luminance_of(render_plane(
            edited_scene(dir.path().string(), "flake_uvless.toml", tag, edits), kSize));
    };
    const auto disc = render("disc", {});
    const auto smooth = render("smooth", {{"min_flakes = 100000000, max_flakes = 1000000000",
                                           "min_flakes = 0, max_flakes = 1"}});
    const Ratio r = mean_ratio(disc, smooth, smooth, kSize, 0, kSize);
    ASSERT_GT(r.pixels, 3000u) << "the ball covers the middle of the image";
    std::size_t glints = 0;
    for (std::size_t i = 0; i < disc.size(); ++i)
        glints += smooth[i] > 1e-6 && disc[i] > 4.0 * smooth[i];
    EXPECT_GT(glints, 100u) << "glints: pixels far brighter than the smooth limit";
    EXPECT_NEAR(r.ratio, 1.0, 4.0 * r.se + 0.01) << "discrete / smooth mean, +- " << r.se;
    {
        // The ball with every corner's uv (0, 0), as exporters write a mesh without a uv map:
        // "auto" lays its flakes out in object space as for no uvs. Its footprint was dropped
        // with the uv solve (a few flakes a pixel): a smooth sheen, no glint, no word.
        std::ifstream in(test::test_dir() + "/scenes/uvless_ball.obj");
        std::ofstream out(dir.file("zero_uv_ball.obj"));
        out << "vt 0 0\n";
        for (std::string line; std::getline(in, line);) {
            if (line.starts_with("f "))
                for (std::size_t at = line.find("//"); at != std::string::npos;
                     at = line.find("//", at))
                    line.replace(at, 2, "/1/");
            out << line << "\n";
        }
        out.close();
        const auto zero = render("zero_uv", {{"mesh = \"uvless_ball.obj\"",
                                              "mesh = \"" + dir.file("zero_uv_ball.obj") + "\""}});
        std::size_t zero_glints = 0;
        for (std::size_t i = 0; i < zero.size(); ++i)
            zero_glints += smooth[i] > 1e-6 && zero[i] > 4.0 * smooth[i];
        EXPECT_GT(zero_glints, glints / 2) << "a mesh with all-zero uvs glitters too";
        const Ratio rz = mean_ratio(zero, smooth, smooth, kSize, 0, kSize);
        EXPECT_NEAR(rz.ratio, 1.0, 4.0 * rz.se + 0.01) << "all-zero uvs: +- " << rz.se;
    }
    const auto moved =
        render("moved", {{"position = [0, 0, 4]", "position = [3, -2, 9]"},
                         {"look_at = [0, 0, 0]", "look_at = [3, -2, 5]"},
                         {"rotate = [30, 20, 0]", "rotate = [30, 20, 0]\ntranslate = [3, -2, 5]"},
                         {"center = [0.8, 0.6, 4.2]", "center = [3.8, -1.4, 9.2]"}});
    const auto other =
        render("seed", {{"max_flakes = 1000000000", "max_flakes = 1000000000, seed = 7"}});
    // The glints are what is left after taking away the smooth limit (the highlight's shape, which
    // every realisation shares).
    const auto glint = [&](const std::vector<double>& img) {
        std::vector<double> g(img.size());
        for (std::size_t i = 0; i < img.size(); ++i) g[i] = img[i] - r.ratio * smooth[i];
        return g;
    };
    const double corr = correlation(glint(disc), glint(moved), kSize),
                 control = correlation(glint(disc), glint(other), kSize);
    EXPECT_GT(corr, 0.95) << "the glints moved with the ball";
    EXPECT_LT(control, 0.3) << "another realisation of flakes has other glints";
    RecordProperty("mean_ratio", fmt::format("{:.4f} +- {:.4f}", r.ratio, r.se));
    RecordProperty("correlation", fmt::format("moved {:.3f}, other seed {:.3f}", corr, control));
}

TEST(FlakeRender, UvsOfAnyMagnitudeKeepTheFlakeLobe) {
    // A quad whose uvs span 1e8 (or 1e20) over 1.2 m: every footprint holds far more flakes than
    // max_flakes, so the render is the smooth limit, as at uvs 0..1 with the same density per
    // uv square made dense. The uv solve's fixed floor on its determinant (1e-30; products of
    // |dp/du| ~ 1e-8 fell below it) and a float overflow of the uv determinant beyond 1e19 gave
    // those triangles no uv footprint: no flakes at all, the image 12% darker, no word.
    test::TempDir dir("flake_big_uvs");
    // The uvs a sheared parallelogram (both products of the uv determinant overflow a float
    // at 1e20, to inf - inf: NaN), or an axis-aligned square (span < 0).
    const auto quad = [&](double span) {
        const std::string path = dir.file(fmt::format("quad_{}.obj", span));
        const double s = std::fabs(span);
        if (span < 0)
            std::ofstream(path) << fmt::format(
                "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt {0} 0\nvt {0} {0}\n"
                "vt 0 {0}\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
                s);
        else
            std::ofstream(path) << fmt::format(
                "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt {} {}\nvt {} {}\n"
                "vt {} {}\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
                2 * s, s, 3 * s, 3 * s, s, 2 * s);
        return path;
    };
    const auto render = [&](double span, const std::string& blend) {
        return luminance_of(render_plane(
            edited_scene(
                dir.path().string(), "flake_plane.toml", fmt::format("q{}", span),
                {{"mesh = \"../../assets/meshes/plane.ply\"", "mesh = \"" + quad(span) + "\""},
                 {"rotate = [90, 0, 0]\n", ""},
                 {"min_flakes = 5000, max_flakes = 10000", blend}}),
            32));
    };
    const auto smooth = render(1.0, "min_flakes = 0, max_flakes = 1");
    double m_smooth = 0.0;
    for (const double v : smooth) m_smooth += v;
    ASSERT_GT(m_smooth, 0.0);
    for (const double span : {1e8, -1e8, 1e20, -1e20}) {
        const auto img = render(span, "min_flakes = 5000, max_flakes = 10000");
        double m = 0.0;
        for (const double v : img) m += v;
        EXPECT_NEAR(m / m_smooth, 1.0, 1e-3) << "uvs spanning " << span;
    }
}

TEST(FlakeRender, AModelInMillimetresGlittersAsInMetres) {
    // The flake plane as a CAD model would hold it, in millimetres, painted with 1 flake per
    // square millimetre, against the same plane in metres at 1e6 per square metre: the same
    // flakes per pixel. Object-space tiles were one unit: on the millimetre model every pixel's
    // footprint spanned dozens of 1 mm tiles, past what the tree handles, and the whole plane
    // rendered the smooth lobe: no glint. Tiles now hold at least 4096 flakes.
    test::TempDir dir("flake_mm");
    const auto render = [&](const std::string& unit, double k) {
        const std::string mesh = dir.file("quad_" + unit + ".obj");
        std::ofstream(mesh) << fmt::format(
            "v -{0} -{0} 0\nv {0} -{0} 0\nv {0} {0} 0\nv -{0} {0} 0\nf 1 2 3\nf 1 3 4\n", 0.6 * k);
        return luminance_of(render_plane(
            edited_scene(dir.path().string(), "flake_plane.toml", unit,
                         {{"mesh = \"../../assets/meshes/plane.ply\"", "mesh = \"" + mesh + "\""},
                          {"rotate = [90, 0, 0]\nscale = 0.6\n", ""},
                          {"position = [0, 0, 3]", fmt::format("position = [0, 0, {}]", 3 * k)},
                          {"center = [0.4, 0.3, 3.2]",
                           fmt::format("center = [{}, {}, {}]", 0.4 * k, 0.3 * k, 3.2 * k)},
                          {"radius = 0.03", fmt::format("radius = {}", 0.03 * k)},
                          {"density = 200000", fmt::format("density = {}", 1e6 / (k * k))},
                          {"min_flakes = 5000", "density_space = \"object\", min_flakes = 5000"}}),
            64));
    };
    // The spread of pixel values over their mean: glitter is grainy, the smooth lobe is not.
    const auto grain = [](const std::vector<double>& img) {
        const auto [m, se] = mean_and_se(img);
        return se * std::sqrt(static_cast<double>(img.size())) / m;
    };
    const auto metres = render("m", 1.0), mm = render("mm", 1000.0);
    const double g_m = grain(metres), g_mm = grain(mm);
    ASSERT_GT(g_m, 0.5) << "the plane in metres glitters";
    EXPECT_GT(g_mm, 0.7 * g_m) << "metres " << g_m << ", millimetres " << g_mm;
    EXPECT_NEAR(mean_and_se(mm).first / mean_and_se(metres).first, 1.0, 0.05);
}

TEST(FlakeRender, BlendBandIsInvisibleInRowMeans) {
    // A plane receding to the horizon with wide cones (gamma 10): the discrete lobe near the
    // camera, the smooth lobe far away, the blend between them in the middle rows. Each band of
    // rows on the plane has the mean of the smooth-forced render (the audit found 0.88 to 1.30
    // when the smooth lobe was not the discrete lobe's expectation).
    test::TempDir dir("flake_receding");
    constexpr int kW = 128, kH = 96;
    const auto render = [&](const std::string& tag,
                            const std::vector<std::pair<std::string, std::string>>& edits) {
        return luminance_of(render_frame(test::quiet_request(
            edited_scene(dir.path().string(), "flake_receding.toml", tag, edits))));
    };
    const auto blended = render("blended", {});
    const auto smooth = render(
        "smooth", {{"min_flakes = 500, max_flakes = 2000", "min_flakes = 0, max_flakes = 1"}});
    // The plane fills the rows below the horizon (row 41 of 96 with this camera).
    constexpr int kBand = 4;
    std::string rows;
    for (int y0 = 44; y0 + kBand <= kH; y0 += kBand) {
        const Ratio r = mean_ratio(blended, smooth, smooth, kW, y0, y0 + kBand);
        if (r.pixels < 64) continue;
        EXPECT_NEAR(r.ratio, 1.0, 0.01 + 3.0 * r.se) << "rows " << y0 << " to " << y0 + kBand - 1;
        rows += fmt::format("{}:{:.3f}+-{:.3f} ", y0, r.ratio, r.se);
    }
    RecordProperty("row_band_ratios", rows);
}

/** The texture of glitter in an image: how often a pixel is dark, how much pixels spread, how
 *  wide a glint is. */
struct GlintTexture {
    double dark = 0.0;  ///< share of pixels under half the mean
    double cv = 0.0;    ///< standard deviation over the mean
    double run = 0.0;   ///< mean length of a row's run of pixels brighter than twice its row mean
};

GlintTexture glint_texture(const std::vector<double>& l, int w, int h) {
    GlintTexture g;
    double s = 0.0, s2 = 0.0;
    for (double x : l) {
        s += x;
        s2 += x * x;
    }
    const double n = static_cast<double>(l.size()), mean = s / n;
    g.cv = std::sqrt(std::max(0.0, s2 / n - mean * mean)) / mean;
    double dark = 0.0, runs = 0.0, run_pixels = 0.0;
    for (double x : l) dark += x < 0.5 * mean ? 1.0 : 0.0;
    g.dark = dark / n;
    for (int y = 0; y < h; ++y) {
        double row = 0.0;
        for (int x = 0; x < w; ++x) row += l[static_cast<std::size_t>(y * w + x)];
        row /= w;
        int run = 0;
        for (int x = 0; x <= w; ++x) {
            if (x < w && l[static_cast<std::size_t>(y * w + x)] > 2.0 * row) {
                ++run;
                continue;
            }
            if (run > 0) {
                runs += 1.0;
                run_pixels += run;
            }
            run = 0;
        }
    }
    g.run = runs > 0.0 ? run_pixels / runs : 0.0;
    return g;
}

TEST(FlakeRender, GrazingGlintsArePointsAsTheEnumerationsAre) {
    // The receding plane's distant band (640x360, 16 spp, pixels 480..600 x 190..250): dense
    // flakes at grazing views, counted in aggregates by the default algorithm. The enumeration
    // sparkles there with dark gaps; the counting algorithm's stand-ins used to give a grey floor
    // (pixels under half the mean 5.7% against 22.8%, spread 0.54 of the mean against 0.66)
    // with horizontal dashes (runs of 2.21 pixels against 1.76): 16 stand-ins at grazing views,
    // keyed by where the footprint lay in its cell, so that neighbours across the plane and the
    // samples of one pixel saw the same or independent ones where real flakes are partly shared.
    // Now 19.9%, 0.66, runs of 1.87.
    test::TempDir dir("flake_grazing");
    constexpr uint32_t kX0 = 480, kY0 = 190, kX1 = 600, kY1 = 250;
    const auto render = [&](const std::string& tag,
                            const std::vector<std::pair<std::string, std::string>>& edits) {
        FrameRequest req = test::quiet_request(
            edited_scene(dir.path().string(), "flake_receding.toml", tag, edits));
        req.options.width_override = 640;
        req.options.height_override = 360;
        req.options.crop = {kX0, kY0, kX1, kY1};
        const FrameResult r = render_frame(req);
        EXPECT_EQ(r.width, kX1 - kX0);
        EXPECT_EQ(r.height, kY1 - kY0);
        return glint_texture(luminance_of(r), static_cast<int>(kX1 - kX0),
                             static_cast<int>(kY1 - kY0));
    };
    const GlintTexture tree = render("tree", {});
    const GlintTexture flakes =
        render("enumerate", {{"min_flakes = 500", "algorithm = \"enumerate\", min_flakes = 500"}});
    RecordProperty("tree",
                   fmt::format("dark {:.3f} cv {:.3f} run {:.2f}", tree.dark, tree.cv, tree.run));
    RecordProperty("enumerate", fmt::format("dark {:.3f} cv {:.3f} run {:.2f}", flakes.dark,
                                            flakes.cv, flakes.run));
    ASSERT_GT(flakes.dark, 0.1) << "the band sparkles with dark gaps";
    EXPECT_GT(tree.dark, 0.75 * flakes.dark);
    EXPECT_NEAR(tree.cv, flakes.cv, 0.1 * flakes.cv);
    EXPECT_LT(tree.run, 1.15 * flakes.run) << "glints as wide as real ones";
    // Four times the stand-ins: closer still (21.8% dark, runs of 1.72; as many pixels brighter
    // than twice their row's mean as the enumeration has, where 64 stand-ins have 73% of them).
    const GlintTexture more =
        render("more", {{"min_flakes = 500", "stand_ins = 256, min_flakes = 500"}});
    RecordProperty("stand_ins_256",
                   fmt::format("dark {:.3f} cv {:.3f} run {:.2f}", more.dark, more.cv, more.run));
    EXPECT_GT(more.dark, 0.9 * flakes.dark);
    EXPECT_GT(more.dark, tree.dark);
    EXPECT_NEAR(more.run, flakes.run, 0.1 * flakes.run);
}

TEST(FlakeRender, ParametersOthersMakeInertAreSaid) {
    // coat_ior while the coat is off, a second population's colour at flakes2_weight 0, the tree's
    // stand_ins in an enumerating material: the render is as if they were not written. They were
    // taken without a word; now each is a warning at its material. A material whose parameters
    // all act says nothing.
    test::TempDir dir("flake_inert");
    std::ofstream(dir.file("s.toml")) << R"([render]
width = 8
height = 8
spp = 1

[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]

[[material]]
name = "inert"
plugin = "flake"
params = { coat_ior = 1.8, flakes2_color = [0.2, 0.4, 0.9], algorithm = "enumerate", stand_ins = 32, preset = "gold", fresnel = "schlick" }

[[material]]
name = "acting"
plugin = "flake"
params = { coat = true, coat_ior = 1.8, flakes2_weight = 0.2, flakes2_color = [0.2, 0.4, 0.9], fresnel = "conductor", preset = "gold" }

[[object]]
mesh = "ball.obj"
material = "inert"

[[object]]
mesh = "ball.obj"
material = "acting"
translate = [1, 0, 0]

[[light]]
type = "distant"
direction = [0, 0, -1]
intensity = 1
)";
    std::filesystem::copy_file(test::test_dir() + "/scenes/uvless_ball.obj", dir.file("ball.obj"));
    RenderOptions options;
    options.threads = 1;
    const Logger log{LogLevel::Warning};  // the session keeps a reference: it must outlive it
    Session session({}, test::shipped_ocio(), options, log);
    testing::internal::CaptureStderr();
    session.load(dir.file("s.toml"));
    const std::string said = testing::internal::GetCapturedStderr();
    const std::string at = dir.file("s.toml") + ":10:1: material 'inert': ";
    for (const std::string& warning :
         {at + "coat_ior has no effect: the coat is off",
          at + "flakes2_color has no effect: there is no second population",
          at + "stand_ins has no effect: they steer the tree algorithm",
          at + "preset has no effect: the preset is the metal of conductor flakes"})
        EXPECT_NE(said.find(warning), std::string::npos) << warning << "\nin:\n" << said;
    EXPECT_EQ(said.find("material 'acting'"), std::string::npos) << said;
    // A material the plugin refuses is not also warned of: film_thickness_min alone was said
    // to have no effect, then refused for the same reason.
    std::ifstream scene(dir.file("s.toml"));
    std::string refused{std::istreambuf_iterator<char>(scene), std::istreambuf_iterator<char>()};
    refused.replace(refused.find("params = { coat_ior"), 0,
                    "params = { film_thickness_min = 300 }\n# ");
    std::ofstream(dir.file("refused.toml")) << refused;
    testing::internal::CaptureStderr();
    EXPECT_THROW(session.load(dir.file("refused.toml")), SpangleError);
    const std::string said_refused = testing::internal::GetCapturedStderr();
    EXPECT_EQ(said_refused.find("has no effect"), std::string::npos) << said_refused;
}

}  // namespace
}  // namespace spangle::test_flake_render
