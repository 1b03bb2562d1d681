// End-to-end renders of tiny scenes: determinism across thread counts, an exact furnace, the
// closed-form irradiance of a rectangle light, and systems skipped for what a scene lacks.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <numeric>

#include "pipeline/frame.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_render {
namespace {

/** The render of the scene file at `path`. */
FrameResult render_path(const std::string& path, int threads, uint32_t spp = 0,
                        Strategy strategy = Strategy::Mis, bool footprints_always = false) {
    FrameRequest req;
    req.scene = path;
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.threads = threads;
    req.options.spp_override = spp;
    req.options.strategy = strategy;
    req.options.footprints_always = footprints_always;
    return render_frame(req);
}

/** The render of tests/scenes/`scene`. */
FrameResult render(const std::string& scene, int threads, uint32_t spp = 0,
                   Strategy strategy = Strategy::Mis) {
    return render_path(test::test_dir() + "/scenes/" + scene, threads, spp, strategy);
}

const ecs::SystemReport& report(const FrameResult& r, const std::string& name) {
    for (const auto& s : r.systems)
        if (s.name == name) return s;
    throw std::runtime_error("no system " + name);
}

TEST(Render, SameImageOnOneAndTwoThreads) {
    const FrameResult one = render("small_lit.toml", 1);
    const FrameResult two = render("small_lit.toml", 2);
    ASSERT_EQ(one.image.size(), two.image.size());
    ASSERT_EQ(one.image.size(), 40u * 24u * 3u);
    EXPECT_EQ(std::memcmp(one.image.data(), two.image.data(), one.image.size() * sizeof(float)), 0)
        << "counter-based sampling must make the image independent of scheduling";
    const double sum = std::accumulate(one.image.begin(), one.image.end(), 0.0);
    EXPECT_GT(sum, 0.0) << "the scene is lit";
    EXPECT_EQ(one.stats.nonfinite, 0u);
    EXPECT_TRUE(report(one, "area_lights").ran);
}

TEST(Render, FurnaceSphereIsAlbedoTimesEnvironmentExactly) {
    const FrameResult r = render("furnace_sphere.toml", 2);
    ASSERT_EQ(r.width, 48u);
    const auto px = [&](uint32_t x, uint32_t y, int c) {
        return r
            .image[3 * (static_cast<std::size_t>(y) * r.width + x) + static_cast<std::size_t>(c)];
    };
    // Every path scatters once off a convex sphere and escapes: L = albedo x Le = 0.5 x 0.8,
    // with no variance, so only float rounding is tolerated.
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(px(24, 24, c), 0.4f, 1e-5f);
        EXPECT_NEAR(px(20, 28, c), 0.4f, 1e-5f);
        EXPECT_NEAR(px(0, 0, c), 0.8f, 1e-6f) << "background is the environment";
    }
}

TEST(Render, RussianRouletteKeepsTheLightAndLittleNoise) {
    // Inside a glowing grey sphere every path bounces on and on, and Russian roulette from the
    // first bounce ends most of them: the picture is still E / (1 - a) = 0.5, less 0.5^65 for
    // the bounces past max_depth and about 1e-4 per bounce lost to interpolated normals.
    const FrameResult r = render("inside_sphere.toml", 2);
    ASSERT_EQ(r.image.size(), 32u * 32u * 3u);
    double sum = 0.0, sum2 = 0.0;
    for (std::size_t p = 0; p < r.image.size(); p += 3) {
        const double v = static_cast<double>(r.image[p + 1]);
        sum += v;
        sum2 += v * v;
    }
    const double n = static_cast<double>(r.image.size() / 3), mean = sum / n;
    const double sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
    EXPECT_NEAR(mean, 0.5, 4.0 * sd / std::sqrt(n) + 5e-4);
    // Without roulette the pixels agree to 5e-4 (64 bounces each, 20x the time); the roulette's
    // own noise: a path at throughput t lives on with probability sqrt(t) (at most 0.95), and
    // the pixels' spread is 0.013 at 64 spp. Survival by t itself (before) spread them 0.0225
    // in 15% less time: 2.6x less efficient.
    EXPECT_LT(sd, 0.018) << "the roulette's noise";
    EXPECT_GT(sd, 0.005) << "roulette decided paths (without it the spread is 5e-4)";
}

