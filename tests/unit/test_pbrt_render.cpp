// pbrt scenes end to end: a pbrt-v3 and a pbrt-v4 scene render the image of their TOML twins
// (a per-block z-test), pbrt's camera conventions hold (points project where pbrt puts them, in
// the EXR's worldToNDC and in the rendered image), two-sided area lights emit from both faces,
// an inline cage read again is not subdivided again, and pbrt's environment layouts map
// directions as pbrt does.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numeric>

#include "core/hash.h"
#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "render/camera.h"
#include "render/lights.h"
#include "scene/pbrt/pbrt_reader.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "test_support.h"

namespace spangle::test_pbrt_render {
namespace {

/** The image a description renders to (working space RGB), on two threads. */
std::vector<float> render(const SceneDescription& d) {
    RenderOptions options;
    options.threads = 2;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(d);
    session.render();
    return session.result().image;
}

/** The scene file `name` of tests/scenes/pbrt with render seed `seed`. */
SceneDescription scene(const std::string& name, uint64_t seed) {
    SceneDescription d = read_scene(test::test_dir() + "/scenes/pbrt/" + name);
    d.render.seed = seed;
    return d;
}

/** The largest |z| over blocks of `block` x `block` pixels and channels between two scenes,
 *  each given as two renders of independent seeds. A block's mean has the variance of its
 *  pixels' (a1 - a2)^2 / 4 summed over n^2 pixels (pixels are independent: each pixel's samples
 *  depend on the pixel alone). */
double max_block_z(const std::vector<float>& a1, const std::vector<float>& a2,
                   const std::vector<float>& b1, const std::vector<float>& b2, uint32_t width,
                   uint32_t height, uint32_t block, std::size_t& blocks) {
    double worst = 0.0;
    blocks = 0;
    for (uint32_t by = 0; by + block <= height; by += block)
        for (uint32_t bx = 0; bx + block <= width; bx += block)
            for (int c = 0; c < 3; ++c) {
                double ma = 0, mb = 0, va = 0, vb = 0;
                const double n = static_cast<double>(block) * block;
                for (uint32_t y = by; y < by + block; ++y)
                    for (uint32_t x = bx; x < bx + block; ++x) {
                        const std::size_t i = 3 * (static_cast<std::size_t>(y) * width + x) + c;
                        ma += 0.5 * (a1[i] + a2[i]) / n;
                        mb += 0.5 * (b1[i] + b2[i]) / n;
                        va += (a1[i] - a2[i]) * (a1[i] - a2[i]) / (4.0 * n * n);
                        vb += (b1[i] - b2[i]) * (b1[i] - b2[i]) / (4.0 * n * n);
                    }
                ++blocks;
                // A block black in both (no light reaches it) has no variance to divide by.
                if (va + vb == 0.0) {
                    if (ma != mb) return 1e30;
                    continue;
                }
                worst = std::max(worst, std::fabs(ma - mb) / std::sqrt(va + vb));
            }
    return worst;
}

/** The z beyond which a block fails: Bonferroni over `blocks` two-sided tests at a family-wise
 *  rate of 1e-3 (4.8 for 324 tests), from the normal tail's bound. */
double critical_z(std::size_t blocks) {
    const double p = 1e-3 / (2.0 * static_cast<double>(blocks));
    double z = 3.0;
    while (0.5 * std::erfc(z / std::sqrt(2.0)) > p) z += 0.01;
    return z;
}

/** Renders the pbrt scene and its TOML twin at two seeds each and z-tests them; with
 *  `unmirror`, the pbrt camera's mirror is turned (a scene that must fail the test). */
double twin_z(const std::string& pbrt, const std::string& toml, bool unmirror, std::size_t& n) {
    SceneDescription p1 = scene(pbrt, 1), p2 = scene(pbrt, 2);
    if (unmirror) p1.camera.mirror = p2.camera.mirror = !p1.camera.mirror;
    const SceneDescription t1 = scene(toml, 3), t2 = scene(toml, 4);
    const uint32_t w = t1.render.width, h = t1.render.height;
    EXPECT_EQ(p1.render.width, w);
    EXPECT_EQ(p1.render.height, h);
    return max_block_z(render(p1), render(p2), render(t1), render(t2), w, h, 8, n);
}

TEST(PbrtRender, AV3SceneRendersAsItsTomlTwin) {
    // twin_v3.pbrt: pbrt's left-handed camera (mirrored image), matte, plastic and metal with
    // pbrt-v3's roughness remap, an inline mesh light, a PLY mesh, a box filter; its twin is the
    // mirrored world through a right-handed camera (tests/scenes/pbrt/make_twins.py).
    std::size_t n = 0;
    const double z = twin_z("twin_v3.pbrt", "twin_v3.toml", false, n);
    EXPECT_LT(z, critical_z(n)) << n << " blocks";
    // The test can fail: the same scene without pbrt's mirror is another picture.
    EXPECT_GT(twin_z("twin_v3.pbrt", "twin_v3.toml", true, n), 2.0 * critical_z(n));
}

TEST(PbrtRender, AV4SceneRendersAsItsTomlTwin) {
    // twin_v4.pbrt: a portrait film (fov on the width), Scale -1 1 1 before LookAt, diffuse with
    // an image texture (uscale), coateddiffuse and a named-metal conductor with pbrt-v4's
    // remap, distant, infinite and area lights, v4's default Gaussian filter.
    std::size_t n = 0;
    const double z = twin_z("twin_v4.pbrt", "twin_v4.toml", false, n);
    EXPECT_LT(z, critical_z(n)) << n << " blocks";
}

/** Where pbrt puts world point p on a w x h film (raster pixels, y down): its LookAt, its
 *  perspective projection with fov on the shorter axis, its default screen window; `flip_x`
 *  for a Scale -1 1 1 before LookAt. Written from pbrt's definitions, not from Spangle's. */
std::pair<double, double> pbrt_raster(Vec3 e, Vec3 l, Vec3 up, double fov, double w, double h,
                                      bool flip_x, Vec3 p) {
    const Vec3 dir = normalize(l - e);
    const Vec3 right = normalize(cross(normalize(up), dir));
    const Vec3 new_up = cross(dir, right);
    const Vec3 d = p - e;
    const double cx = (flip_x ? -1.0 : 1.0) * dot(d, right), cy = dot(d, new_up), cz = dot(d, dir);
    const double t = std::tan(fov * M_PI / 360.0);
    const double sx = cx / cz / t, sy = cy / cz / t;
    const double aspect = w / h;
    const double x0 = aspect > 1 ? -aspect : -1, x1 = -x0;
    const double y0 = aspect > 1 ? -1 : -1 / aspect, y1 = -y0;
    return {(sx - x0) / (x1 - x0) * w, (y1 - sy) / (y1 - y0) * h};
}

/** Where Spangle's EXR worldToNDC puts p, in raster pixels. */
std::pair<double, double> exr_raster(const Camera& c, uint32_t w, uint32_t h, Vec3 p) {
    const CameraMatrices m = CameraModel::of(c, w, h).matrices();
    const float v[4] = {p.x, p.y, p.z, 1.0f};
    double o[4] = {0, 0, 0, 0};
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i)
            o[j] += v[i] * m.world_to_ndc[static_cast<std::size_t>(i * 4 + j)];
    return {o[0] / o[3] * w, o[1] / o[3] * h};
}

/** A pbrt camera (fov 35, a Film of film_w x film_h, mirrored by `Scale -1 1 1` with `flip`)
 *  rendered at w x h: points land where pbrt puts them at that size, to a thousandth of a pixel
 *  (float matrices). */
void expect_points_where_pbrt_puts_them(uint32_t film_w, uint32_t film_h, uint32_t w, uint32_t h,
                                        bool flip) {
    const Vec3 e(1, 2, 6), l(0, 0.5, 0), up(0, 1, 0);
    const Vec3 points[] = {{0, 0, 0}, {1, 0.5, -1}, {-1.5, 2, 0.5}, {0.3f, -0.8f, 1}};
    const std::string text = fmt::format(
        "{}LookAt {} {} {}  {} {} {}  {} {} {}\nCamera \"perspective\" \"float fov\" 35\n"
        "Film \"image\" \"integer xresolution\" {} \"integer yresolution\" {}\n",
        flip ? "Scale -1 1 1\n" : "", e.x, e.y, e.z, l.x, l.y, l.z, up.x, up.y, up.z, film_w,
        film_h);
    PbrtReadInfo info;
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo si = build_scene(read_pbrt_text("camera.pbrt", text, info), color, registry);
    for (const Vec3& p : points) {
        const auto [px, py] = pbrt_raster(e, l, up, 35.0, w, h, flip, p);
        const auto [sx, sy] = exr_raster(si.camera, w, h, p);
        EXPECT_NEAR(sx, px, 1e-3 * w)
            << film_w << "x" << film_h << " at " << w << "x" << h << (flip ? " flipped" : "");
        EXPECT_NEAR(sy, py, 1e-3 * h)
            << film_w << "x" << film_h << " at " << w << "x" << h << (flip ? " flipped" : "");
    }
}

TEST(PbrtCamera, PointsProjectWherePbrtPutsThem) {
    for (const bool flip : {false, true})
        for (const auto& [w, h] : {std::pair{320u, 200u}, std::pair{120u, 240u}})
            expect_points_where_pbrt_puts_them(w, h, w, h, flip);
}

TEST(PbrtCamera, AtAnotherSizeTheFovStaysOnTheShorterSideAsPbrtsDoes) {
    // A portrait Film rendered at a landscape --size (and the other way): pbrt's fov spans the
    // shorter side of the image rendered. Before, the fov was turned into a vertical one for the
    // Film's aspect, so a portrait scene at 320x180 showed 3x the width pbrt shows.
    expect_points_where_pbrt_puts_them(100, 200, 320, 180, false);
    expect_points_where_pbrt_puts_them(320, 180, 90, 160, false);
}

TEST(PbrtCamera, AScreenWindowShowsItsPartOfTheFilmPlane) {
    // screenwindow [0 1 0 1]: the image is the upper-right quarter of the default square view,
    // so the point on the view axis lands at the bottom-left corner.
    const std::string text = R"(LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 60 "float screenwindow" [0 1 0 1]
Film "image" "integer xresolution" 100 "integer yresolution" 100
)";
    PbrtReadInfo info;
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo si = build_scene(read_pbrt_text("w.pbrt", text, info), color, registry);
    const auto [x, y] = exr_raster(si.camera, 100, 100, Vec3(0, 0, 0));
    EXPECT_NEAR(x, 0.0, 1e-3);
    EXPECT_NEAR(y, 100.0, 1e-3);
    // pbrt's camera x is world -x here (up x dir): a point at screen (0.5, 0.5) of the window.
    const double t = std::tan(30.0 * M_PI / 180.0) * 5.0;
    const auto [x2, y2] = exr_raster(
        si.camera, 100, 100, Vec3(-0.5f * static_cast<float>(t), 0.5f * static_cast<float>(t), 0));
    EXPECT_NEAR(x2, 50.0, 1e-2);
    EXPECT_NEAR(y2, 50.0, 1e-2);
}

