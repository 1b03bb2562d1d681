// Render layers (--layers) on an analytic scene: a square seen head-on that covers exactly the
// middle quarter of the image, lit by three light groups. The light-group layers add up to the
// beauty, alpha is the square's coverage, depth, normal and position are the square's, the
// glints are part of the beauty, the object-space position and object number are the square's,
// and turning layers on leaves the beauty bit for bit alone.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "pipeline/frame.h"
#include "test_support.h"

namespace spangle::test_layers {
namespace {

/** A 1.2 m square at z = 0 facing a camera 3 m away whose view is 2.4 m wide: with a box filter
 *  the square covers pixels [16, 48) of a 64 x 64 image exactly. */
std::string square_scene(double clamp = 0.0, double flake_weight = 0.5) {
    return fmt::format(R"(
[render]
width = 64
height = 64
spp = 16
max_depth = 3
filter = "box"
clamp_indirect = {}
working_space = "lin_rec709"
[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]
fov = {}
[environment]
color = [0.2, 0.3, 0.5]
light_group = "sky"
[[material]]
name = "glitter"
plugin = "flake"
params = {{ base_color = 0.3, flake_weight = {}, density = 200000, flake_roughness = 0.3, gamma = 2, min_flakes = 5000, max_flakes = 10000 }}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "glitter"
rotate = [90, 0, 0]
scale = 0.6
[[material]]
name = "wall"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.8 }}
[[object]]
# Behind the camera, facing the square: light bounces between them (scattered twice or more,
# what clamp_indirect caps); camera rays never see it.
mesh = "{}/meshes/plane.ply"
material = "wall"
rotate = [-90, 0, 0]
translate = [0, 0, 6]
scale = 3
[[light]]
type = "sphere"
center = [0.4, 0.3, 3.2]
radius = 0.03
intensity = 3000
light_group = "key"
[[light]]
type = "point"
position = [-1, 1, 2]
intensity = 2
)",
                       clamp, 2.0 * std::atan(0.4) * 180.0 / 3.14159265358979323846, flake_weight,
                       test::asset_dir(), test::asset_dir());
}

/** A quiet request for the square scene (written into `dir`). */
FrameRequest square_request(const test::TempDir& dir, bool layers, double clamp = 0.0,
                            double flake_weight = 0.5, bool background_apart = false) {
    { std::ofstream(dir.file("square.toml")) << square_scene(clamp, flake_weight); }
    FrameRequest req;
    req.scene = dir.file("square.toml");
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.layers = layers;
    req.options.background_apart = background_apart;
    return req;
}

FrameResult render_square(const test::TempDir& dir, bool layers, double clamp = 0.0,
                          double flake_weight = 0.5, bool background_apart = false) {
    return render_frame(square_request(dir, layers, clamp, flake_weight, background_apart));
}

/** The channel named `name` of layer list `names`. */
std::size_t channel(const std::vector<std::string>& names, const std::string& name) {
    const auto it = std::find(names.begin(), names.end(), name);
    EXPECT_NE(it, names.end()) << name;
    return static_cast<std::size_t>(it - names.begin());
}

TEST(Layers, EachPassCarriesTheLayersSoFar) {
    // Found by a user: with --layers --pass-output, the EXR written after each pass held the
    // beauty alone (premultiplied: its sky black) with no alpha, background or layers; after a
    // kill it was what was left. Each pass now carries the layers finished as at the end.
    test::TempDir dir("layers_passes");
    FrameRequest req = square_request(dir, true, 0.0, 0.5, true);
    req.options.spp_override = 8;
    std::vector<std::vector<float>> seen;
    std::vector<std::string> names;
    std::vector<uint32_t> spp;
    req.options.on_pass = [&](const PassImage& p) {
        if (p.spp == 0) return;  // the preview pass: the beauty only
        ASSERT_NE(p.layers, nullptr) << "pass at " << p.spp;
        ASSERT_NE(p.layer_names, nullptr);
        seen.push_back(*p.layers);
        names = *p.layer_names;
        spp.push_back(p.spp);
    };
    const FrameResult r = render_frame(req);
    ASSERT_EQ(spp, (std::vector<uint32_t>{1, 2, 4})) << "passes before the last";
    EXPECT_EQ(names, r.layer_names);
    const std::size_t lc = names.size(), a = channel(names, "A"),
                      bg = channel(names, "background.R");
    for (const auto& l : seen) {
        ASSERT_EQ(l.size(), r.layers.size());
        double alpha = 0.0, back = 0.0;
        for (std::size_t p = 0; p < l.size() / lc; ++p) {
            alpha += l[p * lc + a];
            back += l[p * lc + bg];
        }
        EXPECT_GT(alpha, 0.0) << "coverage";
        EXPECT_GT(back, 0.0) << "the environment kept apart";
    }
}