TEST(Render, RectangleLightMatchesClosedFormIrradiance) {
    // And the same light made transparent, seen through from above (Cycles' lights: the
    // camera does not see it, it casts no shadow, rays that meet it go on).
    for (const char* scene : {"quad_irradiance.toml", "quad_transparent.toml"}) {
        SCOPED_TRACE(scene);
        const FrameResult r = render(scene, 2);
        // Point below the centre of a 2 x 2 light at height 1 = four 1 x 1 rectangles with a corner
        // above it. Form factor of each (parallel planes, corner above the point):
        //   F = 1/(2 pi) [X/sqrt(1+X^2) atan(Y/sqrt(1+X^2)) + Y/sqrt(1+Y^2) atan(X/sqrt(1+Y^2))]
        // with X = Y = 1. Lambert albedo 1 under radiance 1 then reflects L = 4 F.
        const double a = 1.0 / std::sqrt(2.0) * std::atan(1.0 / std::sqrt(2.0));
        const double expected = 4.0 * (2.0 * a) / (2.0 * M_PI);
        double sum = 0.0, sum2 = 0.0;
        const std::size_t n = static_cast<std::size_t>(r.width) * r.height;
        for (std::size_t i = 0; i < n; ++i) {
            const double g = r.image[3 * i + 1];
            sum += g;
            sum2 += g * g;
        }
        const double mean = sum / static_cast<double>(n);
        const double var = (sum2 / static_cast<double>(n) - mean * mean) * static_cast<double>(n) /
                           static_cast<double>(n - 1);
        const double stderr_mean = std::sqrt(var / static_cast<double>(n));
        // The 9 x 9 pixels see a 4 mm patch, where the exact value changes by under 1e-5: the pixel
        // means are independent estimates of the same number, so 4 standard errors (+1e-4 for that
        // spread) bound a correct estimator's deviation with probability > 0.9999.
        EXPECT_NEAR(mean, expected, 4.0 * stderr_mean + 1e-4) << "stderr " << stderr_mean;
        EXPECT_LT(stderr_mean, 0.003) << "the estimate must be tight enough to mean something";
    }
}

TEST(Render, PointLightOnLambertPlaneMatchesClosedForm) {
    const FrameResult r = render("point_plane.toml", 1);
    // L = albedo / pi x I / h^2: no randomness reaches the result but the pixel position, and
    // the 0.2 degree view covers a 2 mm patch where I / d^2 cos varies by under 1e-5.
    const double expected = 2.0 / (1.5 * 1.5) / M_PI;
    for (std::size_t i = 0; i < r.image.size(); ++i)
        EXPECT_NEAR(r.image[i], expected, 1e-5 * expected + 1e-6);
}

TEST(Render, AQuadLightAsLargeAsASkyLightsTheFloorUnderIt) {
    // Edges of 2e10: the cross product's square is beyond a float, so the light's area was inf
    // and its normal 0, and it was dropped (black under every strategy); its densities squared
    // to 0 in the power heuristic, whose weight was then 0 for both strategies. Under a light
    // this large, a white floor reflects its radiance: L = albedo x 1 (the light covers the
    // hemisphere but for 1e-10 radians).
    test::TempDir dir("quad_sky");
    std::string text = test::scene_text("quad_irradiance.toml");
    test::replace_all(text, "../../assets/", test::asset_dir() + "/");
    test::replace_all(text, "corner = [-1.0, 1.0, -1.0]", "corner = [-1e10, 1.0, -1e10]");
    test::replace_all(text, "edge1 = [2.0, 0.0, 0.0]", "edge1 = [2e10, 0.0, 0.0]");
    test::replace_all(text, "edge2 = [0.0, 0.0, 2.0]", "edge2 = [0.0, 0.0, 2e10]");
    ASSERT_NE(text.find("2e10"), std::string::npos);
    std::ofstream(dir.file("s.toml")) << text;
    // (Not by next-event estimation alone: it samples the quad by area, and a sample lands
    // within 10 m of the point once in 1e18.)
    for (const Strategy strategy : {Strategy::Mis, Strategy::BsdfOnly}) {
        const FrameResult f = render_path(dir.file("s.toml"), 2, 64, strategy);
        double mean = 0.0;
        for (const float v : f.image) mean += static_cast<double>(v);
        mean /= static_cast<double>(f.image.size());
        EXPECT_NEAR(mean, 1.0, 0.02) << "strategy " << static_cast<int>(strategy);
    }
}

