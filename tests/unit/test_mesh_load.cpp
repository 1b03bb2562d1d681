#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>

#include <fmt/format.h>

#include "core/error.h"
#include "geometry/mesh_load.h"
#include "test_support.h"

namespace spangle::test_mesh_load {
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
    EXPECT_TRUE(m.notes.empty());
    // A newline after the binary data (writers that end every body with one) is not data left
    // over ("1 bytes follow the data its header describes" before); more than that is.
    std::ifstream in(test::asset_dir() + "/meshes/plane.ply", std::ios::binary);
    const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    const test::TempDir dir("ply_trailing");
    std::ofstream(dir.file("newline.ply"), std::ios::binary) << bytes << "\r\n";
    EXPECT_TRUE(load_mesh(dir.file("newline.ply"), {}).notes.empty());
    std::ofstream(dir.file("extra.ply"), std::ios::binary) << bytes << "\n\n\n\n\n";
    const TriangleMesh extra = load_mesh(dir.file("extra.ply"), {});
    ASSERT_EQ(extra.notes.size(), 1u);
    EXPECT_EQ(extra.notes[0],
              "5 bytes follow the data its header describes (do its element "
              "counts match the data?)");
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

TEST(MeshLoad, PlyTriangleStripsAsStanfordScansWriteThem) {
    // "element tristrips 1" with one list of indices, strips parted by -1 (the Stanford and
    // Cyberware scans, Igea among them): their triangles, each wound as the strip's first, the
    // turns without area dropped. It was "has no face element".
    test::TempDir dir("ply_strips");
    std::ofstream(dir.file("strips.ply"))
        << "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n"
           "property float z\nelement tristrips 1\nproperty list int int vertex_indices\n"
           "end_header\n0 0 0\n0 1 0\n1 0 0\n1 1 0\n2 0 0\n2 1 0\n"
           "10 0 2 1 3 3 5 -1 2 4 5\n";
    const TriangleMesh m = load_mesh(dir.file("strips.ply"), {});
    // Strip 0 2 1 3 3 5: (0 2 1), (1 2 3), then 3 3 and 3 5 turn without area; strip 2 4 5.
    EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 2, 1, 1, 2, 3, 2, 4, 5}));
    // Each entry's list starts strips of its own (the last two corners of one entry and the
    // first of the next made a triangle).
    std::ofstream(dir.file("entries.ply"))
        << "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n"
           "property float z\nelement tristrips 2\nproperty list int int vertex_indices\n"
           "end_header\n0 0 0\n0 1 0\n1 0 0\n1 1 0\n2 0 0\n2 1 0\n4 0 2 1 3\n3 2 4 5\n";
    EXPECT_EQ(load_mesh(dir.file("entries.ply"), {}).indices,
              (std::vector<uint32_t>{0, 2, 1, 1, 2, 3, 2, 4, 5}));
    // Every triangle faces the same way (+z, as the first: (0, 0) -> (1, 0) -> (0, 1)).
    for (std::size_t t = 0; t < m.triangle_count(); ++t) {
        const Vec3 a = m.position(m.indices[3 * t]), b = m.position(m.indices[3 * t + 1]),
                   c = m.position(m.indices[3 * t + 2]);
        EXPECT_GT(cross(b - a, c - a).z, 0.0f) << t;
    }
    // An index past the vertices is said of the strip that holds it (not of a "face").
    std::ofstream(dir.file("past.ply"))
        << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nelement tristrips 2\nproperty list int int vertex_indices\n"
           "end_header\n0 0 0\n0 1 0\n1 0 0\n1 1 0\n3 0 1 2\n3 1 2 7\n";
    try {
        load_mesh(dir.file("past.ply"), {});
        ADD_FAILURE() << "an index past the vertices loaded";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("strip 1 refers to vertex 7, but there are 4"),
                  std::string::npos)
            << e.what();
    }
}