/** A pbrt scene of `view` (LookAt and Camera lines) on a w x h film, 4 samples per pixel, and
 *  nothing but a small emitting sphere of radius r at p, in a black world. */
std::string emitter_scene(const std::string& view, int w, int h, Vec3 p, float r) {
    return fmt::format(R"({}
Film "image" "integer xresolution" {} "integer yresolution" {}
Sampler "halton" "integer pixelsamples" 4
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [10 10 10]
  Translate {} {} {}
  Shape "sphere" "float radius" {}
AttributeEnd
)",
                       view, w, h, p.x, p.y, p.z, r);
}

/** The index of an RGB image's pixel of the largest red value. */
std::size_t brightest(const std::vector<float>& image) {
    std::size_t best = 0;
    for (std::size_t i = 0; i < image.size() / 3; ++i)
        if (image[3 * i] > image[3 * best]) best = i;
    return best;
}

TEST(PbrtCamera, ARenderedPointLandsAtPbrtsPixel) {
    // A small emitter off the view axis, everything else black: its brightest pixel is where
    // pbrt's own projection puts it (within the pixel it falls in).
    const Vec3 p(0.9f, 0.5f, 0.0f);
    const std::string text = emitter_scene(
        "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40", 64, 48, p, 0.03f);
    PbrtReadInfo info;
    const std::size_t best = brightest(render(read_pbrt_text("dot.pbrt", text, info)));
    const auto [px, py] = pbrt_raster({0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 40.0, 64, 48, false, p);
    EXPECT_EQ(best % 64, static_cast<std::size_t>(px)) << "pbrt puts +x on the image's left";
    EXPECT_EQ(best / 64, static_cast<std::size_t>(py));
    EXPECT_LT(px, 32.0) << "the point at world +x lies left of the centre in pbrt's image";
}

TEST(PbrtCamera, OrthographicPointsLandWherePbrtPutsThem) {
    // pbrt's orthographic camera: camera-space x and y themselves on the screen window (by
    // default [-aspect, aspect] x [-1, 1] for a landscape film), whatever the depth. Both the
    // EXR's matrices and a rendered emitter land there; a point twice as far lands on the same
    // pixel. Before, the camera was noted as unsupported and a perspective one stood in.
    const Vec3 e(0, 0, 5);
    const auto raster = [](Vec3 p, double w, double h) {
        // LookAt 0 0 5 -> 0 0 0: camera x is world -x (pbrt's left-handed space), y is y.
        const double sx = -p.x, sy = p.y, aspect = w / h;
        return std::pair{(sx + aspect) / (2.0 * aspect) * w, (1.0 - sy) / 2.0 * h};
    };
    const auto scene = [&](Vec3 p) {
        return emitter_scene(
            fmt::format("LookAt {} {} {}  0 0 0  0 1 0\nCamera \"orthographic\"", e.x, e.y, e.z),
            64, 48, p, 0.03f);
    };
    for (const Vec3& p : {Vec3(0.6f, 0.35f, 0.0f), Vec3(-0.9f, -0.2f, -4.0f)}) {
        PbrtReadInfo info;
        ColorConfig color = test::shipped_config();
        ecs::Registry registry;
        const SceneInfo si = build_scene(read_pbrt_text("o.pbrt", scene(p), info), color, registry);
        EXPECT_GT(si.camera.ortho_height, 0.0f);
        const auto [px, py] = raster(p, 64, 48);
        const auto [sx, sy] = exr_raster(si.camera, 64, 48, p);
        EXPECT_NEAR(sx, px, 1e-3 * 64);
        EXPECT_NEAR(sy, py, 1e-3 * 48);
        PbrtReadInfo info2;
        const std::size_t best = brightest(render(read_pbrt_text("o.pbrt", scene(p), info2)));
        EXPECT_EQ(best % 64, static_cast<std::size_t>(px)) << "x of " << p.x;
        EXPECT_EQ(best / 64, static_cast<std::size_t>(py)) << "y of " << p.y;
    }
}

TEST(PbrtCamera, EquirectangularPointsLandWherePbrtPutsThem) {
    // pbrt-v4's spherical camera with the equirectangular mapping (and v3's environment camera):
    // a direction (sin t cos p, cos t, sin t sin p) in its left-handed camera space at image
    // (p / 2 pi, t / pi). A small emitter in each of several directions lands on that pixel.
    // Before, a perspective camera of fov 90 stood in with a note.
    const auto pixel = [](Vec3 p) {
        // LookAt 0 0 0 -> 0 0 -1, up y: camera x is world -x, y is y, z is world -z.
        const Vec3 d = normalize(p);
        const double cx = -d.x, cy = d.y, cz = -d.z;
        double phi = std::atan2(cz, cx);
        if (phi < 0.0) phi += 2.0 * M_PI;
        return std::pair{phi / (2.0 * M_PI) * 64.0, std::acos(cy) / M_PI * 32.0};
    };
    for (const char* camera :
         {R"(Camera "spherical" "string mapping" "equirectangular")", R"(Camera "environment")"})
        for (const Vec3& p : {Vec3(3.0f, 0.0f, 0.0f), Vec3(0.0f, 0.0f, -3.0f),
                              Vec3(2.0f, 1.5f, 1.0f), Vec3(-1.0f, -2.0f, 2.5f)}) {
            const std::string text = emitter_scene(
                fmt::format("LookAt 0 0 0  0 0 -1  0 1 0\n{}", camera), 64, 32, p, 0.25f);
            PbrtReadInfo info;
            const SceneDescription d = read_pbrt_text("pano.pbrt", text, info);
            EXPECT_TRUE(d.camera.equirect) << camera;
            for (const std::string& n : d.notes)
                EXPECT_EQ(n.find("not supported"), std::string::npos) << n;
            // The emitter (a few pixels across) by its light's centroid, in pixels (+0.5: a
            // pixel's centre); x taken round the seam nearest the expected column.
            const std::vector<float> image = render(d);
            const auto [px, py] = pixel(p);
            double sum = 0.0, sx = 0.0, sy = 0.0;
            for (std::size_t i = 0; i < image.size() / 3; ++i) {
                const double v = image[3 * i];
                double x = static_cast<double>(i % 64) + 0.5;
                x += 64.0 * std::round((px - x) / 64.0);
                sum += v;
                sx += v * x;
                sy += v * (static_cast<double>(i / 64) + 0.5);
            }
            ASSERT_GT(sum, 0.0) << camera;
            EXPECT_NEAR(sx / sum, px, 0.35) << camera << " x of " << p.x << " " << p.y;
            EXPECT_NEAR(sy / sum, py, 0.35) << camera << " y of " << p.x << " " << p.y;
        }
    // Its default mapping, equal-area, is not Spangle's: noted, a perspective camera stands in.
    PbrtReadInfo info;
    const SceneDescription ea = read_pbrt_text("ea.pbrt", "Camera \"spherical\"\n", info);
    EXPECT_FALSE(ea.camera.equirect);
}

TEST(PbrtRender, ATwoSidedAreaLightEmitsFromBothFaces) {
    // The camera sees the quad's back face: one-sided it is black there, two-sided it shows L.
    const auto centre = [](bool two_sided) {
        const std::string text = fmt::format(R"(LookAt 0 0 -3  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "image" "integer xresolution" 8 "integer yresolution" 8
Sampler "halton" "integer pixelsamples" 1
WorldBegin
AreaLightSource "diffuse" "rgb L" [2 3 4] "bool twosided" {}
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point3 P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
)",
                                             two_sided);
        PbrtReadInfo info;
        const std::vector<float> image = render(read_pbrt_text("two.pbrt", text, info));
        const std::size_t i = 3 * (4 * 8 + 4);
        return Vec3(image[i], image[i + 1], image[i + 2]);
    };
    EXPECT_EQ(centre(false), Vec3(0.0f));
    const Vec3 two = centre(true);
    // The emitter seen directly is its radiance (working space lin_rec709 = pbrt's RGB), to
    // float rounding of the film's fixed-point sums.
    EXPECT_NEAR(two.x, 2.0f, 1e-4f);
    EXPECT_NEAR(two.y, 3.0f, 1e-4f);
    EXPECT_NEAR(two.z, 4.0f, 1e-4f);
}