TEST(Render, ASphereLightLightsNothingInsideIt) {
    // It emits outward: the camera and BSDF rays see it black from within, and next-event
    // estimation lit the inside on its own (a white floor inside one: 0.5 with NEE alone, 0
    // with BSDF sampling alone).
    test::TempDir dir("sphere_inside");
    std::string text = test::scene_text("point_plane.toml");
    test::replace_all(text, "../../assets/", test::asset_dir() + "/");
    test::replace_all(text, "type = \"point\"\nposition = [0, 1.5, 0]\nintensity = 2.0",
                      "type = \"sphere\"\ncenter = [0, 0, 0]\nradius = 100\nintensity = 1");
    ASSERT_NE(text.find("radius = 100"), std::string::npos);
    std::ofstream(dir.file("s.toml")) << text;
    for (const Strategy strategy : {Strategy::Mis, Strategy::NeeOnly, Strategy::BsdfOnly}) {
        const FrameResult f = render_path(dir.file("s.toml"), 1, 16, strategy);
        EXPECT_EQ(*std::max_element(f.image.begin(), f.image.end()), 0.0f)
            << "strategy " << static_cast<int>(strategy);
    }
}

TEST(Render, SmallAndFarSphereLightsGiveTheirClosedFormIrradiance) {
    // A sphere light of radius R and radiance L at distance D over a white floor: the floor
    // below shows L (R / D)^2. Its cone was computed as 1 - sqrt(1 - (R / D)^2) in floats: 4-7%
    // bright at R / D = 1e-3 (a 1 cm bulb 10 m away), black at 1e-4 and below.
    test::TempDir dir("sphere_light_far");
    for (const double ratio : {1e-2, 1e-3, 3e-4, 1e-4, 1e-6}) {
        const double d = 2.0, r = ratio * d;
        std::string text = test::scene_text("point_plane.toml");
        test::replace_all(text, "../../assets/", test::asset_dir() + "/");
        test::replace_all(text, "type = \"point\"\nposition = [0, 1.5, 0]\nintensity = 2.0",
                          fmt::format("type = \"sphere\"\ncenter = [0, {}, 0]\nradius = {}\n"
                                      "intensity = {}",
                                      d, r, 1.0 / (ratio * ratio)));
        ASSERT_NE(text.find("type = \"sphere\""), std::string::npos);
        std::ofstream(dir.file("s.toml")) << text;
        const FrameResult f = render_path(dir.file("s.toml"), 1);
        double mean = 0.0;
        for (const float v : f.image) mean += static_cast<double>(v);
        mean /= static_cast<double>(f.image.size());
        EXPECT_NEAR(mean, 1.0, 2e-3) << "R / D = " << ratio;
    }
}

/** Per-pixel difference of two renders in units of their combined standard error, estimated
 *  from the spread of the difference over all pixels' green channel. */
double max_z_of_mean_difference(const FrameResult& a, const FrameResult& b) {
    const std::size_t n = a.image.size() / 3;
    double sum = 0.0, sum2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double d = static_cast<double>(a.image[3 * i + 1]) - b.image[3 * i + 1];
        sum += d;
        sum2 += d * d;
    }
    const double mean = sum / static_cast<double>(n);
    const double sd = std::sqrt(std::max(1e-30, sum2 / static_cast<double>(n) - mean * mean));
    return std::fabs(mean) / (sd / std::sqrt(static_cast<double>(n)));
}

TEST(Render, MisNeeOnlyAndBsdfOnlyAgree) {
    for (const char* scene :
         {"quad_irradiance.toml", "glossy_sphere_light.toml", "quad_transparent.toml"}) {
        const FrameResult mis = render(scene, 2, 0, Strategy::Mis);
        const FrameResult nee = render(scene, 2, 0, Strategy::NeeOnly);
        const FrameResult bsdf = render(scene, 2, 0, Strategy::BsdfOnly);
        // The image means of unbiased estimators of the same image differ by noise only:
        // their difference is within 4 standard errors.
        EXPECT_LT(max_z_of_mean_difference(mis, nee), 4.0) << scene;
        EXPECT_LT(max_z_of_mean_difference(mis, bsdf), 4.0) << scene;
        EXPECT_LT(max_z_of_mean_difference(nee, bsdf), 4.0) << scene;
        double lum = 0.0;
        for (float v : mis.image) lum += v;
        EXPECT_GT(lum, 0.0) << scene << " is lit";
    }
}

