// Cut-outs: a material's `alpha` lets rays through its surfaces. The ray tracer's filter alone
// (fixed coverage: all, none, a cutoff, by chance; the chance per ray and triangle, the same for
// a ray traced alone or in a stream), then whole renders: an alpha texture's transparent half
// shows the background, a constant alpha lets its share through, a cut-out casts no shadow
// where it is cut, and the bad values are refused at their line.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "accel/embree_scene.h"
#include "core/hash.h"
#include "pipeline/frame.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_cut_outs {
namespace {

/** Two unit squares facing +z, one at z = 0 and one at z = -1 (one mesh, two instances). */
struct Layers {
    GeometryStore geometry;
    std::vector<Instance> instances;
    EmbreeScene scene;

    Layers() {
        auto m = std::make_shared<TriangleMesh>();
        m->positions = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
        m->indices = {0, 1, 2, 0, 2, 3};
        geometry.meshes.push_back(m);
        for (int k = 0; k < 2; ++k) {
            Instance inst;
            inst.to_world = Affine::translate(Vec3(0.0f, 0.0f, -static_cast<float>(k)));
            inst.to_object = inst.to_world.inverse();
            inst.normal_to_world = inst.to_world.normal_matrix();
            instances.push_back(inst);
        }
        scene.build(geometry, instances, {}, {});
    }
};

float constant_coverage(const void* self, uint32_t, float, float) {
    return *static_cast<const float*>(self);
}

/** Where rays from z = 1 straight down meet: 0 nothing, 1 the front square, 2 the back one. */
int first_layer(const Layers& f, Vec3 o, const CutOuts* cuts) {
    Hit hit;
    if (!f.scene.intersect(o, Vec3(0, 0, -1), 1e30f, hit, 0.0f, cuts)) return 0;
    return hit.t < 1.5f ? 1 : 2;
}

/** n ray origins spread over the squares, at z = 1. */
std::vector<Vec3> origins(std::size_t n) {
    std::vector<Vec3> o;
    for (std::size_t i = 0; i < n; ++i)
        o.emplace_back(1.8f * to_unit_float(hash2(i, 11)) - 0.9f,
                       1.8f * to_unit_float(hash2(i, 12)) - 0.9f, 1.0f);
    return o;
}

TEST(CutOut, FixedCoverageLetsRaysThroughOrNot) {
    Layers f;
    const Vec3 o(0.3f, 0.2f, 1.0f);
    float none = 0.0f, all = 1.0f, some = 0.4f;
    CutOuts cuts(2);
    EXPECT_EQ(first_layer(f, o, &cuts), 1) << "entries without a coverage are opaque";
    cuts[0] = CutOut{constant_coverage, &none, -1.0f};
    EXPECT_EQ(first_layer(f, o, &cuts), 2);
    EXPECT_EQ(first_layer(f, o, nullptr), 1) << "no cut-outs given: every surface opaque";
    cuts[1] = CutOut{constant_coverage, &none, -1.0f};
    EXPECT_EQ(first_layer(f, o, &cuts), 0);
    EXPECT_FALSE(f.scene.occluded(o, Vec3(0, 0, -1), 10.0f, 0.0f, &cuts));
    EXPECT_TRUE(f.scene.occluded(o, Vec3(0, 0, -1), 10.0f));
    cuts[0] = CutOut{constant_coverage, &all, -1.0f};
    EXPECT_EQ(first_layer(f, o, &cuts), 1);
    // A cutoff: a hit counts where coverage >= cutoff.
    cuts[0] = CutOut{constant_coverage, &some, 0.5f};
    EXPECT_EQ(first_layer(f, o, &cuts), 0);
    cuts[0] = CutOut{constant_coverage, &some, 0.4f};
    EXPECT_EQ(first_layer(f, o, &cuts), 1);
}

TEST(CutOut, ACoverageBetweenStopsThatShareOfRaysPerLayer) {
    Layers f;
    float half = 0.5f, third = 0.3f;
    const CutOuts cuts = {CutOut{constant_coverage, &third, -1.0f},
                          CutOut{constant_coverage, &half, -1.0f}};
    const std::size_t n = 40000;
    const std::vector<Vec3> o = origins(n);
    std::size_t front = 0, back = 0, through = 0;
    for (const Vec3& p : o) {
        const int k = first_layer(f, p, &cuts);
        front += k == 1;
        back += k == 2;
        through += k == 0;
    }
    // Binomial shares; 5 standard deviations (of at most 0.0025 here).
    const auto near = [n](std::size_t count, double p) {
        const double share = static_cast<double>(count) / static_cast<double>(n);
        return std::fabs(share - p) < 5.0 * std::sqrt(p * (1.0 - p) / static_cast<double>(n));
    };
    EXPECT_TRUE(near(front, 0.3)) << front;
    EXPECT_TRUE(near(back, 0.7 * 0.5)) << back;
    // Each layer decides for itself: both let a ray through 0.7 x 0.5 of the time (one number
    // per ray would let 0.5 through).
    EXPECT_TRUE(near(through, 0.7 * 0.5)) << through;
    // The same ray decides alike alone, in a stream, and for a shadow ray over the same line.
    std::vector<Vec3> d(n, Vec3(0, 0, -1));
    std::vector<Hit> hits(n);
    std::vector<uint8_t> found(n), blocked(n);
    std::vector<float> tmax(n, 10.0f);
    f.scene.intersect_stream(o.data(), d.data(), n, hits.data(), found.data(), nullptr, nullptr,
                             &cuts);
    f.scene.occluded_stream(o.data(), d.data(), tmax.data(), n, blocked.data(), nullptr, &cuts);
    for (std::size_t i = 0; i < n; ++i) {
        const int k = first_layer(f, o[i], &cuts);
        ASSERT_EQ(found[i] != 0, k != 0) << i;
        ASSERT_EQ(blocked[i] != 0, k != 0) << i;
        if (k != 0) {
            ASSERT_EQ(hits[i].t < 1.5f, k == 1) << i;
        }
    }
}

/** A 64 x 64 view filled by a unit plane of material `material` in front of a white sky (one
 *  bounce: the plane is black where it is met). */
std::string sky_scene(const std::string& material, const std::string& extra = "") {
    return fmt::format(R"(
[render]
width = 64
height = 64
spp = 8
max_depth = 1
filter = "box"
working_space = "lin_rec709"
[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]
fov = 20
[environment]
color = [1, 1, 1]
[[material]]
name = "m"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0, 0, 0] }}
{}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "m"
rotate = [90, 0, 0]
scale = 0.6
{}
)",
                       material, test::asset_dir(), extra);
}

