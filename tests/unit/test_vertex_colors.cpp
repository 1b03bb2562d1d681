// Vertex colours: read from PLY (integer ones sRGB-encoded, floating-point ones linear), OBJ
// (`v x y z r g b`, sRGB-encoded) and glTF (COLOR_0, linear), written back by the PLY writer,
// carried through subdivision, and multiplied into a colour parameter that asks for them
// (`{ vertex_color = true }`): a render of a coloured quad shows its colours times the factor,
// and a mesh without colours shows the factor alone.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "desc_support.h"
#include "geometry/cage.h"
#include "geometry/mesh_load.h"
#include "geometry/ply_reader.h"
#include "geometry/ply_writer.h"
#include "geometry/subdivision.h"
#include "gltf_writer.h"
#include "pipeline/frame.h"
#include "scene/gltf/gltf_reader.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_vertex_colors {
namespace {

double decoded(double encoded) {
    return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

TEST(VertexColors, PlyIntegerColoursAreSrgbEncodedAndFloatOnesLinear) {
    test::TempDir dir("vertex_colors_ply");
    std::ofstream(dir.file("bytes.ply")) << "ply\nformat ascii 1.0\nelement vertex 3\n"
                                            "property float x\nproperty float y\nproperty float z\n"
                                            "property uchar red\nproperty uchar green\n"
                                            "property uchar blue\nproperty uchar alpha\n"
                                            "element face 1\nproperty list uchar int "
                                            "vertex_indices\nend_header\n"
                                            "0 0 0 255 128 0 255\n1 0 0 10 20 30 255\n"
                                            "0 1 0 0 0 0 0\n3 0 1 2\n";
    const TriangleMesh a = read_ply(dir.file("bytes.ply"), FileLoc{"t", 1, 1});
    ASSERT_EQ(a.colors.size(), 9u);
    EXPECT_FLOAT_EQ(a.colors[0], 1.0f);
    EXPECT_NEAR(a.colors[1], decoded(128.0 / 255.0), 1e-6);
    EXPECT_NEAR(a.colors[1], 0.2158605, 1e-6);
    EXPECT_FLOAT_EQ(a.colors[2], 0.0f);
    EXPECT_NEAR(a.colors[4], decoded(20.0 / 255.0), 1e-7);
    // 32-bit integer colours hold 0..255 (as the writers that use them write them); a vertex
    // with only some of the three channels has no colour, said.
    std::ofstream(dir.file("ints.ply")) << "ply\nformat ascii 1.0\nelement vertex 3\n"
                                           "property float x\nproperty float y\nproperty float z\n"
                                           "property int red\nproperty int green\n"
                                           "property int blue\nelement face 1\n"
                                           "property list uchar int vertex_indices\nend_header\n"
                                           "0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n"
                                           "3 0 1 2\n";
    EXPECT_EQ(read_ply(dir.file("ints.ply"), FileLoc{"t", 1, 1}).colors,
              (std::vector<float>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
    std::ofstream(dir.file("two.ply")) << "ply\nformat ascii 1.0\nelement vertex 3\n"
                                          "property float x\nproperty float y\nproperty float z\n"
                                          "property uchar red\nproperty uchar green\n"
                                          "element face 1\nproperty list uchar int "
                                          "vertex_indices\nend_header\n"
                                          "0 0 0 1 2\n1 0 0 3 4\n0 1 0 5 6\n3 0 1 2\n";
    const TriangleMesh two = read_ply(dir.file("two.ply"), FileLoc{"t", 1, 1});
    EXPECT_TRUE(two.colors.empty());
    ASSERT_EQ(two.notes.size(), 1u);
    EXPECT_NE(two.notes[0].find("not all three"), std::string::npos);
    std::ofstream(dir.file("floats.ply"))
        << "ply\nformat ascii 1.0\nelement vertex 3\n"
           "property float x\nproperty float y\nproperty float z\n"
           "property float red\nproperty float green\n"
           "property float blue\n"
           "element face 1\nproperty list uchar int "
           "vertex_indices\nend_header\n"
           "0 0 0 0.25 0.5 2\n1 0 0 0 0 0\n0 1 0 1 1 1\n3 0 1 2\n";
    const TriangleMesh b = read_ply(dir.file("floats.ply"), FileLoc{"t", 1, 1});
    EXPECT_EQ(b.colors, (std::vector<float>{0.25f, 0.5f, 2.0f, 0, 0, 0, 1, 1, 1}));
    // Spangle's own writer keeps them (linear floats), and the reader gives them back.
    write_ply(b, dir.file("out.ply"), "test");
    const TriangleMesh c = read_ply(dir.file("out.ply"), FileLoc{"t", 1, 1});
    EXPECT_EQ(c.colors, b.colors);
    EXPECT_EQ(mesh_content_hash(c), mesh_content_hash(b));
    TriangleMesh plain = b;
    plain.colors.clear();
    EXPECT_NE(mesh_content_hash(plain), mesh_content_hash(b)) << "colours are content";
}

TEST(VertexColors, ObjColoursAreKeptAndVerticesWithoutOneAreWhite) {
    test::TempDir dir("vertex_colors_obj");
    std::ofstream(dir.file("c.obj")) << "v 0 0 0 1 0.5 0\nv 1 0 0 0 0 1\nv 1 1 0\nv 0 1 0 1.0 "
                                        "1.0 1.0\nv 2 2 2 1\nf 1 2 3 4\n";
    const TriangleMesh m = load_mesh(dir.file("c.obj"), FileLoc{"t", 1, 1});
    ASSERT_EQ(m.vertex_count(), 4u);
    ASSERT_EQ(m.colors.size(), 12u);
    EXPECT_FLOAT_EQ(m.colors[0], 1.0f);
    EXPECT_NEAR(m.colors[1], decoded(0.5), 1e-6);
    EXPECT_EQ(m.color(2), Vec3(1, 1, 1)) << "a vertex without a colour is white";
    bool noted = false;
    for (const std::string& n : m.notes) noted = noted || n.find("no colour") != std::string::npos;
    EXPECT_TRUE(noted);
    // `v x y z w` is a weight, not a colour; a file without colours has none.
    std::ofstream(dir.file("w.obj")) << "v 0 0 0 1\nv 1 0 0 1\nv 1 1 0 1\nf 1 2 3\n";
    EXPECT_TRUE(load_mesh(dir.file("w.obj"), FileLoc{"t", 1, 1}).colors.empty());
    // Colours written 0..255 (any above 1) are read so, said; a fourth number (alpha) is
    // allowed; ZBrush's #MRGB polypaint is said not to be read.
    std::ofstream(dir.file("bytes.obj")) << "v 0 0 0 255 128 0 255\nv 1 0 0 0 0 255 255\n"
                                            "v 1 1 0 0 0 0 255\n#MRGB ff00ff00\nf 1 2 3\n";
    const TriangleMesh b = load_mesh(dir.file("bytes.obj"), FileLoc{"t", 1, 1});
    ASSERT_EQ(b.colors.size(), 9u);
    EXPECT_FLOAT_EQ(b.colors[0], 1.0f);
    EXPECT_NEAR(b.colors[1], decoded(128.0 / 255.0), 1e-6);
    EXPECT_FLOAT_EQ(b.colors[5], 1.0f);
    std::string notes;
    for (const std::string& n : b.notes) notes += n + "\n";
    EXPECT_NE(notes.find("0..255"), std::string::npos) << notes;
    EXPECT_NE(notes.find("#MRGB"), std::string::npos) << notes;
}

TEST(VertexColors, SubdivisionCarriesThemToTheLimit) {
    test::TempDir dir("vertex_colors_cage");
    // A cube cage: one constant colour stays that colour everywhere; a gradient stays within
    // the cage's range.
    const char* cube =
        "v -1 -1 -1 {0}\nv 1 -1 -1 {0}\nv 1 1 -1 {1}\nv -1 1 -1 {1}\n"
        "v -1 -1 1 {0}\nv 1 -1 1 {0}\nv 1 1 1 {1}\nv -1 1 1 {1}\n"
        "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    std::ofstream(dir.file("flat.obj"))
        << fmt::format(fmt::runtime(cube), "0.5 0.2 0.8", "0.5 0.2 0.8");
    std::ofstream(dir.file("ramp.obj")) << fmt::format(fmt::runtime(cube), "0 0 0", "1 1 1");
    SubdivOptions o;
    o.level = 3;
    const TriangleMesh flat =
        subdivide(load_cage(dir.file("flat.obj"), FileLoc{"t", 1, 1}), o, FileLoc{"t", 1, 1});
    ASSERT_EQ(flat.colors.size(), flat.positions.size());
    const auto c = static_cast<float>(decoded(0.5));
    for (std::size_t i = 0; i < flat.vertex_count(); ++i)
        ASSERT_NEAR(flat.colors[3 * i], c, 1e-6) << "vertex " << i;
    const TriangleMesh ramp =
        subdivide(load_cage(dir.file("ramp.obj"), FileLoc{"t", 1, 1}), o, FileLoc{"t", 1, 1});
    float lo = 1, hi = 0;
    for (float x : ramp.colors) {
        lo = std::min(lo, x);
        hi = std::max(hi, x);
    }
    EXPECT_GE(lo, 0.0f);
    EXPECT_LE(hi, 1.0f);
    EXPECT_GT(hi - lo, 0.5f) << "the ramp is kept, not averaged away";
    // Colour follows height: the top of the limit surface is lighter than its bottom.
    for (std::size_t i = 0; i < ramp.vertex_count(); ++i)
        if (std::fabs(ramp.positions[3 * i + 1]) > 0.5f) {
            ASSERT_EQ(ramp.positions[3 * i + 1] > 0.0f, ramp.colors[3 * i] > 0.5f) << i;
        }
}

/** A quad facing the camera at x = `x` (PLY, vertex colours `rgb` on every corner unless
 *  empty), as scene text. */
std::string quad_ply(const test::TempDir& dir, const std::string& name, const std::string& rgb) {
    std::ofstream out(dir.file(name));
    out << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\n";
    if (!rgb.empty()) out << "property float red\nproperty float green\nproperty float blue\n";
    out << "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    for (const char* p : {"-1 -1 0", "1 -1 0", "1 1 0", "-1 1 0"}) out << p << " " << rgb << "\n";
    out << "4 0 1 2 3\n";
    return dir.file(name);
}

TEST(VertexColors, MultiplyTheParameterThatAsksForThem) {
    test::TempDir dir("vertex_colors_render");
    const std::string colored = quad_ply(dir, "colored.ply", "0.2 0.6 0.9");
    const std::string plain = quad_ply(dir, "plain.ply", "");
    // Diffuse quads under a white sky and nothing else: each pixel on a quad is its albedo.
    const std::string scene = fmt::format(R"([render]
width = 40
height = 20
spp = 16
max_depth = 2
[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
fov = 30
[environment]
color = [1, 1, 1]
[[material]]
name = "tinted"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = {{ vertex_color = true, scale = 0.5 }} }}
[[object]]
mesh = "{}"
material = "tinted"
translate = [-1.2, 0, 0]
[[object]]
mesh = "{}"
material = "tinted"
translate = [1.2, 0, 0]
)",
                                          colored, plain);
    const FrameResult r = render_frame(test::text_request(dir, "scene.toml", scene));
    // The frame is 2.68 units high (fov 30 degrees, vertical, at 5): 7.5 pixels a unit, so the
    // quads cover x 3.6..18.5 and 21.5..36.4, y 2.5..17.5.
    const Vec3 left = test::block_mean(r, 9, 8, 4, 4), right = test::block_mean(r, 27, 8, 4, 4);
    // The colours are linear Rec.709; the image is in the working space (ACEScg by default).
    float want[3] = {0.1f, 0.3f, 0.45f};
    r.color.convert("lin_rec709", r.color.working_space(), want, 1);
    EXPECT_NEAR(left.x, want[0], 0.01f * want[0]);
    EXPECT_NEAR(left.y, want[1], 0.01f * want[1]);
    EXPECT_NEAR(left.z, want[2], 0.01f * want[2]);
    EXPECT_GT(std::fabs(want[0] - 0.1f), 0.05f) << "the test sees the conversion";
    for (float c : {right.x, right.y, right.z})
        EXPECT_NEAR(c, 0.5f, 0.015f) << "a mesh without colours reads 1";
}

TEST(VertexColors, TheirScaleIsAColourOfTheirOwnSpace) {
    // `scale` multiplies the vertex colours before they are converted (both linear Rec.709, as
    // glTF's baseColorFactor times COLOR_0): a red factor on a mesh without colours renders as
    // the red colour itself, and on green vertices as black (per channel in the working space,
    // ACEScg, red times green was not black).
    test::TempDir dir("vertex_colors_scale");
    const std::string green = quad_ply(dir, "green.ply", "0 1 0");
    const std::string plain = quad_ply(dir, "plain.ply", "");
    const auto scene = [&](const std::string& mesh, const std::string& albedo) {
        return fmt::format(R"([render]
width = 20
height = 20
spp = 16
max_depth = 2
[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
fov = 10
[environment]
color = [1, 1, 1]
[[material]]
name = "m"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = {} }}
[[object]]
mesh = "{}"
material = "m"
)",
                           albedo, mesh);
    };
    const auto centre = [&](const std::string& mesh, const std::string& albedo) {
        return test::block_mean(
            render_frame(test::text_request(dir, "s.toml", scene(mesh, albedo))), 8, 8, 4, 4);
    };
    const Vec3 factor = centre(plain, "{ vertex_color = true, scale = [1, 0, 0] }");
    const Vec3 colour = centre(plain, "{ rgb = [1, 0, 0], space = \"lin_rec709\" }");
    EXPECT_NEAR(factor.x, colour.x, 0.01f * colour.x);
    EXPECT_NEAR(factor.y, colour.y, 0.01f);
    EXPECT_NEAR(factor.z, colour.z, 0.01f);
    EXPECT_GT(colour.y, 0.03f) << "Rec.709 red has green in ACEScg: the test sees the space";
    const Vec3 black = centre(green, "{ vertex_color = true, scale = [1, 0, 0] }");
    EXPECT_LT(std::max({std::fabs(black.x), std::fabs(black.y), std::fabs(black.z)}), 1e-3f);
}