TEST(PbrtRender, AFlakeMaterialsIntegerSeedIsTakenAndChangesTheFlakes) {
    // pbrt-v3's flake material with "integer seed": the seed went to the plugin as a float,
    // which refused it ("parameter 'seed' must be an integer"), and convert wrote 3.0.
    const auto image = [](int seed) {
        const std::string text = fmt::format(R"(LookAt 0 0 3  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "image" "integer xresolution" 16 "integer yresolution" 16
Sampler "halton" "integer pixelsamples" 2
WorldBegin
LightSource "distant" "point from" [0 0 1] "point to" [0 0 0] "rgb L" [3 3 3]
Material "flake" "rgb Kd" [0.5 0.02 0.02] "float density" 200000 "integer seed" {}
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point3 P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "point2 uv" [0 0 1 0 1 1 0 1]
)",
                                             seed);
        PbrtReadInfo info;
        const SceneDescription d = read_pbrt_text("flake.pbrt", text, info);
        const auto& params = d.materials.at(0).params;
        const auto it = std::find_if(params.begin(), params.end(),
                                     [](const ParamDesc& q) { return q.name == "seed"; });
        EXPECT_TRUE(it != params.end() && it->is_integer && it->number == seed);
        return render(d);
    };
    const std::vector<float> a = image(3), b = image(4);
    EXPECT_GT(std::accumulate(a.begin(), a.end(), 0.0), 0.0);
    EXPECT_NE(a, b) << "the seed changes the flakes";
}