TEST(MeshLoad, PlyCornerUvsAsMeshLabWritesThem) {
    // MeshLab writes uvs per face corner ("property list uchar float texcoord"): read, the
    // corners of one vertex with other uvs split into vertices of their own (a seam). They were
    // dropped, and a uv-laid material then warned that the mesh had none.
    test::TempDir dir("ply_wedges");
    std::ofstream(dir.file("wedge.ply"))
        << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
           "property list uchar float texcoord\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
           "3 0 1 2 6 0 0 1 0 1 1\n3 0 2 3 6 0.5 0 1 1 0 1\n";
    const TriangleMesh m = load_mesh(dir.file("wedge.ply"), {});
    ASSERT_EQ(m.triangle_count(), 2u);
    EXPECT_EQ(m.vertex_count(), 5u) << "vertex 0 has two uvs: two vertices";
    ASSERT_EQ(m.uvs.size(), 2 * m.vertex_count());
    // Each corner's uv is the one the file gives it, at the corner's own position.
    const float want[6][4] = {{0, 0, 0, 0},    {1, 0, 1, 0}, {1, 1, 1, 1},
                              {0, 0, 0.5f, 0}, {1, 1, 1, 1}, {0, 1, 0, 1}};
    for (std::size_t c = 0; c < 6; ++c) {
        const uint32_t v = m.indices[c];
        EXPECT_EQ(m.position(v).x, want[c][0]) << c;
        EXPECT_EQ(m.position(v).y, want[c][1]) << c;
        EXPECT_EQ(m.uvs[2 * v], want[c][2]) << c;
        EXPECT_EQ(m.uvs[2 * v + 1], want[c][3]) << c;
    }
}

TEST(MeshLoad, PlyFirstLineAsToolsWriteIt) {
    // "ply" followed by blanks, after a UTF-8 byte order mark: still a PLY file.
    const test::TempDir dir("ply_first_line");
    const std::string body =
        "format ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    std::ofstream(dir.file("a.ply")) << "ply \t\r\n" << body;
    std::ofstream(dir.file("b.ply")) << "\xEF\xBB\xBFply\n" << body;
    for (const char* name : {"a.ply", "b.ply"})
        EXPECT_EQ(load_mesh(dir.file(name), FileLoc{"s.toml", 1, 1}).triangle_count(), 1u) << name;
    // Not a PLY: the message shows what the first line is.
    std::ofstream(dir.file("c.ply")) << "solid cube\n" << body;
    try {
        load_mesh(dir.file("c.ply"), FileLoc{"s.toml", 1, 1});
        FAIL() << "an STL-like file was read as PLY";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("its first line must be 'ply', it is 'solid cube'"),
                  std::string::npos)
            << e.what();
    }
}