FrameResult render_text(const test::TempDir& dir, const std::string& name,
                        const std::string& text) {
    return render_frame(test::text_request(dir, name, text));
}

/** Mean of the green channel over columns [x0, x1) of a 64-wide image. */
double column_mean(const FrameResult& r, uint32_t x0, uint32_t x1) {
    double sum = 0.0;
    for (uint32_t y = 0; y < r.height; ++y)
        for (uint32_t x = x0; x < x1; ++x) sum += r.image[3 * (y * r.width + x) + 1];
    return sum / (static_cast<double>(r.height) * (x1 - x0));
}

TEST(CutOut, AnAlphaTexturesClearHalfShowsTheSky) {
    test::TempDir dir("cut_out_texture");
    const std::string tex = test::test_dir() + "/scenes/textures/half_alpha.png";
    // half_alpha.png: alpha 0 on its left half, 1 on its right; the plane's uvs span [0, 4].
    const FrameResult r =
        render_text(dir, "a.toml",
                    sky_scene(fmt::format(
                        "alpha = {{ texture = \"{}\", uv_transform = {{ scale = 0.25 }} }}", tex)));
    ASSERT_EQ(r.width, 64u);
    EXPECT_GT(column_mean(r, 0, 26), 0.999) << "the clear half shows the sky";
    EXPECT_LT(column_mean(r, 38, 64), 0.001) << "the opaque half is the black plane";
    // The same image's green channel (160/255) read as alpha: that share of rays meets it.
    const FrameResult g = render_text(
        dir, "g.toml",
        sky_scene(fmt::format("alpha = {{ texture = \"{}\", channel = \"g\", uv_transform = {{ "
                              "scale = 0.25 }} }}",
                              tex)));
    const double sky = column_mean(g, 0, 64);
    // 64 x 64 x 8 samples: the share's standard deviation is 0.0027.
    EXPECT_NEAR(sky, 1.0 - 160.0 / 255.0, 0.02);
    // Without a cut-out the plane hides the sky everywhere (the checks above can fail).
    const FrameResult plain = render_text(dir, "p.toml", sky_scene(""));
    EXPECT_LT(column_mean(plain, 0, 64), 0.001);
    // The alpha channel of an image without one reads 1 (as glTF and Blender read it), times
    // scale: a grey mask asked for its "a" is whole; at scale 0 it is not there.
    const std::string grey = test::test_dir() + "/scenes/textures/roughness_ramp.png";
    const FrameResult whole = render_text(
        dir, "w.toml",
        sky_scene(fmt::format("alpha = {{ texture = \"{}\", channel = \"a\" }}", grey)));
    EXPECT_LT(column_mean(whole, 0, 64), 0.001);
    const FrameResult none = render_text(
        dir, "n.toml",
        sky_scene(fmt::format("alpha = {{ texture = \"{}\", channel = \"a\", scale = 0 }}", grey)));
    EXPECT_GT(column_mean(none, 0, 64), 0.999);
    // r, g and b of a grey image are its grey: the ramp cuts where it is below the cutoff (its
    // left, 0.02 to 0.6 across), without an error.
    const FrameResult ramp = render_text(
        dir, "r.toml",
        sky_scene(fmt::format("alpha = {{ texture = \"{}\", channel = \"b\", space = \"raw\", "
                              "uv_transform = {{ scale = 0.25 }} }}\nalpha_cutoff = 0.45",
                              grey)));
    EXPECT_GT(column_mean(ramp, 0, 20), 0.999);
    EXPECT_LT(column_mean(ramp, 56, 64), 0.001);
    // pbrt's rule: an alpha of 1 everywhere is dropped and the colours' mean (red: 1/3) read.
    const std::string red = test::test_dir() + "/scenes/textures/red_opaque.png";
    const auto pbrt = [&](const char* name, double cutoff) {
        return column_mean(
            render_text(dir, name,
                        sky_scene(fmt::format("alpha = {{ texture = \"{}\", channel = \"pbrt\", "
                                              "space = \"raw\" }}\nalpha_cutoff = {}",
                                              red, cutoff))),
            0, 64);
    };
    EXPECT_LT(pbrt("p3.toml", 0.3), 0.001) << "1/3 >= 0.3: met";
    EXPECT_GT(pbrt("p4.toml", 0.4), 0.999) << "1/3 < 0.4: cut";
    // Its alpha channel (1) without pbrt's rule: whole at either cutoff.
    const FrameResult own = render_text(
        dir, "pa.toml",
        sky_scene(fmt::format("alpha = {{ texture = \"{}\" }}\nalpha_cutoff = 0.4", red)));
    EXPECT_LT(column_mean(own, 0, 64), 0.001);
}