TEST(PbrtRender, TheFilmsCropWindowIsRenderedUnlessTheRequestGivesOne) {
    // Film 40 x 20 with cropwindow [0.25 0.75 0.1 0.6]: pixels x [ceil(10), ceil(30)) and
    // y [ceil(2), ceil(12)), as pbrt rounds them; a request's own crop (the CLI's --crop) wins.
    test::TempDir dir("pbrt_crop");
    std::ofstream(dir.file("crop.pbrt")) << R"(LookAt 0 0 -3  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "image" "integer xresolution" 40 "integer yresolution" 20
  "float cropwindow" [0.25 0.75 0.1 0.6]
Sampler "halton" "integer pixelsamples" 1
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Material "diffuse"
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point3 P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
)";
    FrameRequest req;
    req.scene = dir.file("crop.pbrt");
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.threads = 2;
    const FrameResult cropped = render_frame(req);
    EXPECT_EQ(cropped.width, 20u);
    EXPECT_EQ(cropped.height, 10u);
    EXPECT_EQ(cropped.window.x0, 10u);
    EXPECT_EQ(cropped.window.y0, 2u);
    EXPECT_EQ(cropped.window.full_width, 40u);
    req.options.crop = CropWindow{0, 0, 40, 20};
    const FrameResult whole = render_frame(req);
    EXPECT_EQ(whole.width, 40u);
    EXPECT_EQ(whole.height, 20u);
}