TEST(Render, MillimetreSceneRendersAsTheSameSceneInMetres) {
    // Light transport is scale-invariant: the scene shrunk a thousandfold (a jewel or a
    // glitter flake modelled in metres) is the same image. Ray origins left the surface by a
    // fixed 1.5e-5 near the world's origin, more than a shadow ray's margin at this scale and
    // 6% of the sphere light's radius: most light samples were blocked (the image 40x darker
    // under NEE in a real case), and only BSDF sampling saw the light.
    const test::TempDir dir("mm_scene");
    const std::string name = "glossy_sphere_light.toml";
    std::ofstream(dir.file("mm.toml")) << test::scene_text(
        name, {{"position = [0, 1.2, 3]", "position = [0, 0.0012, 0.003]"},
               {"scale = 0.3", "scale = 0.0003"},
               {"scale = 4", "scale = 0.004"},
               {"translate = [-0.8, 1.0, -1.5]", "translate = [-0.0008, 0.001, -0.0015]"},
               {"center = [0.6, 0.8, -1.2]", "center = [0.0006, 0.0008, -0.0012]"},
               {"radius = 0.25", "radius = 0.00025"}});
    std::ofstream(dir.file("m.toml")) << test::scene_text(name);
    const auto at = [&](const std::string& file, Strategy strategy) {
        FrameRequest req = test::quiet_request(dir.file(file));
        req.options.threads = 2;
        req.options.strategy = strategy;
        return render_frame(req);
    };
    const FrameResult metres = at("m.toml", Strategy::Mis);
    const FrameResult mm = at("mm.toml", Strategy::Mis);
    const FrameResult mm_nee = at("mm.toml", Strategy::NeeOnly);
    const FrameResult mm_bsdf = at("mm.toml", Strategy::BsdfOnly);
    EXPECT_LT(max_z_of_mean_difference(metres, mm), 4.0);
    EXPECT_LT(max_z_of_mean_difference(mm_nee, mm_bsdf), 4.0);
    double sum_m = 0.0, sum_mm = 0.0;
    for (std::size_t i = 0; i < metres.image.size(); ++i) {
        sum_m += metres.image[i];
        sum_mm += mm_nee.image[i];
    }
    EXPECT_GT(sum_m, 0.0);
    EXPECT_NEAR(sum_mm / sum_m, 1.0, 0.05) << "the image's total light under NEE";
}

TEST(Render, ASceneFarFromTheOriginIsLitAsAtTheOrigin) {
    // The same scene moved 1e4 and 1e5 along x (a site in survey coordinates): shadow rays
    // towards a point of a sphere light or an emissive mesh stopped a relative 1e-4 short of it,
    // less than the rounding of coordinates there, and ended inside the light: under NEE the
    // image lost 10% of its light at 1e4 and 36% at 1e5, with no word.
    const test::TempDir dir("far_scene");
    const std::string name = "glossy_sphere_light.toml";
    const auto at = [&](const std::string& file) {
        FrameRequest req = test::quiet_request(dir.file(file));
        req.options.threads = 2;
        req.options.spp_override = 64;
        req.options.strategy = Strategy::NeeOnly;
        const FrameResult f = render_frame(req);
        return std::accumulate(f.image.begin(), f.image.end(), 0.0);
    };
    std::ofstream(dir.file("origin.toml")) << test::scene_text(name);
    const double origin = at("origin.toml");
    ASSERT_GT(origin, 0.0);
    for (const double x : {1e4, 1e5}) {
        const std::string file = fmt::format("far{}.toml", x);
        std::ofstream(dir.file(file)) << test::scene_text(
            name,
            {{"position = [0, 1.2, 3]", fmt::format("position = [{}, 1.2, 3]", x)},
             {"look_at = [0, 0, 0]", fmt::format("look_at = [{}, 0, 0]", x)},
             {"scale = 4", fmt::format("scale = 4\ntranslate = [{}, 0, 0]", x)},
             {"translate = [-0.8, 1.0, -1.5]", fmt::format("translate = [{}, 1.0, -1.5]", x - 0.8)},
             {"center = [0.6, 0.8, -1.2]", fmt::format("center = [{}, 0.8, -1.2]", x + 0.6)}});
        EXPECT_NEAR(at(file) / origin, 1.0, 0.01) << "the scene at x = " << x;
    }
}

