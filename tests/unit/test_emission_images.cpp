// Emission images: an emissive mesh whose radiance is an image read at its uvs (`emission =
// { texture = "file", scale }`, glTF's emissiveTexture). Seen directly it is the image times the
// intensity; it lights a floor the same through light sampling alone, BSDF sampling alone and
// both (light sampling reads the image where it samples and weighs triangles by their share of
// it); a black part of the image lights nothing; glTF's emissiveTexture becomes one, and
// `spangle convert` keeps it.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "color/image_output.h"
#include "gltf_writer.h"
#include "pipeline/frame.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/pbrt/pbrt_reader.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_emission_images {
namespace {

/** A 16 x 16 image whose left half is `left` and right half `right` (linear Rec.709, written
 *  as a float EXR tagged so). */
void write_halves(const std::string& path, Vec3 left, Vec3 right) {
    constexpr int n = 16;
    std::vector<float> rgb(3 * n * n);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const Vec3 c = x < n / 2 ? left : right;
            float* p = &rgb[3 * static_cast<std::size_t>(y * n + x)];
            p[0] = c.x;
            p[1] = c.y;
            p[2] = c.z;
        }
    ColorConfig color = test::shipped_config();
    color.set_working_space("lin_rec709");
    ExrOptions o;
    o.half = false;
    write_exr(path, rgb, n, n, color, o);
}

/** A 2 x 2 quad in the xy plane (z = 0) facing +z with uvs over the whole image. */
std::string write_screen(const test::TempDir& dir) {
    std::ofstream(dir.file("screen.obj")) << "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                                             "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
                                             "f 1/1/1 2/2/1 3/3/1 4/4/1\n";
    return dir.file("screen.obj");
}

TEST(EmissionImage, SeenDirectlyIsTheImageTimesTheIntensity) {
    test::TempDir dir("emission_image_seen");
    write_halves(dir.file("halves.exr"), {1.0f, 0.0f, 0.0f}, {0.0f, 0.25f, 1.0f});
    const std::string screen = write_screen(dir);
    const std::string scene = fmt::format(R"([render]
width = 32
height = 32
spp = 4
max_depth = 1
working_space = "lin_rec709"
[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]
fov = 20
[[material]]
name = "black"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0 }}
[[object]]
mesh = "{}"
material = "black"
emission = {{ texture = "halves.exr", space = "lin_rec709", scale = [1, 1, 0.5] }}
emission_intensity = 2
)",
                                          screen);
    const FrameResult r = render_frame(test::text_request(dir, "seen.toml", scene));
    // The screen fills the frame (2 units at 4 units, fov 20: 1.41 units high).
    const Vec3 left = test::block_mean(r, 4, 12, 6, 8), right = test::block_mean(r, 22, 12, 6, 8);
    EXPECT_NEAR(left.x, 2.0f, 1e-3f);
    EXPECT_NEAR(left.y, 0.0f, 1e-3f);
    EXPECT_NEAR(left.z, 0.0f, 1e-3f);
    EXPECT_NEAR(right.x, 0.0f, 1e-3f);
    EXPECT_NEAR(right.y, 0.5f, 1e-3f);
    EXPECT_NEAR(right.z, 1.0f, 1e-3f) << "scale multiplies the image";
}

/** A screen (the image, facing down) over a white floor, seen from below the screen. */
std::string lit_floor_scene(const std::string& screen, const std::string& emission) {
    return fmt::format(R"([render]
width = 32
height = 32
spp = 64
max_depth = 1
filter = "box"
working_space = "lin_rec709"
[camera]
position = [0, 0, 1.5]
look_at = [0, 0, 0]
fov = 40
[[material]]
name = "floor"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [1, 1, 1] }}
[[material]]
name = "black"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0 }}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "floor"
rotate = [90, 0, 0]
scale = 3
[[object]]
mesh = "{}"
material = "black"
rotate = [180, 0, 0]
translate = [0, 0, 2]
scale = 1.5
emission = {}
)",
                       test::asset_dir(), screen, emission);
}

TEST(EmissionImage, LightsAFloorAlikeUnderEveryStrategy) {
    test::TempDir dir("emission_image_strategies");
    write_halves(dir.file("halves.exr"), {1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f});
    const std::string screen = write_screen(dir);
    const auto render = [&](const std::string& emission, Strategy strategy) {
        FrameRequest req = test::text_request(dir, "lit.toml", lit_floor_scene(screen, emission));
        req.options.strategy = strategy;
        return render_frame(req);
    };
    const std::string image = R"({ texture = "halves.exr", space = "lin_rec709" })";
    // The image's halves light the floor's halves (red one side, blue the other: the screen is
    // turned over about x, so its left half stays over the floor's left).
    Vec3 means[3];
    int k = 0;
    for (Strategy st : {Strategy::Mis, Strategy::NeeOnly, Strategy::BsdfOnly}) {
        const FrameResult r = render(image, st);
        const Vec3 left = test::block_mean(r, 0, 0, 12, 32),
                   right = test::block_mean(r, 20, 0, 12, 32);
        means[k++] = test::block_mean(r, 0, 0, 32, 32);
        // (1.36 to 1: each floor point sees both halves, the near one larger.)
        EXPECT_GT(left.x, 1.25f * left.z) << static_cast<int>(st);
        EXPECT_GT(right.z, 1.25f * right.x) << static_cast<int>(st);
    }
    for (int c = 1; c < 3; ++c) {
        EXPECT_NEAR(means[c].x, means[0].x, 0.03f * means[0].x) << c;
        EXPECT_NEAR(means[c].z, means[0].z, 0.03f * means[0].z) << c;
    }
    // The image's total equals a plain emission of its mean colour's: the floor's mean
    // irradiance (the floor spans the light's whole reach) is the same.
    const FrameResult flat = render("[0.5, 0, 0.5]", Strategy::Mis);
    const Vec3 m = test::block_mean(flat, 0, 0, 32, 32);
    EXPECT_NEAR(means[0].x + means[0].z, m.x + m.z, 0.03f * (m.x + m.z));
    EXPECT_GT(means[0].x, 0.01f);
}