TEST(MeshLoad, GzippedPlyIsReadAsThePlyItHolds) {
    // pbrt-v4's scenes (ganesha, sssdragon, lte-orb) ship their meshes as .ply.gz: the same
    // mesh as the plain file (they were "has extension '.gz'; expected .obj or .ply").
    const test::TempDir dir("ply_gz");
    std::ifstream in(test::asset_dir() + "/meshes/plane.ply", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    gzFile gz = gzopen(dir.file("plane.ply.gz").c_str(), "wb");
    gzwrite(gz, bytes.data(), static_cast<unsigned>(bytes.size()));
    gzclose(gz);
    const TriangleMesh plain = load_mesh(test::asset_dir() + "/meshes/plane.ply", {});
    const TriangleMesh packed = load_mesh(dir.file("plane.ply.gz"), {});
    EXPECT_EQ(packed.positions, plain.positions);
    EXPECT_EQ(packed.normals, plain.normals);
    EXPECT_EQ(packed.uvs, plain.uvs);
    EXPECT_EQ(packed.indices, plain.indices);
    // A .gz that holds something else is not taken for a mesh of another kind.
    std::ofstream(dir.file("x.obj.gz")) << "v 0 0 0\n";
    EXPECT_THROW(load_mesh(dir.file("x.obj.gz"), {}), SpangleError);
    // A damaged gzip stream says so.
    std::ofstream(dir.file("bad.ply.gz")) << std::string("\x1f\x8b\x08\x00garbage", 12);
    try {
        load_mesh(dir.file("bad.ply.gz"), {});
        FAIL() << "a damaged .ply.gz was read";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("not a valid gzip file"), std::string::npos)
            << e.what();
    }
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
        EXPECT_NE(msg.find("nan_vertex.obj', line 2: vertex has the non-finite value 'nan'"),
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

/** Writes `text` to a temporary .obj and loads it. */
TriangleMesh load_obj_text(const std::string& text) {
    const test::TempDir dir("obj_reader");
    const std::string path = dir.file("m.obj");
    std::ofstream(path) << text;
    return load_mesh(path, FileLoc{"scene.toml", 3, 8});
}

/** The message loading `text` as an OBJ throws (empty when it loads). */
std::string obj_error(const std::string& text) {
    try {
        load_obj_text(text);
        return "";
    } catch (const SpangleError& e) {
        return e.what();
    }
}

TEST(MeshLoad, FacesOfFewerThanThreeCornersAreSkippedAndSaid) {
    // Points and edges written as faces (scanners and some exporters write them) failed the
    // whole mesh; they are not surfaces: skipped, counted in a note the loader says.
    const TriangleMesh obj = load_obj_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\nf 1 2 3\nf 3\n");
    EXPECT_EQ(obj.triangle_count(), 1u);
    ASSERT_EQ(obj.notes.size(), 1u);
    EXPECT_EQ(obj.notes[0],
              "2 faces of fewer than 3 corners (points or edges, not surfaces) skipped");
    const test::TempDir dir("ply_short_faces");
    const std::string head =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n0 1 0\n";
    std::ofstream(dir.file("a.ply")) << head << "2 0 1\n3 0 1 2\n0\n";
    const TriangleMesh ply = load_mesh(dir.file("a.ply"), FileLoc{"s.toml", 1, 1});
    EXPECT_EQ(ply.triangle_count(), 1u);
    ASSERT_EQ(ply.notes.size(), 1u);
    EXPECT_EQ(ply.notes[0],
              "2 faces of fewer than 3 corners (points or edges, not surfaces) skipped");
    // A corner beyond the vertices is named by the file's face (it was the triangle's number:
    // face 0, a quad, was "triangle 1").
    std::ofstream(dir.file("b.ply")) << head << "3 0 1 2\n4 0 1 2 7\n3 0 1 2\n";
    try {
        load_mesh(dir.file("b.ply"), FileLoc{"s.toml", 1, 1});
        FAIL() << "an index beyond the vertices was read";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("face 1 refers to vertex 7, but there are 3 vertices"),
                  std::string::npos)
            << e.what();
    }
    // Only such faces: no surface at all, said with the reason.
    EXPECT_NE(obj_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n")
                  .find("has no triangles (1 face of fewer than 3 corners"),
              std::string::npos);
}

TEST(ObjReader, CornersSharingIndicesShareAVertexAndPolygonsAreFanned) {
    // A quad and a pentagon over shared corners; uvs on every corner, no normals.
    const TriangleMesh m = load_obj_text(
        "# comment\no quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5\nusemtl paint\ns off\n"
        "f 1/1 2/2 3/3 4/4\nf 1/1 4/4 5/5 -1/-1 -2/-2\n");
    EXPECT_EQ(m.vertex_count(), 5u) << "(v, vt) pairs repeat: shared";
    EXPECT_EQ(m.triangle_count(), 2u + 3u);
    EXPECT_TRUE(m.normals.empty());
    ASSERT_EQ(m.uvs.size(), 10u);
    EXPECT_FLOAT_EQ(m.uvs[9], 0.0f) << "vt with one number has v = 0";
    // Fan around the first corner: (0,1,2), (0,2,3); then (0,3,4), (0,4,4), (0,4,3).
    EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 4, 0, 4, 3}));
    // One material, as nearly every exported OBJ names: nothing to say (the scene's stands in).
    EXPECT_TRUE(m.notes.empty());
    // Several, and lines and points: not read, each said once (they were silent).
    const TriangleMesh lp = load_obj_text(
        "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\np 3\nl 2 3\nusemtl red\nf 1 2 3\n"
        "usemtl blue\nf 1 3 2\nusemtl red\nf 2 1 3\n");
    EXPECT_EQ(lp.triangle_count(), 3u);
    ASSERT_EQ(lp.notes.size(), 2u);
    EXPECT_NE(lp.notes[0].find("lines and points ('l' at line 5) are not surfaces"),
              std::string::npos)
        << lp.notes[0];
    EXPECT_NE(lp.notes[1].find("its 2 materials (usemtl; the second at line 10) are not read"),
              std::string::npos)
        << lp.notes[1];
}

TEST(ObjReader, NormalsOnlyWhenEveryCornerHasOneAndForwardIndices) {
    // Faces before the vertices they name (allowed), a continued line, CRLF endings.
    const TriangleMesh m = load_obj_text(
        "f 1//1 2//1 \\\r\n 3//1\r\nv 0 0 0\r\nv 1 0 0\r\nv +0 1 0 1\r\nvn 0 0 1\r\n");
    EXPECT_EQ(m.triangle_count(), 1u);
    ASSERT_EQ(m.normals.size(), 9u);
    EXPECT_FLOAT_EQ(m.normals[8], 1.0f);
    EXPECT_FLOAT_EQ(m.positions[7], 1.0f);
    const TriangleMesh mixed =
        load_obj_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\nf 1 3 2\n");
    EXPECT_TRUE(mixed.normals.empty()) << "a corner without a normal: face normals for all";
}