TEST(Layers, LightGroupsAddUpToTheBeautyAndAlphaIsCoverage) {
    test::TempDir dir("layers");
    const FrameResult r = render_square(dir, true);
    const std::vector<std::string> want = {
        "A", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "Z", "P.X", "P.Y", "P.Z",
        "Pobj.X", "Pobj.Y", "Pobj.Z", "object", "glints.R", "glints.G", "glints.B",
        // Groups in order of first use: the environment's, the sphere's, the point light's
        // (which names none).
        "lightgroup_sky.R", "lightgroup_sky.G", "lightgroup_sky.B", "lightgroup_key.R",
        "lightgroup_key.G", "lightgroup_key.B", "lightgroup_default.R", "lightgroup_default.G",
        "lightgroup_default.B",
        // The glint part of each group's light.
        "glints_sky.R", "glints_sky.G", "glints_sky.B", "glints_key.R", "glints_key.G",
        "glints_key.B", "glints_default.R", "glints_default.G", "glints_default.B"};
    ASSERT_GE(r.layer_names.size(), want.size());
    ASSERT_EQ(std::vector<std::string>(r.layer_names.begin(),
                                       r.layer_names.begin() + static_cast<long>(want.size())),
              want);
    EXPECT_EQ(r.layer_names[want.size()], "CryptoObject00.R");
    EXPECT_EQ(r.layer_names.back(), "CryptoMaterial02.A");
    const std::size_t lc = r.layer_names.size(), w = r.width, h = r.height;
    ASSERT_EQ(r.layers.size(), lc * w * h);
    const auto at = [&](std::size_t x, std::size_t y, std::size_t c) {
        return r.layers[(y * w + x) * lc + c];
    };
    double glint_sum = 0.0, sum_groups[3] = {0, 0, 0};
    double alpha_sum = 0.0;
    for (std::size_t y = 0; y < h; ++y)
        for (std::size_t x = 0; x < w; ++x) {
            const float* beauty = &r.image[3 * (y * w + x)];
            for (std::size_t c = 0; c < 3; ++c) {
                double groups = 0.0;
                for (std::size_t g = 0; g < 3; ++g) {
                    groups += at(x, y, 18 + 3 * g + c);
                    sum_groups[g] += at(x, y, 18 + 3 * g + c);
                }
                ASSERT_NEAR(groups, beauty[c], 1e-5 * std::max(1.0f, beauty[c]))
                    << "pixel (" << x << ", " << y << ") channel " << c;
                const float glint = at(x, y, 15 + c);
                ASSERT_GE(glint, 0.0f);
                ASSERT_LE(glint, beauty[c] * (1.0f + 1e-5f) + 1e-6f) << "glints are part of it";
                glint_sum += glint;
            }
            // Coverage: 1 on the square (pixels 16..47), 0 around it; the box filter keeps every
            // sample inside its pixel.
            const bool inside = x >= 16 && x < 48 && y >= 16 && y < 48;
            const float a = at(x, y, 0);
            alpha_sum += a;
            ASSERT_NEAR(a, inside ? 1.0f : 0.0f, 1e-6f) << "alpha at (" << x << ", " << y << ")";
            if (inside) {
                // The square faces the camera at depth 3; its normal is +z, its points z = 0.
                ASSERT_NEAR(at(x, y, 7), 3.0f, 1e-4f);
                ASSERT_NEAR(at(x, y, 6), 1.0f, 1e-4f);
                ASSERT_NEAR(at(x, y, 10), 0.0f, 1e-4f);
                ASSERT_LE(std::fabs(at(x, y, 8)), 0.6f + 1e-4f);
                ASSERT_GT(at(x, y, 1), 0.0f) << "albedo";
                // The square is the first [[object]], plane.ply (y = 0) scaled by 0.6 and turned
                // 90 degrees about x: its own point (P.x, 0, -P.y) / 0.6.
                ASSERT_EQ(at(x, y, 14), 1.0f) << "object number at (" << x << ", " << y << ")";
                ASSERT_NEAR(at(x, y, 11), at(x, y, 8) / 0.6f, 1e-4f);
                ASSERT_NEAR(at(x, y, 12), 0.0f, 1e-4f);
                ASSERT_NEAR(at(x, y, 13), -at(x, y, 9) / 0.6f, 1e-4f);
            } else {
                for (std::size_t c = 1; c < 15; ++c) ASSERT_EQ(at(x, y, c), 0.0f);
            }
        }
    EXPECT_NEAR(alpha_sum / static_cast<double>(w * h), 0.25, 1e-6);
    EXPECT_GT(glint_sum, 1.0) << "the flakes glint in the sphere light";
    for (double s : sum_groups) EXPECT_GT(s, 1.0) << "every group lights something";
}