bool contains(const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
}

TEST(PbrtRender, AnIdenticalCageReadAgainIsNotSubdividedAgain) {
    const auto cage = [](float top, bool second) {
        std::string text = fmt::format(R"(LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
Film "image" "integer xresolution" 16 "integer yresolution" 16
WorldBegin
LightSource "infinite"
Shape "loopsubdiv" "integer levels" 3 "integer indices" [0 1 2 0 2 3 0 3 1 1 3 2]
  "point3 P" [0 0 {}  1 0 -1  -1 1 -1  -1 -1 -1]
)",
                                       top);
        if (second)
            text +=
                "Translate 3 0 0\nShape \"loopsubdiv\" \"integer indices\" [0 1 2 0 2 3 0 3 1 1 3 "
                "2]"
                " \"point3 P\" [0 0 2  1 0 -1  -1 1 -1  -1 -1 -1]\n";
        PbrtReadInfo info;
        return read_pbrt_text("cage.pbrt", text, info);
    };
    RenderOptions options;
    options.threads = 2;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    const ReloadReport first = session.load(cage(1, false));
    EXPECT_TRUE(contains(first.ran, "subdivide"));
    // The same cage read again (a new Cage object with the same content): nothing reruns.
    const ReloadReport same = session.load(cage(1, false));
    EXPECT_TRUE(same.ran.empty()) << same.summary();
    // Another surface beside it: subdivide runs, and takes the first refinement from its cache.
    const ReloadReport more = session.load(cage(1, true));
    EXPECT_TRUE(contains(more.ran, "subdivide"));
    EXPECT_EQ(more.reused.count("subdivided meshes") ? more.reused.at("subdivided meshes") : 0, 1)
        << more.summary();
    // A changed cage is refined again.
    const ReloadReport moved = session.load(cage(1.5f, true));
    EXPECT_TRUE(contains(moved.ran, "subdivide"));
    EXPECT_EQ(moved.reused.count("subdivided meshes") ? moved.reused.at("subdivided meshes") : 0, 1)
        << "the unchanged second cage is reused, the changed first one is not: " << moved.summary();
}

