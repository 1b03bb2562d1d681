#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>

#include "core/error.h"
#include "geometry/mesh_load.h"
#include "test_support.h"

namespace spangle {
namespace {

TEST(MeshLoad, ObjWithNormalsAndUvs) {
    const TriangleMesh m = load_mesh(test::asset_dir() + "/meshes/sphere.obj", {});
    EXPECT_GT(m.triangle_count(), 1000u);
    ASSERT_EQ(m.normals.size(), m.positions.size());
    ASSERT_EQ(m.uvs.size() / 2, m.vertex_count());
    for (std::size_t i = 0; i < m.vertex_count(); ++i) {
        const Vec3 n(m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2]);
        EXPECT_NEAR(length(n), 1.0f, 1e-4f);
        EXPECT_NEAR(length(m.position(static_cast<uint32_t>(i))), 1.0f, 1e-4f) << "unit sphere";
    }
}

TEST(MeshLoad, BinaryLittleEndianPly) {
    const TriangleMesh m = load_mesh(test::asset_dir() + "/meshes/plane.ply", {});
    EXPECT_EQ(m.vertex_count(), 4u);
    EXPECT_EQ(m.triangle_count(), 2u);
    ASSERT_EQ(m.normals.size(), 12u);
    EXPECT_FLOAT_EQ(m.normals[1], 1.0f);
    ASSERT_EQ(m.uvs.size(), 8u);
    EXPECT_FLOAT_EQ(*std::max_element(m.uvs.begin(), m.uvs.end()), 4.0f);
}

TEST(MeshLoad, AsciiPlyAndQuadsAreTriangulated) {
    test::TempDir dir("mesh_ascii");
    std::ofstream(dir.file("quad.ply"))
        << "ply\nformat ascii 1.0\nelement vertex 4\n"
           "property float x\nproperty float y\nproperty float z\n"
           "element face 1\nproperty list uchar int vertex_indices\n"
           "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
    const TriangleMesh m = load_mesh(dir.file("quad.ply"), {});
    EXPECT_EQ(m.triangle_count(), 2u);
    EXPECT_TRUE(m.normals.empty()) << "no normals in the file, none invented";
    EXPECT_TRUE(m.uvs.empty());
    std::ofstream(dir.file("quad.obj")) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt "
                                           "1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
    const TriangleMesh o = load_mesh(dir.file("quad.obj"), {});
    EXPECT_EQ(o.triangle_count(), 2u);
    EXPECT_EQ(o.uvs.size() / 2, o.vertex_count());
}

TEST(MeshLoad, BigEndianPlyWithOtherElementsAndTypes) {
    // Spangle's own PLY reader: big-endian doubles, s/t uvs, an element it does not use (read
    // through, not misread as data of the next), a non-list face property, a ushort count.
    test::TempDir dir("mesh_big_endian");
    std::string data =
        "ply\r\nformat binary_big_endian 1.0\r\ncomment made by hand\r\n"
        "element material 2\r\nproperty uchar red\r\nproperty list uchar float weights\r\n"
        "element vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\n"
        "property float s\r\nproperty float t\r\n"
        "element face 1\r\nproperty int flags\r\nproperty list ushort uint vertex_indices\r\n"
        "end_header\r\n";
    const auto put = [&](const void* p, std::size_t n) {
        const auto* b = static_cast<const unsigned char*>(p);
        for (std::size_t i = 0; i < n; ++i) data.push_back(static_cast<char>(b[n - 1 - i]));
    };
    for (int m = 0; m < 2; ++m) {  // material: red, 2 weights
        data.push_back(static_cast<char>(200));
        data.push_back(2);
        const float w = 0.5f;
        put(&w, 4);
        put(&w, 4);
    }
    const double xyz[3][3] = {{0, 0, 0}, {2, 0, 0}, {0, 3, 0}};
    for (int v = 0; v < 3; ++v) {
        for (double c : xyz[v]) put(&c, 8);
        const float st[2] = {0.25f * static_cast<float>(v), 0.5f};
        put(&st[0], 4);
        put(&st[1], 4);
    }
    const int32_t flags = 7;
    put(&flags, 4);
    const uint16_t n = 3;
    put(&n, 2);
    for (uint32_t i : {0u, 1u, 2u}) put(&i, 4);
    std::ofstream(dir.file("be.ply"), std::ios::binary) << data;
    const TriangleMesh m = load_mesh(dir.file("be.ply"), {});
    ASSERT_EQ(m.vertex_count(), 3u);
    ASSERT_EQ(m.triangle_count(), 1u);
    EXPECT_FLOAT_EQ(m.positions[3], 2.0f);
    EXPECT_FLOAT_EQ(m.positions[7], 3.0f);
    ASSERT_EQ(m.uvs.size(), 6u);
    EXPECT_FLOAT_EQ(m.uvs[4], 0.5f);
    EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2}));
}

TEST(MeshLoad, ErrorsNameTheSceneLineAndTheFile) {
    const FileLoc ref{"scene.toml", 12, 8};
    try {
        load_mesh(test::test_dir() + "/scenes_bad/meshes/nan_vertex.obj", ref);
        FAIL();
    } catch (const SpangleError& e) {
        const std::string msg = e.what();
        EXPECT_EQ(msg.rfind("scene.toml:12:8: error: mesh '", 0), 0u) << msg;
        EXPECT_NE(msg.find("nan_vertex.obj': vertex 1 has a non-finite position"),
                  std::string::npos)
            << msg;
    }
    try {
        load_mesh(test::test_dir() + "/scenes_bad/meshes/ok.stl", ref);
        FAIL();
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("not found"), std::string::npos) << e.what();
    }
}

TEST(MeshLoad, ValidateCatchesIndicesPastTheEnd) {
    TriangleMesh m;
    m.source = "made.obj";
    m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    m.indices = {0, 1, 3};
    try {
        validate_mesh(m, {});
        FAIL();
    } catch (const SpangleError& e) {
        EXPECT_NE(
            std::string(e.what()).find("triangle 0 refers to vertex 3, but there are 3 vertices"),
            std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace spangle