TEST(Render, AnOccluderACentimetreFromALightFarFromTheOriginKeepsItsShadow) {
    // A black slab 0.6 m wide, 1 cm under a small quad light (or a spot light) over a floor, at
    // x = 1e4 (floats 1 mm apart): the floor the camera sees is all in its shadow, as at the
    // origin. Shadow rays that stopped 32 ulps of their coordinates short of a light (2 cm there)
    // ended before the slab: the floor was lit through it; a point or spot light has no surface
    // to stop short of and keeps every occluder.
    const test::TempDir dir("occluder_near_light");
    std::ofstream(dir.file("cube.obj"))
        << "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\n"
           "v -1 1 1\nf 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 2 6 7 3\nf 3 7 8 4\nf 4 8 5 1\n";
    const auto total = [&](const std::string& light) {
        std::ofstream(dir.file("s.toml")) << fmt::format(
            R"([render]
width = 32
height = 18
spp = 16
max_depth = 1
[camera]
position = [10000.0, 4, 5000.01]
look_at = [10000.0, 0, 5000.0]
fov = 60
[[material]]
name = "floor"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.5 }}
[[material]]
name = "black"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.0 }}
[[object]]
mesh = "{0}/meshes/plane.ply"
material = "floor"
scale = 4
translate = [10000.0, 0, 5000.0]
[[object]]
mesh = "{1}"
material = "black"
scale = [0.3, 0.002, 0.3]
translate = [10000.0, 0.988, 5000.0]
{2}
)",
            test::asset_dir(), dir.file("cube.obj"), light);
        FrameRequest req = test::quiet_request(dir.file("s.toml"));
        req.options.threads = 2;
        req.options.strategy = Strategy::NeeOnly;
        const FrameResult f = render_frame(req);
        return std::accumulate(f.image.begin(), f.image.end(), 0.0);
    };
    EXPECT_EQ(total("[[light]]\ntype = \"quad\"\ncorner = [9999.95, 1.0, 4999.95]\n"
                    "edge1 = [0.1, 0, 0]\nedge2 = [0, 0, 0.1]\nintensity = 30"),
              0.0);
    EXPECT_EQ(total("[[light]]\ntype = \"spot\"\nposition = [10000.0, 1.0, 5000.0]\n"
                    "look_at = [10000.0, 0, 5000.0]\ncone_angle = 70\nintensity = 1"),
              0.0);
}

TEST(Render, SceneWithoutLightsSkipsTheLightSystem) {
    const FrameResult r = render("furnace_sphere.toml", 1, 1);
    const auto& lights = report(r, "area_lights");
    EXPECT_FALSE(lights.ran);
    EXPECT_EQ(lights.reason, "no QuadLight, SphereLight, Emission");
    EXPECT_TRUE(report(r, "environment").ran);
    EXPECT_TRUE(report(r, "render").ran);
}

TEST(Render, UnusedMaterialNeverOpensItsPlugin) {
    const FrameResult r = render("unused_material.toml", 1, 1);
    EXPECT_EQ(r.plugins_opened, std::vector<std::string>{"smooth"})
        << "the unused material names a plugin that does not exist; it must not be looked for";
}

// The smooth plugin's models read no footprint (SPANGLE_IGNORES_FOOTPRINT): a scene of them
// alone gets none computed, and renders to the same bits as with them. delta_hard_cases has a
// mirror, glass and a coat, whose specular bounces carry ray differentials when footprints are
// on.
TEST(Render, FootprintsAreLeftOutWhereNothingReadsThemToTheSameBits) {
    for (const char* scene : {"small_lit.toml", "delta_hard_cases.toml", "caustic_mirror.toml"}) {
        const std::string path = test::test_dir() + "/scenes/" + scene;
        const FrameResult without = render_path(path, 2);
        const FrameResult with = render_path(path, 2, 0, Strategy::Mis, true);
        EXPECT_FALSE(without.stats.footprints) << scene;
        EXPECT_TRUE(with.stats.footprints) << scene;
        ASSERT_EQ(without.image.size(), with.image.size()) << scene;
        ASSERT_FALSE(without.image.empty()) << scene;
        EXPECT_EQ(std::memcmp(without.image.data(), with.image.data(),
                              without.image.size() * sizeof(float)),
                  0)
            << scene;
    }
}

// Flakes read footprints, and so do textures and normal maps whatever their plugin.
TEST(Render, FootprintsAreComputedWhereAMaterialOrTextureReadsThem) {
    EXPECT_TRUE(render("flake_plane.toml", 2, 1).stats.footprints);
    test::TempDir dir("footprints_textured");
    const auto write = [&](const std::string& name, const std::string& albedo) {
        std::ofstream(dir.file(name)) << test::scene_text(
            "small_lit.toml",
            {{"params = { albedo = 0.5 }", "params = { albedo = " + albedo + " }"}});
        return dir.file(name);
    };
    EXPECT_TRUE(render_path(write("tex.toml", "{ texture = \"textures/red_opaque.png\" }"), 2, 1)
                    .stats.footprints);
    EXPECT_FALSE(render_path(write("plain.toml", "0.4"), 2, 1).stats.footprints);
}

TEST(Render, EmptySceneRendersTheEnvironment) {
    const FrameResult r = render("empty.toml", 1, 1);
    EXPECT_FALSE(report(r, "mesh_load").ran);
    EXPECT_FALSE(report(r, "materials").ran);
    EXPECT_FALSE(report(r, "accelerate").ran);
    for (float v : r.image) EXPECT_NEAR(v, 0.25f, 1e-6f);
}

}  // namespace
}  // namespace spangle::test_render