TEST(PbrtEnvironment, PbrtsLatLongMapsHaveZUpAndPhiFromX) {
    // An 8 x 4 map of distinct pixels: the direction at a pixel's centre by pbrt's definition
    // (phi = 2 pi u from +x towards +y, theta = pi v from +z) reads that very pixel.
    const int w = 8, h = 4;
    std::vector<float> rgb(3 * w * h);
    for (int i = 0; i < w * h; ++i)
        rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = 1.0f + static_cast<float>(i);
    const EnvironmentMap map(rgb, w, h, 0.0f, MapProjection::LatLongZUp, Affine());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double phi = 2 * M_PI * (x + 0.5) / w, theta = M_PI * (y + 0.5) / h;
            const Vec3 d(static_cast<float>(std::sin(theta) * std::cos(phi)),
                         static_cast<float>(std::sin(theta) * std::sin(phi)),
                         static_cast<float>(std::cos(theta)));
            EXPECT_NEAR(map.eval(d).x, 1.0f + static_cast<float>(y * w + x), 1e-3f)
                << x << "," << y;
        }
}

TEST(PbrtEnvironment, EqualAreaMapsPutTheirCentreUpAndSampleByTheirPdf) {
    const int n = 16;
    std::vector<float> rgb(3 * n * n, 0.1f);
    const auto set = [&](int x, int y, float v) {
        for (int c = 0; c < 3; ++c) rgb[3 * (y * n + x) + c] = v;
    };
    set(n / 2, n / 2, 5.0f);  // just off the centre: +z
    set(n - 1, n / 2, 7.0f);  // right edge middle: +x
    const EnvironmentMap map(rgb, n, n, 0.0f, MapProjection::EqualArea, Affine());
    EXPECT_GT(map.eval(normalize(Vec3(0.02f, 0.02f, 1))).x, 1.0f) << "the square's centre is +z";
    EXPECT_GT(map.eval(normalize(Vec3(1, 0.05f, 0))).x, 1.0f) << "its right edge is +x";
    EXPECT_NEAR(map.eval(Vec3(0, 0, -1)).x, 0.1f, 1e-6f) << "its corners are -z";
    // sample() and pdf() agree, and the pdf integrates to 1 over the sphere (Monte Carlo with
    // 2^16 uniform directions: a standard error of about 1%; 5% bound).
    double integral = 0.0;
    const int count = 1 << 16;
    for (int i = 0; i < count; ++i) {
        const float u0 = to_unit_float(hash2(1, static_cast<uint64_t>(i)));
        const float u1 = to_unit_float(hash2(2, static_cast<uint64_t>(i)));
        float pdf = 0.0f;
        const Vec3 d = map.sample(u0, u1, pdf);
        if (i < 512 && pdf > 0.0f) {
            EXPECT_NEAR(map.pdf(d) / pdf, 1.0f, 1e-3f);
        }
        const float z = 1.0f - 2.0f * u0, r = std::sqrt(std::max(0.0f, 1.0f - z * z));
        const Vec3 uniform(r * std::cos(2 * kPi * u1), r * std::sin(2 * kPi * u1), z);
        integral += map.pdf(uniform) * 4.0 * M_PI / count;
    }
    EXPECT_NEAR(integral, 1.0, 0.05);
}

}  // namespace
}  // namespace spangle::test_pbrt_render