TEST(Layers, ClampedContributionsStillAddUpAndNoFlakesMeanNoGlints) {
    test::TempDir dir("layers_clamp");
    // A firefly clamp low enough to scale most indirect light, and no flakes at all.
    const FrameResult r = render_square(dir, true, 0.05, 0.0);
    const std::size_t lc = r.layer_names.size();
    ASSERT_EQ(lc, 27u + 9u + 24u) << "with each group's glints and the Cryptomatte pairs";
    const std::size_t pixels = r.width * r.height;
    const FrameResult unclamped = render_square(dir, true, 0.0, 0.0);
    double clamped_sum = 0.0, unclamped_sum = 0.0;
    for (std::size_t p = 0; p < pixels; ++p)
        for (std::size_t c = 0; c < 3; ++c) {
            const float beauty = r.image[3 * p + c];
            double groups = 0.0;
            for (std::size_t g = 0; g < 3; ++g) groups += r.layers[p * lc + 18 + 3 * g + c];
            ASSERT_NEAR(groups, beauty, 1e-5 * std::max(1.0f, beauty)) << "pixel " << p;
            ASSERT_EQ(r.layers[p * lc + 15 + c], 0.0f) << "a glint without flakes, pixel " << p;
            clamped_sum += beauty;
            unclamped_sum += unclamped.image[3 * p + c];
        }
    EXPECT_LT(clamped_sum, 0.999 * unclamped_sum) << "the clamp took effect";
}

TEST(Layers, BeautyIsRestPlusGlintsInEveryLightGroup) {
    test::TempDir dir("layers_glint_recipe");
    const FrameResult r = render_square(dir, true);
    const auto& n = r.layer_names;
    const std::size_t lc = n.size(), pixels = static_cast<std::size_t>(r.width) * r.height;
    double glints_seen[3] = {0, 0, 0};
    for (std::size_t p = 0; p < pixels; ++p) {
        const float* l = &r.layers[p * lc];
        for (std::size_t c = 0; c < 3; ++c) {
            const char* rgb[] = {"R", "G", "B"};
            const float beauty = r.image[3 * p + c];
            const float glints = l[channel(n, fmt::format("glints.{}", rgb[c]))];
            // The recipe of docs/layers.md: rest = lightgroup - glints_group per group; the
            // beauty is the rests plus the glints. Sums of floats: rounding only.
            double rest = 0.0, group_glints = 0.0;
            std::size_t g = 0;
            for (const char* group : {"sky", "key", "default"}) {
                const float light = l[channel(n, fmt::format("lightgroup_{}.{}", group, rgb[c]))];
                const float gl = l[channel(n, fmt::format("glints_{}.{}", group, rgb[c]))];
                ASSERT_GE(gl, 0.0f);
                ASSERT_LE(gl, light * (1.0f + 1e-5f) + 1e-6f) << "a group's glints are its light";
                rest += light - gl;
                group_glints += gl;
                glints_seen[g++] += gl;
            }
            const float tol = 1e-5f * std::max(1.0f, beauty);
            ASSERT_NEAR(group_glints, glints, tol) << "pixel " << p;
            ASSERT_NEAR(rest + glints, beauty, tol) << "pixel " << p;
        }
    }
    // The key light (a small sphere) makes glints; so does the sky (by BSDF sampling).
    EXPECT_GT(glints_seen[1], 1.0);
    EXPECT_GT(glints_seen[0], 0.0);
}

TEST(Layers, TheBackgroundApartMakesTheBeautyPremultiplied) {
    test::TempDir dir("layers_background");
    const FrameResult apart = render_square(dir, true, 0.0, 0.5, true);
    const FrameResult whole = render_square(dir, true, 0.0, 0.5, false);
    const auto& n = apart.layer_names;
    const std::size_t lc = n.size(), pixels = static_cast<std::size_t>(apart.width) * apart.height;
    const std::size_t bg = channel(n, "background.R"), a = channel(n, "A");
    int empty = 0;
    for (std::size_t p = 0; p < pixels; ++p) {
        const float alpha = apart.layers[p * lc + a];
        for (std::size_t c = 0; c < 3; ++c) {
            const float beauty = apart.image[3 * p + c], back = apart.layers[p * lc + bg + c];
            // Over the background it is the picture without the split (float rounding).
            ASSERT_NEAR(beauty + back, whole.image[3 * p + c],
                        1e-5f * std::max(1.0f, whole.image[3 * p + c]))
                << "pixel " << p;
            if (alpha == 0.0f) {
                ASSERT_EQ(beauty, 0.0f) << "pixel " << p;
            }
            if (alpha == 1.0f) {
                ASSERT_EQ(back, 0.0f) << "pixel " << p;
            }
        }
        empty += alpha == 0.0f;
    }
    EXPECT_EQ(empty, 64 * 64 - 32 * 32);
}

TEST(Layers, TurningThemOnLeavesTheBeautyAlone) {
    test::TempDir dir("layers_beauty");
    const FrameResult with = render_square(dir, true);
    const FrameResult without = render_square(dir, false);
    EXPECT_TRUE(without.layers.empty());
    ASSERT_EQ(with.image.size(), without.image.size());
    for (std::size_t i = 0; i < with.image.size(); ++i)
        ASSERT_EQ(with.image[i], without.image[i]) << "value " << i;
}

}  // namespace
}  // namespace spangle::test_layers