TEST(ObjReader, ConcaveFacesAreClippedConvexOnesFanned) {
    // A U (8 corners, counter-clockwise seen from +z, then the same U written clockwise and
    // turned into the yz-plane): its notch x in (1, 3), y in (1, 4) must stay empty and its six
    // triangles must cover its area, 10, once.
    const std::string u =
        "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 3 4 0\nv 3 1 0\nv 1 1 0\nv 1 4 0\nv 0 4 0\n";
    const std::string u_yz =
        "v 0 0 0\nv 0 0 4\nv 0 4 4\nv 0 4 3\nv 0 1 3\nv 0 1 1\nv 0 4 1\nv 0 4 0\n";
    for (const std::string& text : {u + "f 1 2 3 4 5 6 7 8\n", u_yz + "f 8 7 6 5 4 3 2 1\n"}) {
        const TriangleMesh m = load_obj_text(text);
        ASSERT_EQ(m.triangle_count(), 6u) << text;
        double area = 0.0;
        for (uint32_t t = 0; t < m.triangle_count(); ++t) {
            Vec3 p[3];
            for (int k = 0; k < 3; ++k) {
                const uint32_t v = m.indices[3 * t + static_cast<uint32_t>(k)];
                p[k] = {m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]};
            }
            area += 0.5 * static_cast<double>(length(cross(p[1] - p[0], p[2] - p[0])));
            // The notch's middle, (2, 2.5) in the face's plane, is in no triangle.
            const bool yz = text == u_yz + "f 8 7 6 5 4 3 2 1\n";
            const auto c2 = [&](Vec3 q) { return yz ? std::pair{q.z, q.y} : std::pair{q.x, q.y}; };
            const auto side = [&](Vec3 a, Vec3 b) {
                const auto [ax, ay] = c2(a);
                const auto [bx, by] = c2(b);
                return (bx - ax) * (2.5f - ay) - (by - ay) * (2.0f - ax);
            };
            const float s0 = side(p[0], p[1]), s1 = side(p[1], p[2]), s2 = side(p[2], p[0]);
            EXPECT_FALSE((s0 > 0 && s1 > 0 && s2 > 0) || (s0 < 0 && s1 < 0 && s2 < 0))
                << "triangle " << t << " covers the notch";
        }
        EXPECT_NEAR(area, 10.0, 1e-5);
    }
    // A convex pentagon keeps its fan (the meshes the reader made before are unchanged).
    const TriangleMesh convex =
        load_obj_text("v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 3 0\nv -1 1 0\nf 1 2 3 4 5\n");
    EXPECT_EQ(convex.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 3, 4}));
}

/** The triangles' areas in the xy-plane, signed (counter-clockwise positive), summed, and the
 *  sum of their sizes: both equal the outline's area when they tile it once. */
std::pair<double, double> xy_areas(const TriangleMesh& m) {
    double signed_sum = 0.0, size_sum = 0.0;
    for (uint32_t t = 0; t < m.triangle_count(); ++t) {
        const Vec3 a = m.position(m.indices[3 * t]), b = m.position(m.indices[3 * t + 1]),
                   c = m.position(m.indices[3 * t + 2]);
        const double s =
            0.5 * ((static_cast<double>(b.x) - a.x) * (static_cast<double>(c.y) - a.y) -
                   (static_cast<double>(b.y) - a.y) * (static_cast<double>(c.x) - a.x));
        signed_sum += s;
        size_sum += std::fabs(s);
    }
    return {signed_sum, size_sum};
}

TEST(MeshLoad, ConcavePolygonsOfAnySizeAreClippedInBothFormats) {
    // Stars of n points (radius 0.9 and 0.5 in turn), as text, logos and boolean caps give
    // them: beyond 256 corners they were fanned from the first (a 300-corner star covered 20
    // times its area; 200,000 corners, 16,000 times). Every size, OBJ and PLY, tiles the
    // outline once; the largest in well under a second (the reflex corners in a grid).
    const test::TempDir dir("mesh_stars");
    for (const int n : {8, 300, 4000, 100000}) {
        std::vector<std::pair<double, double>> pts;
        double area = 0.0;
        for (int i = 0; i < n; ++i) {
            const double r = i % 2 == 0 ? 0.9 : 0.5, a = 2.0 * M_PI * i / n;
            pts.emplace_back(r * std::cos(a), r * std::sin(a));
        }
        for (int i = 0; i < n; ++i) {
            const auto [x0, y0] = pts[static_cast<std::size_t>(i)];
            const auto [x1, y1] = pts[static_cast<std::size_t>((i + 1) % n)];
            area += 0.5 * (x0 * y1 - x1 * y0);
        }
        std::string obj, ply = fmt::format(
                             "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\n"
                             "property float y\nproperty float z\nelement face 1\n"
                             "property list uint int vertex_indices\nend_header\n",
                             n);
        for (const auto& [x, y] : pts) {
            obj += fmt::format("v {:.9g} {:.9g} 0\n", x, y);
            ply += fmt::format("{:.9g} {:.9g} 0\n", x, y);
        }
        obj += "f";
        ply += fmt::format("{}", n);
        for (int i = 0; i < n; ++i) {
            obj += fmt::format(" {}", i + 1);
            ply += fmt::format(" {}", i);
        }
        obj += "\n";
        ply += "\n";
        std::ofstream(dir.file("star.obj")) << obj;
        std::ofstream(dir.file("star.ply")) << ply;
        for (const char* file : {"star.obj", "star.ply"}) {
            const TriangleMesh m = load_mesh(dir.file(file), {});
            ASSERT_EQ(m.triangle_count(), static_cast<std::size_t>(n - 2)) << file << " " << n;
            const auto [signed_sum, size_sum] = xy_areas(m);
            EXPECT_NEAR(signed_sum, area, 1e-6 * area) << file << " " << n;
            EXPECT_NEAR(size_sum, area, 1e-6 * area) << file << " " << n << ": triangles overlap";
        }
    }
}