TEST(VertexColors, GltfColor0TintsTheBaseColour) {
    test::TempDir dir("vertex_colors_gltf");
    test::GltfWriter w;
    const int pos = w.floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, "VEC3", 3);
    const int col = w.floats({1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1, 0.5f, 1, 1, 1, 1}, "VEC4", 4);
    const int idx = w.u16({0, 1, 2, 0, 2, 3});
    const std::string body = fmt::format(
        R"("nodes":[{{"mesh":0}},{{"mesh":1}}],"meshes":[)"
        R"({{"primitives":[{{"attributes":{{"POSITION":{},"COLOR_0":{}}},"indices":{},"material":0}}]}},)"
        R"({{"primitives":[{{"attributes":{{"POSITION":{}}},"indices":{},"material":1}}]}}],)"
        R"("materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.5,0.5,0.5,1]}}}},)"
        R"({{"pbrMetallicRoughness":{{"baseColorFactor":[0.5,0.5,0.5,1]}}}}])",
        pos, col, idx, pos, idx);
    w.write_gltf(dir.file("c.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("c.gltf"), {});
    ASSERT_EQ(d.objects.size(), 2u);
    const TriangleMesh& m = *std::get<InlineMeshShape>(d.objects[0].shape).mesh;
    EXPECT_EQ(m.colors, (std::vector<float>{1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1}));
    bool alpha_noted = false;
    for (const std::string& n : d.notes)
        alpha_noted = alpha_noted || n.find("COLOR_0's alpha is dropped") != std::string::npos;
    EXPECT_TRUE(alpha_noted);
    ASSERT_EQ(d.materials.size(), 2u);
    const ParamDesc* tinted = test::param(d.materials[0], "base_color");
    ASSERT_NE(tinted, nullptr);
    EXPECT_EQ(tinted->kind, ParamDesc::Kind::Texture);
    EXPECT_TRUE(tinted->texture.vertex_color);
    EXPECT_TRUE(tinted->texture.path.empty());
    EXPECT_FLOAT_EQ(tinted->texture.scale[0], 0.5f);
    // The material of primitives without COLOR_0 keeps a plain colour.
    const ParamDesc* plain = test::param(d.materials[1], "base_color");
    ASSERT_NE(plain, nullptr);
    EXPECT_EQ(plain->kind, ParamDesc::Kind::Color);
}

}  // namespace
}  // namespace spangle::test_vertex_colors