TEST(CutOut, AConstantAlphaLetsItsShareThroughOrIsCutWhole) {
    test::TempDir dir("cut_out_constant");
    const FrameResult quarter = render_text(dir, "q.toml", sky_scene("alpha = 0.25"));
    EXPECT_NEAR(column_mean(quarter, 0, 64), 0.75, 0.02);
    const FrameResult below =
        render_text(dir, "b.toml", sky_scene("alpha = 0.4\nalpha_cutoff = 0.5"));
    EXPECT_GT(column_mean(below, 0, 64), 0.999) << "under the cutoff: not there";
    const FrameResult above =
        render_text(dir, "a.toml", sky_scene("alpha = 0.6\nalpha_cutoff = 0.5"));
    EXPECT_LT(column_mean(above, 0, 64), 0.001) << "over the cutoff: whole";
    // The same render twice is the same image (the chance is a hash of the ray).
    const FrameResult again = render_text(dir, "q2.toml", sky_scene("alpha = 0.25"));
    EXPECT_EQ(again.image, quarter.image);
}

TEST(CutOut, ACutOutCastsNoShadowWhereItIsCut) {
    test::TempDir dir("cut_out_shadow");
    // A white floor lit by a sun straight above, seen from above; a plane between them.
    const auto scene = [](const std::string& alpha, bool blocker) {
        return fmt::format(R"(
[render]
width = 32
height = 32
spp = 4
max_depth = 1
filter = "box"
working_space = "lin_rec709"
[camera]
position = [0, 3, 0.001]
look_at = [0, 0, 0]
fov = 20
[[material]]
name = "floor"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0.8, 0.8, 0.8] }}
[[material]]
name = "screen"
plugin = "smooth"
model = "diffuse"
{}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "floor"
{}
[[light]]
type = "distant"
direction = [0, 1, 0]
intensity = 3
)",
                           alpha, test::asset_dir(),
                           blocker ? fmt::format("[[object]]\nmesh = \"{}/meshes/plane.ply\"\n"
                                                 "material = \"screen\"\ntranslate = [0, 5, 0]\n"
                                                 "scale = 3",
                                                 test::asset_dir())
                                   : std::string());
    };
    const FrameResult open = render_text(dir, "open.toml", scene("", false));
    const FrameResult cut = render_text(dir, "cut.toml", scene("alpha = 0", true));
    const FrameResult shade = render_text(dir, "shade.toml", scene("", true));
    const double lit = column_mean(open, 0, 32);
    ASSERT_GT(lit, 0.1);
    EXPECT_NEAR(column_mean(cut, 0, 32), lit, 1e-6 * lit) << "a fully cut screen casts no shadow";
    EXPECT_LT(column_mean(shade, 0, 32), 0.01 * lit) << "the same screen opaque shades the floor";
}