TEST(EmissionImage, ABlackImageLightsNothing) {
    test::TempDir dir("emission_image_black");
    write_halves(dir.file("black.exr"), {0, 0, 0}, {0, 0, 0});
    const std::string screen = write_screen(dir);
    for (Strategy st : {Strategy::Mis, Strategy::NeeOnly, Strategy::BsdfOnly}) {
        FrameRequest req = test::text_request(
            dir, "black.toml",
            lit_floor_scene(screen, R"({ texture = "black.exr", space = "lin_rec709" })"));
        req.options.strategy = st;
        const FrameResult r = render_frame(req);
        const Vec3 m = test::block_mean(r, 0, 0, 32, 32);
        EXPECT_EQ(m.x + m.y + m.z, 0.0f) << static_cast<int>(st);
    }
}

TEST(EmissionImage, GltfEmissiveTextureBecomesOne) {
    test::TempDir dir("emission_image_gltf");
    // A 2 x 1 PNG-free route: the texture as an EXR beside the file (glTF names images by uri).
    write_halves(dir.file("glow.exr"), {1, 1, 1}, {0, 0, 0});
    test::GltfWriter w;
    const int pos = w.floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, "VEC3", 3);
    const int uv = w.floats({0, 1, 1, 1, 1, 0, 0, 0}, "VEC2", 2);
    const int idx = w.u16({0, 1, 2, 0, 2, 3});
    const std::string body = fmt::format(
        R"("nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{},"TEXCOORD_0":{}}},"indices":{},"material":0}}]}}],)"
        R"("images":[{{"uri":"glow.exr"}}],"textures":[{{"source":0}}],)"
        R"("materials":[{{"emissiveFactor":[1,0.5,0.25],"emissiveTexture":{{"index":0}}}}])",
        pos, uv, idx);
    w.write_gltf(dir.file("glow.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("glow.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    ASSERT_TRUE(d.objects[0].emission.has_value());
    const EmissionDesc& e = *d.objects[0].emission;
    ASSERT_TRUE(e.texture.has_value()) << "the emissive texture is the emission's image";
    EXPECT_EQ(e.texture->path, dir.file("glow.exr"));
    EXPECT_FLOAT_EQ(e.texture->scale[1], 0.5f) << "the factor scales it";
    for (const std::string& n : d.notes)
        EXPECT_EQ(n.find("emissiveTexture is dropped"), std::string::npos) << n;
}

TEST(EmissionImage, PbrtAreaLightFilenameBecomesOne) {
    // pbrt-v4's diffuse area light with "filename": the image (at the shape's uvs) instead of
    // L, times scale; it was noted and dropped (L stood in).
    test::TempDir dir("emission_image_pbrt");
    write_halves(dir.file("glow.exr"), {1, 1, 1}, {0, 0, 0});
    std::ofstream(dir.file("glow.pbrt"))
        << "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
           "AttributeBegin\nAreaLightSource \"diffuse\" \"string filename\" \"glow.exr\" "
           "\"float scale\" 3\n"
           "Shape \"trianglemesh\" \"point3 P\" [-1 -1 0 1 -1 0 1 1 0 -1 1 0] "
           "\"point2 uv\" [0 0 1 0 1 1 0 1] \"integer indices\" [0 1 2 0 2 3]\n"
           "AttributeEnd\n";
    const SceneDescription d = read_pbrt_scene(dir.file("glow.pbrt"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    ASSERT_TRUE(d.objects[0].emission.has_value());
    const EmissionDesc& e = *d.objects[0].emission;
    ASSERT_TRUE(e.texture.has_value());
    EXPECT_EQ(e.texture->path, dir.file("glow.exr"));
    EXPECT_DOUBLE_EQ(e.intensity, 3.0);
    EXPECT_EQ(e.color.rgb, Vec3(1, 1, 1)) << "L is unused with an image";
    for (const std::string& n : d.notes)
        EXPECT_EQ(n.find("image is not supported"), std::string::npos) << n;
}

}  // namespace
}  // namespace spangle::test_emission_images