TEST(ObjReader, ReadsWhatRealExportersWrite) {
    // A UTF-8 byte order mark, corners ending in a slash ("v/vt/", "v//"), comments after data.
    const TriangleMesh m = load_obj_text(
        "\xEF\xBB\xBFv 0 0 0\nv 1 0 0 # x axis\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
        "f 1/1/ 2/2/ 3/3/ # a triangle\nf 1// 3// 2//\n");
    EXPECT_EQ(m.triangle_count(), 2u);
    ASSERT_EQ(m.positions.size() % 3, 0u);
    EXPECT_FLOAT_EQ(m.positions[0], 0.0f) << "the first vertex is read despite the mark";
    EXPECT_EQ(m.vertex_count(), 6u) << "(v, vt) pairs: three with uvs, three without";
    EXPECT_TRUE(m.normals.empty());
}

TEST(ObjReader, ErrorsNameTheLine) {
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    const auto has = [](const std::string& msg, const std::string& part) {
        return msg.rfind("scene.toml:3:8: error: mesh '", 0) == 0 &&
               msg.find(part) != std::string::npos;
    };
    EXPECT_PRED2(has, obj_error(tri + "f 1 2 0\n"),
                 "line 4: face refers to vertex 0; OBJ indices start at 1");
    EXPECT_PRED2(has, obj_error(tri + "f 1 2 -4\n"),
                 "line 4: face refers to vertex -4, but only 3 have been read so far");
    EXPECT_PRED2(has, obj_error(tri + "f 1 2 3\nf 1 2 9\n"),
                 "line 5: face refers to vertex 9, but the file has 3");
    EXPECT_PRED2(has, obj_error(tri + "f 1/1 2 3\n"),
                 "line 4: face refers to uv 1, but the file has 0");
    EXPECT_PRED2(has, obj_error(tri + "f 1/x 2 3\n"),
                 "line 4: face corner has 'x' where a uv index belongs");
    EXPECT_PRED2(has, obj_error(tri + "f 1/1/1/ 2 3\n"),
                 "line 4: face corner '1/1/1/' is not v, v/vt, v//vn or v/vt/vn");
    EXPECT_PRED2(has, obj_error("v 0 0\n"), "line 1: vertex is missing a number");
    EXPECT_PRED2(has, obj_error("v 0 0 1e39\n"),
                 "line 1: vertex has '1e39', out of the range of a float");
    EXPECT_PRED2(has, obj_error("v 0 inf 0\n"), "line 1: vertex has the non-finite value 'inf'");
    EXPECT_PRED2(has, obj_error("v 0 0x1 0\n"), "line 1: vertex has '0x1' where a number belongs");
    EXPECT_PRED2(has, obj_error(tri + "vn 0 0 nan\n"),
                 "line 4: normal has the non-finite value 'nan'");
    EXPECT_PRED2(has, obj_error(tri), "has no triangles");
    EXPECT_PRED2(has, obj_error(tri + "f 1 2 99999999999999999999\n"),
                 "where a vertex index belongs");
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
    // A non-finite normal is named by its vertex.
    m.indices = {0, 1, 2};
    m.normals = {0, 0, 1, 0, 0, 1, 0, NAN, 1};
    try {
        validate_mesh(m, {});
        FAIL();
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("vertex 2 has a non-finite normal (0, nan, 1)"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace spangle::test_mesh_load