TEST(CutOut, AnEmittersLightIsCutAsItsSurfaceIs) {
    // A lamp (an emitting quad) of alpha 0.5 over a white floor, seen from under the lamp:
    // light sampling weighs each of
    // its points by the share of rays that meet it, so it lights the floor as BSDF rays find it
    // (light sampling lit the floor with the whole lamp: an alpha 0 lamp still shone).
    test::TempDir dir("cut_out_emitter");
    const auto scene = [](const std::string& alpha) {
        return fmt::format(R"(
[render]
width = 32
height = 32
spp = 64
max_depth = 1
filter = "box"
working_space = "lin_rec709"
[camera]
position = [0, 0, 1.5]
look_at = [0, 0, 0]
fov = 10
[[material]]
name = "floor"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [1, 1, 1] }}
[[material]]
name = "lamp"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0, 0, 0] }}
{}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "floor"
rotate = [90, 0, 0]
scale = 3
[[object]]
mesh = "{}/meshes/plane.ply"
material = "lamp"
rotate = [-90, 0, 0]
translate = [0, 0, 2]
scale = 2
emission = [1, 1, 1]
)",
                           alpha, test::asset_dir(), test::asset_dir());
    };
    const auto floor_mean = [&](const std::string& alpha, Strategy strategy) {
        FrameRequest req = test::text_request(dir, "lamp.toml", scene(alpha));
        req.options.strategy = strategy;
        return column_mean(render_frame(req), 0, 32);
    };
    const double opaque = floor_mean("", Strategy::Mis);
    ASSERT_GT(opaque, 0.05);
    for (Strategy st : {Strategy::Mis, Strategy::NeeOnly, Strategy::BsdfOnly}) {
        EXPECT_NEAR(floor_mean("alpha = 0.5", st), 0.5 * opaque, 0.03 * opaque)
            << static_cast<int>(st);
        EXPECT_EQ(floor_mean("alpha = 0", st), 0.0) << static_cast<int>(st);
        EXPECT_EQ(floor_mean("alpha = 0.4\nalpha_cutoff = 0.5", st), 0.0);
    }
}

}  // namespace
}  // namespace spangle::test_cut_outs
