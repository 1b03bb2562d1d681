// The glTF 2.0 reader: glTF files written here (tests/unit/gltf_writer.h) with every feature the
// reader reads, checked in the SceneDescription it makes and in what the builder makes of it;
// camera conventions by projecting known points; errors at the JSON's line:col; and a glTF
// scene rendered against the TOML scene written to be equivalent, by a z-test per pixel block.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "desc_support.h"
#include "gltf_writer.h"
#include "render/camera.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "test_support.h"

namespace spangle::test_gltf_reader {
namespace {

using test::GltfWriter;
using test::has_note;
using test::param;

/** A unit quad in the xy plane facing +z: accessors for POSITION, NORMAL, TEXCOORD_0, indices. */
struct QuadAccessors {
    int position, normal, uv, indices;
};

/** The quad's accessors in w. */
QuadAccessors quad(GltfWriter& w) {
    QuadAccessors q{};
    q.position = w.floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, "VEC3", 3);
    q.normal = w.floats({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 3);
    q.uv = w.floats({0, 1, 1, 1, 1, 0, 0, 0}, "VEC2", 2);
    q.indices = w.u16({0, 1, 2, 0, 2, 3});
    return q;
}

/** The quad as a primitive (with `extra` attributes; material -1: none). */
std::string quad_primitive(const QuadAccessors& q, int material, const std::string& extra = "") {
    return fmt::format(
        R"({{"attributes":{{"POSITION":{},"NORMAL":{},"TEXCOORD_0":{}{}}},"indices":{}{}}})",
        q.position, q.normal, q.uv, extra, q.indices,
        material >= 0 ? fmt::format(R"(,"material":{})", material) : std::string());
}

/** How many notes contain `text`. */
int count_notes(const SceneDescription& d, const std::string& text) {
    int n = 0;
    for (const std::string& s : d.notes) n += s.find(text) != std::string::npos ? 1 : 0;
    return n;
}

/** Expects every entry of a and b within tol. */
void expect_affine_near(const Affine& a, const Affine& b, float tol) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.m[r][c], b.m[r][c], tol) << r << "," << c;
    EXPECT_NEAR(a.t.x, b.t.x, tol);
    EXPECT_NEAR(a.t.y, b.t.y, tol);
    EXPECT_NEAR(a.t.z, b.t.z, tol);
}

// Tolerances: the reader composes float matrices from doubles in the JSON; 1e-5 is a few ulps
// at the sizes used here.
constexpr float kTol = 1e-5f;

TEST(GltfReader, NodeHierarchyComposesIntoWorldMatrices) {
    test::TempDir dir("gltf_nodes");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    // Parent: translate (1, 2, 3) and a quarter turn about +y (quaternion (0, s, 0, s)); child:
    // scale 2 and translate (0, 0, 1) in the parent's frame.
    const float s = std::sqrt(0.5f);
    const std::string body = fmt::format(
        R"("scene":0,"scenes":[{{"nodes":[0]}}],)"
        R"("nodes":[{{"name":"parent","translation":[1,2,3],"rotation":[0,{},0,{}],"children":[1]}},)"
        R"({{"name":"child","mesh":0,"scale":[2,2,2],"translation":[0,0,1]}}],)"
        R"("meshes":[{{"primitives":[{}]}}])",
        s, s, quad_primitive(q, -1));
    w.write_gltf(dir.file("nodes.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("nodes.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    ASSERT_TRUE(d.objects[0].placement.matrix);
    const Affine expected = Affine::translate({1, 2, 3})
                                .compose(Affine::rotate(90.0f, {0, 1, 0}))
                                .compose(Affine::translate({0, 0, 1}))
                                .compose(Affine::scale({2, 2, 2}));
    expect_affine_near(*d.objects[0].placement.matrix, expected, kTol);
    EXPECT_EQ(d.objects[0].name, "child");
    // The child's origin lands at the parent's translation plus its offset turned by 90 degrees
    // about +y: (0, 0, 1) -> (1, 0, 0).
    const Vec3 o = d.objects[0].placement.matrix->apply_point({0, 0, 0});
    EXPECT_NEAR(o.x, 2.0f, kTol);
    EXPECT_NEAR(o.y, 2.0f, kTol);
    EXPECT_NEAR(o.z, 3.0f, kTol);
    // The builder places the object by that matrix.
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo info = build_scene(d, color, registry);
    ASSERT_EQ(info.object_to_world.size(), 1u);
    expect_affine_near(info.object_to_world[0], expected, kTol);
}

TEST(GltfReader, NodesSharingAMeshShareOneTriangleMeshAndMatrixNodesRead) {
    test::TempDir dir("gltf_share");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    const std::string body = fmt::format(
        R"("nodes":[{{"mesh":0}},{{"mesh":0,"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 5,6,7,1]}}],)"
        R"("meshes":[{{"name":"quad","primitives":[{},{}]}}])",
        quad_primitive(q, -1), quad_primitive(q, -1));
    w.write_gltf(dir.file("share.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("share.gltf"), {});
    ASSERT_EQ(d.objects.size(), 4u);  // two nodes, two primitives each
    const auto mesh = [&](std::size_t i) {
        return std::get<InlineMeshShape>(d.objects[i].shape).mesh;
    };
    EXPECT_EQ(mesh(0), mesh(2));  // node 0 and node 1, primitive 0: one pointer, one BVH
    EXPECT_EQ(mesh(1), mesh(3));
    EXPECT_NE(mesh(0), mesh(1));
    EXPECT_EQ(d.objects[0].name, "quad#0");
    EXPECT_NEAR(d.objects[2].placement.matrix->t.x, 5.0f, kTol);
    EXPECT_NEAR(d.objects[2].placement.matrix->t.z, 7.0f, kTol);
}

// glTF: a node whose world matrix has a negative determinant draws its triangles' clockwise side
// as the front, so that a mirrored model keeps its outside out. Spangle fronts the side a
// triangle's corners run counter-clockwise around in world space: the reader reverses a mirrored
// mesh's winding, so the quad (facing +z) still faces +z when mirrored in x, y or all three, and
// mirrored GPU instances of it too. Unmirrored nodes keep the mesh as written (one pointer).
TEST(GltfReader, MirroredNodesKeepTheirFrontFaces) {
    test::TempDir dir("gltf_mirror");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    const int flip = w.floats({-1, 1, 1, 1, -1, 1}, "VEC3", 3);  // two instances' SCALE
    const std::string body = fmt::format(
        R"("extensionsUsed":["EXT_mesh_gpu_instancing"],)"
        R"("nodes":[{{"mesh":0}},{{"mesh":0,"scale":[-1,1,1]}},{{"mesh":0,"scale":[1,-2,1]}},)"
        R"({{"mesh":0,"scale":[-1,-1,-1]}},{{"mesh":0,"scale":[1,1,-1],"rotation":[0,1,0,0]}},)"
        R"({{"mesh":0,"extensions":{{"EXT_mesh_gpu_instancing":{{"attributes":{{"SCALE":{}}}}}}}}}],)"
        R"("meshes":[{{"primitives":[{}]}}])",
        flip, quad_primitive(q, -1));
    w.write_gltf(dir.file("mirror.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("mirror.gltf"), {});
    ASSERT_EQ(d.objects.size(), 7u);
    // The front of each triangle in world space, against where the quad's normal (+z) went.
    for (std::size_t i = 0; i < d.objects.size(); ++i) {
        const Affine& m = *d.objects[i].placement.matrix;
        const TriangleMesh& mesh = *std::get<InlineMeshShape>(d.objects[i].shape).mesh;
        // The quad's normal +z carried as normals are (M^-T n, up to a positive factor): the
        // cross product of its carried tangents, turned where M mirrors.
        const Vec3 normal = cross(m.apply_vector({1, 0, 0}), m.apply_vector({0, 1, 0})) *
                            (m.determinant() < 0.0f ? -1.0f : 1.0f);
        ASSERT_EQ(mesh.triangle_count(), 2u);
        for (uint32_t t = 0; t < 2; ++t) {
            const Vec3 a = m.apply_point(mesh.position(mesh.indices[3 * t]));
            const Vec3 b = m.apply_point(mesh.position(mesh.indices[3 * t + 1]));
            const Vec3 c = m.apply_point(mesh.position(mesh.indices[3 * t + 2]));
            EXPECT_GT(dot(cross(b - a, c - a), normal), 0.0f) << "object " << i << " tri " << t;
        }
    }
    const auto mesh = [&](std::size_t i) {
        return std::get<InlineMeshShape>(d.objects[i].shape).mesh;
    };
    EXPECT_NE(mesh(0), mesh(1));
    EXPECT_EQ(mesh(1), mesh(2));  // one reversed copy for every mirrored node
    EXPECT_EQ(mesh(1), mesh(3));
    EXPECT_EQ(mesh(5), mesh(6));
    EXPECT_EQ(mesh(0)->indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
    EXPECT_EQ(mesh(1)->indices, (std::vector<uint32_t>{0, 2, 1, 0, 3, 2}));
}

// Members glTF makes optional and tinygltf 2.7 requires: a skin's inverseBindMatrices
// (identity), an animation target's node (KHR_animation_pointer channels have none: noted and
// dropped), and a file without buffer views whose accessor has no view (zeros). A skin without
// joints is an error at the skin.
// A node flattened onto a plane (scale 0 along one axis) is made thin for Embree, with a sign of
// no meaning: its mesh is not reversed, however it is turned.
TEST(GltfReader, AFlattenedNodeIsNotTakenForAMirroredOne) {
    test::TempDir dir("gltf_flat_turned");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    const float s = std::sqrt(0.5f);
    const std::string body =
        fmt::format(R"("nodes":[{{"mesh":0,"scale":[1,1,0],"rotation":[{},0,0,{}]}},)"
                    R"({{"mesh":0,"scale":[1,0,1],"rotation":[1,0,0,0]}}],)"
                    R"("meshes":[{{"primitives":[{}]}}])",
                    s, s, quad_primitive(q, -1));
    w.write_gltf(dir.file("flat.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("flat.gltf"), {});
    ASSERT_EQ(d.objects.size(), 2u);
    for (const ObjectDesc& o : d.objects)
        EXPECT_EQ(std::get<InlineMeshShape>(o.shape).mesh->indices,
                  (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}))
            << o.what;
}

TEST(GltfReader, MembersTinygltfRequiresAreOptionalAsGltfSays) {
    test::TempDir dir("gltf_optional");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    const int times = w.floats({0, 1}, "SCALAR", 1);
    const int colors = w.floats({0, 0, 0, 1, 1, 1}, "VEC3", 3);
    const std::string body = fmt::format(
        R"("nodes":[{{"mesh":0}},{{"name":"joint"}}],"skins":[{{"joints":[1]}}],)"
        R"("materials":[{{}}],"meshes":[{{"primitives":[{}]}}],)"
        R"("animations":[{{"samplers":[{{"input":{},"output":{}}}],"channels":[{{"sampler":0,)"
        R"("target":{{"path":"pointer","extensions":{{"KHR_animation_pointer":)"
        R"({{"pointer":"/materials/0/emissiveFactor"}}}}}}}}]}}])",
        quad_primitive(q, 0), times, colors);
    w.write_gltf(dir.file("optional.gltf"), body);
    SceneDescription d;
    ASSERT_NO_THROW(d = read_gltf_scene(dir.file("optional.gltf"), {}));
    EXPECT_EQ(d.objects.size(), 1u);
    EXPECT_EQ(count_notes(d, "animations of 'pointer' are dropped"), 1)
        << fmt::format("{}", fmt::join(d.notes, "\n"));

    // No views and no buffers: three zero positions and indices, sparse-free.
    std::ofstream(dir.file("viewless.gltf"))
        << R"({"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
           R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
           R"("accessors":[{"componentType":5126,"count":3,"type":"VEC3",)"
           R"("min":[0,0,0],"max":[0,0,0]}]})";
    EXPECT_NO_THROW(read_gltf_scene(dir.file("viewless.gltf"), {}));

    std::ofstream(dir.file("jointless.gltf")) << R"({"asset":{"version":"2.0"},"skins":[{}]})";
    try {
        read_gltf_scene(dir.file("jointless.gltf"), {});
        ADD_FAILURE() << "a skin without joints was read";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("skin 0 has no 'joints'"), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("jointless.gltf:1:"), std::string::npos) << e.what();
    }
}

TEST(GltfReader, PrimitivesKeepPositionsNormalsAndUvsWithVFlipped) {
    test::TempDir dir("gltf_prims");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    const int tangent = w.floats({1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1}, "VEC4", 4);
    const int uv1 = w.floats({0, 0, 0, 0, 0, 0, 0, 0}, "VEC2", 2);
    const int strip_idx = w.u32({0, 1, 3, 2});
    const std::string extra = fmt::format(R"(,"TANGENT":{},"TEXCOORD_1":{})", tangent, uv1);
    const std::string body =
        fmt::format(R"("nodes":[{{"mesh":0}},{{"mesh":1}}],"meshes":[{{"primitives":[{}]}},)"
                    R"({{"primitives":[{{"attributes":{{"POSITION":{}}},"indices":{},"mode":5}},)"
                    R"({{"attributes":{{"POSITION":{}}},"mode":1}}]}}])",
                    quad_primitive(q, -1, extra), q.position, strip_idx, q.position);
    w.write_gltf(dir.file("prims.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("prims.gltf"), {});
    ASSERT_EQ(d.objects.size(), 2u);  // the line primitive is not drawn
    const TriangleMesh& m = *std::get<InlineMeshShape>(d.objects[0].shape).mesh;
    EXPECT_EQ(m.positions, (std::vector<float>{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}));
    EXPECT_EQ(m.normals, (std::vector<float>{0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}));
    // glTF's t runs down the image: (0, 1) at the bottom-left corner is Spangle's v = 0.
    EXPECT_EQ(m.uvs, (std::vector<float>{0, 0, 1, 0, 1, 1, 0, 1}));
    EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
    // A strip 0 1 3 2 is the triangles (0 1 3) and (3 1 2): the second flips its first two.
    const TriangleMesh& strip = *std::get<InlineMeshShape>(d.objects[1].shape).mesh;
    EXPECT_EQ(strip.indices, (std::vector<uint32_t>{0, 1, 3, 3, 1, 2}));
    EXPECT_TRUE(strip.normals.empty());
    EXPECT_EQ(count_notes(d, "TANGENT attributes are dropped"), 1);
    EXPECT_EQ(count_notes(d, "TEXCOORD_1 is dropped"), 1);
    EXPECT_EQ(count_notes(d, "points or lines (mode 1)"), 1);
    // Each note is "file:line:col: ..." at the attribute that was dropped.
    EXPECT_TRUE(has_note(d, dir.file("prims.gltf") + ":1:"));
}

TEST(GltfReader, GpuInstancesAreObjectsSharingTheMeshPlacedAfterTheirNode) {
    // EXT_mesh_gpu_instancing: three instances of a quad under a node moved by (10, 0, 0); the
    // rotations as normalised shorts (as gltfpack writes them).
    test::TempDir dir("gltf_instancing");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    const int t = w.floats({0, 0, 0, 1, 0, 0, 0, 2, 0}, "VEC3", 3);
    const int s = w.floats({1, 1, 1, 2, 2, 2, 1, 1, 1}, "VEC3", 3);
    // Identity, identity, and 90 degrees about z: (0, 0, sin 45, cos 45) x 32767.
    const std::vector<int16_t> rot = {0, 0, 0, 32767, 0, 0, 0, 32767, 0, 0, 23170, 23170};
    const int rv = w.view(rot.data(), rot.size() * 2);
    w.accessors.push_back(fmt::format(
        R"({{"bufferView":{},"componentType":5122,"normalized":true,"count":3,"type":"VEC4"}})",
        rv));
    const auto r = static_cast<int>(w.accessors.size()) - 1;
    const std::string body = fmt::format(
        R"("extensionsUsed":["EXT_mesh_gpu_instancing"],"extensionsRequired":)"
        R"(["EXT_mesh_gpu_instancing"],"nodes":[{{"name":"quad","mesh":0,"translation":[10,0,0],)"
        R"("extensions":{{"EXT_mesh_gpu_instancing":{{"attributes":{{"TRANSLATION":{},)"
        R"("ROTATION":{},"SCALE":{},"_ID":{}}}}}}}}}],"meshes":[{{"primitives":[{}]}}])",
        t, r, s, t, quad_primitive(q, -1));
    w.write_gltf(dir.file("inst.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("inst.gltf"), {});
    ASSERT_EQ(d.objects.size(), 3u);
    const auto mesh = [&](std::size_t i) {
        return std::get<InlineMeshShape>(d.objects[i].shape).mesh.get();
    };
    EXPECT_EQ(mesh(0), mesh(1));
    EXPECT_EQ(mesh(0), mesh(2));
    EXPECT_EQ(d.objects[0].name, "quad@0");
    EXPECT_EQ(d.objects[2].name, "quad@2");
    // Where the quad's corner (1, 0, 0) goes: node after instance.
    const auto corner = [&](std::size_t i) {
        return d.objects[i].placement.matrix.value().apply_point({1, 0, 0});
    };
    EXPECT_NEAR(corner(0).x, 11.0f, 1e-4f);
    EXPECT_NEAR(corner(1).x, 10.0f + 1.0f + 2.0f, 1e-4f);  // scaled by 2, then moved by 1
    EXPECT_NEAR(corner(2).x, 10.0f, 1e-3f);                // turned onto +y, then moved by 2 in y
    EXPECT_NEAR(corner(2).y, 3.0f, 1e-3f);
    EXPECT_EQ(count_notes(d, "instance attribute _ID is dropped"), 1);

    // Instances scaled onto a point or a line are not drawn (noted), one flattened onto a
    // plane is drawn flat: as nodes are. One merely small (gltfpack's instances of a quantised
    // 1 cm model carry 6e-7 per axis) is drawn: it was hidden as scaled to nothing.
    GltfWriter w3;
    const QuadAccessors q3 = quad(w3);
    const int s3 =
        w3.floats({1, 1, 1, 0, 0, 0, 1, 0, 0, 1, 1, 0, 6.1e-7f, 6.1e-7f, 6.1e-7f}, "VEC3", 3);
    w3.write_gltf(dir.file("flat.gltf"),
                  fmt::format(R"("nodes":[{{"mesh":0,"extensions":{{"EXT_mesh_gpu_instancing":)"
                              R"({{"attributes":{{"SCALE":{}}}}}}}}}],)"
                              R"("meshes":[{{"primitives":[{}]}}])",
                              s3, quad_primitive(q3, -1)));
    const SceneDescription flat = read_gltf_scene(dir.file("flat.gltf"), {});
    ASSERT_EQ(flat.objects.size(), 3u);
    // Neither the node nor its mesh has a name: the node's number stands in (it was "").
    EXPECT_EQ(flat.objects[0].name, "node 0@0");
    EXPECT_EQ(flat.objects[1].name, "node 0@3");
    EXPECT_EQ(flat.objects[2].name, "node 0@4");
    EXPECT_NEAR(flat.objects[2].placement.matrix.value().apply_point({1, 0, 0}).x, 6.1e-7f, 1e-12f);
    EXPECT_GT(std::fabs(flat.objects[1].placement.matrix.value().determinant()), 0.0f);
    EXPECT_EQ(count_notes(flat, "instance 1 of node 0 is scaled to nothing"), 1);

    // More instances than Spangle makes objects from one file (each is one): an error at the
    // attribute, before it is read (a 1 KB file asked for 2^24 of them by a view-less
    // accessor: minutes, and more memory than the machine had).
    GltfWriter w4;
    const QuadAccessors q4 = quad(w4);
    w4.accessors.push_back(R"({"componentType":5126,"count":5000000,"type":"VEC3"})");
    w4.write_gltf(dir.file("many.gltf"),
                  fmt::format(R"("nodes":[{{"mesh":0,"extensions":{{"EXT_mesh_gpu_instancing":)"
                              R"({{"attributes":{{"TRANSLATION":{}}}}}}}}}],)"
                              R"("meshes":[{{"primitives":[{}]}}])",
                              w4.accessors.size() - 1, quad_primitive(q4, -1)));
    try {
        read_gltf_scene(dir.file("many.gltf"), {});
        ADD_FAILURE() << "no error";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("node 0 asks for 5000000 instances"),
                  std::string::npos)
            << e.what();
    }

    // Attributes of different counts: an error at the second.
    GltfWriter w2;
    const QuadAccessors q2 = quad(w2);
    const int t2 = w2.floats({0, 0, 0, 1, 0, 0}, "VEC3", 3);
    const int s2 = w2.floats({1, 1, 1}, "VEC3", 3);
    w2.write_gltf(dir.file("bad.gltf"),
                  fmt::format(R"("nodes":[{{"mesh":0,"extensions":{{"EXT_mesh_gpu_instancing":)"
                              R"({{"attributes":{{"TRANSLATION":{},"SCALE":{}}}}}}}}}],)"
                              R"("meshes":[{{"primitives":[{}]}}])",
                              t2, s2, quad_primitive(q2, -1)));
    try {
        read_gltf_scene(dir.file("bad.gltf"), {});
        ADD_FAILURE() << "no error";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("instance attribute TRANSLATION has 2 elements, "
                                             "SCALE has 1"),
                  std::string::npos)
            << e.what();
    }
}

/** The film position (pixels, y down) where camera c of a w x h image sees world point p. */
std::pair<float, float> project(const CameraModel& cam, Vec3 p, const CameraDesc& c, uint32_t w,
                                uint32_t h) {
    // Search the film for the ray closest to p's direction (the camera model has no inverse):
    // Newton steps on the film position from the centre.
    float fx = 0.5f * static_cast<float>(w), fy = 0.5f * static_cast<float>(h);
    const Vec3 want = normalize(p - c.position);
    for (int it = 0; it < 50; ++it) {
        const Vec3 d0 = cam.generate(fx, fy, 0.5f, 0.5f).d;
        const Vec3 dx = cam.generate(fx + 1, fy, 0.5f, 0.5f).d - d0;
        const Vec3 dy = cam.generate(fx, fy + 1, 0.5f, 0.5f).d - d0;
        const Vec3 e = want - d0;
        fx += dot(e, dx) / dot(dx, dx);
        fy += dot(e, dy) / dot(dy, dy);
    }
    return {fx, fy};
}

TEST(GltfReader, CameraLooksDownItsMinusZWithYUpAndYfovVertical) {
    test::TempDir dir("gltf_camera");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    // A camera at (0, 0, 10) turned 90 degrees about +y looks down world -x; yfov 0.8 rad with
    // aspect 2 makes a 640 x 320 image.
    const float s = std::sqrt(0.5f);
    const std::string body = fmt::format(
        R"("nodes":[{{"mesh":0}},{{"name":"cam","camera":0,"translation":[0,0,10],"rotation":[0,{},0,{}]}}],)"
        R"("cameras":[{{"name":"main","type":"perspective","perspective":{{"yfov":0.8,"aspectRatio":2.0,"znear":0.1}}}}],)"
        R"("meshes":[{{"primitives":[{}]}}])",
        s, s, quad_primitive(q, -1));
    w.write_gltf(dir.file("camera.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("camera.gltf"), {});
    const CameraDesc& c = d.camera;
    EXPECT_NEAR(c.fov_deg, 0.8 * 180.0 / M_PI, 1e-9);
    EXPECT_EQ(d.render.width, 640u);
    EXPECT_EQ(d.render.height, 320u);
    EXPECT_NEAR(c.position.z, 10.0f, kTol);
    const CameraModel cam(c.position, c.look_at, c.up, static_cast<float>(c.fov_deg), 0.0f, 1.0f,
                          d.render.width, d.render.height);
    // Straight ahead (world -x) is the image centre; +y (the camera's up) is above it; world
    // -z, to the camera's right in a right-handed frame looking down -x with y up, is right of
    // it; a point tan(yfov / 2) up at distance 1 is on the top edge.
    const auto [cx, cy] = project(cam, c.position + Vec3{-5, 0, 0}, c, 640, 320);
    EXPECT_NEAR(cx, 320.0f, 0.01f);
    EXPECT_NEAR(cy, 160.0f, 0.01f);
    const auto [ux, uy] = project(cam, c.position + Vec3{-5, 1, 0}, c, 640, 320);
    EXPECT_NEAR(ux, 320.0f, 0.01f);
    EXPECT_LT(uy, 160.0f);
    const auto [rx, ry] = project(cam, c.position + Vec3{-5, 0, -1}, c, 640, 320);
    EXPECT_GT(rx, 320.0f);
    EXPECT_NEAR(ry, 160.0f, 0.01f);
    const auto [tx, ty] = project(cam, c.position + Vec3{-1, std::tan(0.4f), 0}, c, 640, 320);
    EXPECT_NEAR(tx, 320.0f, 0.01f);
    EXPECT_NEAR(ty, 0.0f, 0.05f);  // film positions to 1/20 pixel: Newton on float rays
}

TEST(GltfReader, AnAspectRatioThatIsNotUsableIsSaid) {
    // 0 was ignored, and 1/1000 made a 640 x 16384 image, both without a word.
    test::TempDir dir("gltf_aspect");
    const auto read = [&](const std::string& aspect, bool size_given = false) {
        GltfWriter w;
        const QuadAccessors q = quad(w);
        w.write_gltf(
            dir.file("a.gltf"),
            fmt::format(R"("nodes":[{{"mesh":0}},{{"camera":0,"translation":[0,0,5]}}],)"
                        R"("cameras":[{{"type":"perspective","perspective":{{"yfov":0.8,)"
                        R"("aspectRatio":{},"znear":0.1}}}}],"meshes":[{{"primitives":[{}]}}])",
                        aspect, quad_primitive(q, -1)));
        SceneReadOptions options;
        options.size_given = size_given;
        return read_gltf_scene(dir.file("a.gltf"), options);
    };
    const SceneDescription zero = read("0");
    EXPECT_EQ(zero.render.height, 360u) << "the default size";
    EXPECT_EQ(count_notes(zero, "aspectRatio 0 is not a positive number: ignored"), 1);
    const SceneDescription tall = read("0.001");
    EXPECT_EQ(tall.render.height, 16384u);
    EXPECT_EQ(count_notes(tall, "the camera's aspect ratio 0.001 makes the image 640 x 16384"), 1);
    const SceneDescription fine = read("1.5");
    EXPECT_EQ(fine.render.height, 427u);
    EXPECT_EQ(count_notes(fine, "aspect ratio") + count_notes(fine, "aspectRatio"), 0);
    // With --size the file's aspect sets nothing, so nothing is said of it.
    for (const char* aspect : {"0", "0.001"}) {
        const SceneDescription sized = read(aspect, true);
        EXPECT_EQ(count_notes(sized, "aspect ratio") + count_notes(sized, "aspectRatio"), 0)
            << aspect;
    }
    // Nor when a TOML scene imports it and gives the width and height; with the width alone
    // the height is still the import's, so the note stays.
    const auto imported = [&](const std::string& size) {
        read("0.001");
        std::ofstream(dir.file("s.toml")) << "[render]\n"
                                          << size << "\n[[import]]\nfile = \"a.gltf\"\n";
        return read_scene(dir.file("s.toml"));
    };
    const SceneDescription sized = imported("width = 320\nheight = 200");
    EXPECT_EQ(sized.render.height, 200u);
    EXPECT_EQ(count_notes(sized, "aspect ratio"), 0);
    EXPECT_EQ(count_notes(imported("width = 320"), "aspect ratio"), 1);
}

TEST(GltfReader, OrthographicCameraKeepsItsMagnification) {
    // xmag 3, ymag 1.5: a view 3 units tall and 6 wide (a 2:1 image), parallel rays down the
    // node's -z. Before, the camera was noted as unsupported and the default framing stood in.
    test::TempDir dir("gltf_ortho");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    // A quad and an orthographic camera of these magnifications at (1, 2, 10), as `name`.
    const auto write = [&](const char* name, const char* xmag, const char* ymag) {
        w.write_gltf(
            dir.file(name),
            fmt::format(
                R"("nodes":[{{"mesh":0}},{{"camera":0,"translation":[1,2,10]}}],)"
                R"("cameras":[{{"type":"orthographic","orthographic":{{"xmag":{},"ymag":{},"znear":0.1,"zfar":100}}}}],)"
                R"("meshes":[{{"primitives":[{}]}}])",
                xmag, ymag, quad_primitive(q, -1)));
        return dir.file(name);
    };
    const SceneDescription d = read_gltf_scene(write("ortho.gltf", "3", "1.5"), {});
    const CameraDesc& c = d.camera;
    for (const std::string& n : d.notes) EXPECT_EQ(n.find("camera"), std::string::npos) << n;
    EXPECT_EQ(c.ortho_height, 3.0);
    EXPECT_EQ(d.render.height * 2, d.render.width);
    EXPECT_NEAR(c.position.x, 1.0f, kTol);
    EXPECT_LT(c.look_at.z, c.position.z);
    FilmLayout layout;
    layout.ortho_height = static_cast<float>(c.ortho_height);
    const CameraModel cam(c.position, c.look_at, c.up, 40.0f, 0.0f, 1.0f, d.render.width,
                          d.render.height, layout);
    // The image's top-right corner ray leaves 3 units right and 1.5 up of the camera.
    const RayDifferential r = cam.generate(static_cast<float>(d.render.width), 0.0f, 0.5f, 0.5f);
    EXPECT_NEAR(r.o.x, 1.0f + 3.0f, 1e-4f);
    EXPECT_NEAR(r.o.y, 2.0f + 1.5f, 1e-4f);
    EXPECT_NEAR(r.d.z, -1.0f, 1e-6f);
    // A magnification of 0 is an error (a negative one: UnnamedCamerasArePickedByTheirIndex).
    for (const auto& [xmag, ymag] : {std::pair{"0", "1.5"}, std::pair{"3", "0"}})
        EXPECT_THROW(read_gltf_scene(write("bad.gltf", xmag, ymag), {}), SpangleError)
            << xmag << " " << ymag;
}

TEST(GltfReader, UnnamedCamerasArePickedByTheirIndex) {
    // The Khronos "Cameras" sample's two cameras have no names, nor do their nodes: --camera
    // "#1" picks the second (an orthographic one); before, no name could, and the error listed
    // two empty names.
    test::TempDir dir("gltf_unnamed_cameras");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    const std::string body = fmt::format(
        R"("nodes":[{{"mesh":0}},{{"camera":0,"translation":[0,0,5]}},{{"camera":1,"translation":[0,0,7]}}],)"
        R"("cameras":[{{"type":"perspective","perspective":{{"yfov":0.7,"znear":0.1}}}},)"
        R"({{"type":"orthographic","orthographic":{{"xmag":2,"ymag":-1,"znear":0.1,"zfar":100}}}}],)"
        R"("meshes":[{{"primitives":[{}]}}])",
        quad_primitive(q, -1));
    w.write_gltf(dir.file("cams.gltf"), body);
    const SceneDescription first = read_gltf_scene(dir.file("cams.gltf"), {});
    EXPECT_EQ(first.camera.ortho_height, 0.0);
    // The first of several cameras is taken, and said (it was silent).
    EXPECT_TRUE(has_note(first, "the file has 2 cameras: the first, '#0', is used"));
    SceneReadOptions second;
    second.camera = "#1";
    const SceneDescription d = read_gltf_scene(dir.file("cams.gltf"), second);
    EXPECT_EQ(d.camera.ortho_height, 2.0);
    EXPECT_NEAR(d.camera.position.z, 7.0f, kTol);
    bool noted = false;
    for (const std::string& n : d.notes)
        noted = noted || n.find("ymag -1 is negative") != std::string::npos;
    EXPECT_TRUE(noted);
    SceneReadOptions wrong;
    wrong.camera = "side";
    try {
        read_gltf_scene(dir.file("cams.gltf"), wrong);
        FAIL() << "no error for an unknown camera";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("(cameras: #0, #1)"), std::string::npos) << e.what();
    }
}

/** A quad and two cameras: an unnamed one on node "front", "top" on node "high". */
std::string two_cameras_body(GltfWriter& w) {
    const QuadAccessors q = quad(w);
    return fmt::format(
        R"("nodes":[{{"mesh":0}},{{"name":"front","camera":0,"translation":[0,0,5]}},)"
        R"({{"name":"high","camera":1,"translation":[0,9,0],"rotation":[-0.7071068,0,0,0.7071068]}}],)"
        R"("cameras":[{{"type":"perspective","perspective":{{"yfov":0.5,"znear":0.1}}}},)"
        R"({{"name":"top","type":"perspective","perspective":{{"yfov":0.7,"znear":0.1}}}}],)"
        R"("meshes":[{{"primitives":[{}]}}])",
        quad_primitive(q, -1));
}

TEST(GltfReader, CameraIsTheFirstOrTheOneNamed) {
    test::TempDir dir("gltf_cameras");
    GltfWriter w;
    w.write_gltf(dir.file("cams.gltf"), two_cameras_body(w));
    const SceneDescription first = read_gltf_scene(dir.file("cams.gltf"), {});
    EXPECT_NEAR(first.camera.fov_deg, 0.5 * 180.0 / M_PI, 1e-9);
    SceneReadOptions by_camera;
    by_camera.camera = "top";  // a camera's name
    const SceneDescription top = read_gltf_scene(dir.file("cams.gltf"), by_camera);
    EXPECT_NEAR(top.camera.fov_deg, 0.7 * 180.0 / M_PI, 1e-9);
    EXPECT_NEAR(top.camera.look_at.y, 8.0f, kTol);  // looking straight down from y = 9
    SceneReadOptions by_node;
    by_node.camera = "front";  // a camera node's name
    EXPECT_NEAR(read_gltf_scene(dir.file("cams.gltf"), by_node).camera.position.z, 5.0f, kTol);
    SceneReadOptions wrong;
    wrong.camera = "side";
    try {
        read_gltf_scene(dir.file("cams.gltf"), wrong);
        FAIL() << "no error for an unknown camera";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("no camera named 'side' (cameras: front, top)"),
                  std::string::npos)
            << e.what();
    }
}

TEST(GltfReader, TinygltfsErrorsAreSaidAtTheElementTheyName) {
    // tinygltf refuses an index to a missing buffer view itself; its error was placed at 1:1.
    test::TempDir dir("gltf_tiny_error");
    std::ofstream(dir.file("bad.gltf")) << R"({
  "asset": {"version": "2.0"},
  "meshes": [{"primitives": [{"attributes": {}, "indices": 0}]}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 6}],
  "accessors": [
    {
      "bufferView": 1,
      "componentType": 5123, "count": 3, "type": "SCALAR"
    }
  ]
})";
    try {
        read_gltf_scene(dir.file("bad.gltf"), {});
        ADD_FAILURE() << "no error";
    } catch (const SpangleError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("bad.gltf:7:"), std::string::npos) << what;
        EXPECT_NE(what.find("bufferView"), std::string::npos) << what;
    }
}

TEST(GltfReader, CameraByNameIsAnErrorWhereNoFileChoosesByName) {
    // `--camera top` on a TOML scene with its own [camera] rendered that camera without a word
    // (a typo too); it is an error now. Through an import into a scene without [camera] it
    // picks the glTF file's camera as on the file itself.
    test::TempDir dir("gltf_camera_option");
    GltfWriter w;
    w.write_gltf(dir.file("cams.gltf"), two_cameras_body(w));
    std::ofstream(dir.file("own.toml")) << "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, "
                                           "0]\n[[import]]\nfile = \"cams.gltf\"\n";
    std::ofstream(dir.file("none.toml")) << "[[import]]\nfile = \"cams.gltf\"\n";
    SceneReadOptions top;
    top.camera = "top";
    try {
        read_scene(dir.file("own.toml"), top);
        FAIL() << "--camera on a scene with its own [camera] was taken silently";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("--camera 'top': this scene does not choose"),
                  std::string::npos)
            << e.what();
    }
    const SceneDescription imported = read_scene(dir.file("none.toml"), top);
    EXPECT_NEAR(imported.camera.fov_deg, 0.7 * 180.0 / M_PI, 1e-9) << "the glTF's 'top'";
    EXPECT_NO_THROW(read_scene(dir.file("own.toml"), {})) << "without --camera: its [camera]";
}

TEST(GltfReader, WithoutCameraOrLightTheDefaultsFrameTheBoundsAndLightTheStudio) {
    test::TempDir dir("gltf_defaults");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    w.write_gltf(
        dir.file("bare.gltf"),
        fmt::format(
            R"("nodes":[{{"mesh":0,"translation":[10,0,0]}}],"meshes":[{{"primitives":[{}]}}])",
            quad_primitive(q, -1)));
    const SceneDescription d = read_gltf_scene(dir.file("bare.gltf"), {});
    // The quad spans [10, 11] x [0, 1] x 0: the camera looks at its centre from +z, 15 degrees
    // up, at the distance where its bounding sphere (radius sqrt(2) / 2) fills the 40-degree view.
    EXPECT_NEAR(d.camera.look_at.x, 10.5f, kTol);
    EXPECT_NEAR(d.camera.look_at.y, 0.5f, kTol);
    const Vec3 v = d.camera.position - d.camera.look_at;
    EXPECT_NEAR(length(v), std::sqrt(0.5f) / std::sin(20.0f * kPi / 180.0f), 1e-4f);
    EXPECT_NEAR(std::atan2(v.y, v.z) * 180.0f / kPi, 15.0f, 1e-3f);
    EXPECT_EQ(d.camera.fov_deg, 40.0);
    EXPECT_TRUE(has_note(d, "no camera: a default framing"));
    // Imported by a TOML scene: said where the framing is the scene's camera, not where the
    // scene has its own (the note said the framing stood in under the scene's camera).
    std::ofstream(dir.file("own.toml")) << "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, "
                                           "0]\n[[import]]\nfile = \"bare.gltf\"\n";
    std::ofstream(dir.file("none.toml")) << "[[import]]\nfile = \"bare.gltf\"\n";
    EXPECT_FALSE(has_note(read_scene(dir.file("own.toml")), "no camera: a default framing"));
    EXPECT_TRUE(has_note(read_scene(dir.file("none.toml")), "no camera: a default framing"));
    ASSERT_TRUE(d.environment && d.environment->color);
    EXPECT_EQ(d.environment->color->rgb.x, 0.25f);
    ASSERT_EQ(d.lights.size(), 1u);
    EXPECT_TRUE(std::holds_alternative<DistantLightDesc>(d.lights[0].shape));
    EXPECT_TRUE(has_note(d, "default studio light"));
    // The material-less primitive gets glTF's default material: white, metallic 1, roughness 1.
    ASSERT_EQ(d.materials.size(), 1u);
    EXPECT_EQ(d.materials[0].name, "gltf_default");
    EXPECT_EQ(d.materials[0].model, "metal_rough");
    EXPECT_EQ(param(d.materials[0], "metallic")->number, 1.0);

    // --env lights the scene instead: then no stand-in light, and the map is the environment.
    SceneReadOptions with_env;
    with_env.environment = test::asset_dir() + "/env/studio.exr";
    const SceneDescription lit = read_scene(dir.file("bare.gltf"), with_env);
    EXPECT_TRUE(lit.lights.empty());
    EXPECT_FALSE(has_note(lit, "default studio light"));
    ASSERT_TRUE(lit.environment && lit.environment->map);
    EXPECT_EQ(lit.environment->map->path, with_env.environment);
    EXPECT_FALSE(has_note(d, "mesh")) << "it draws one";

    // An export of nothing: said (the notes were of the camera and the light only).
    std::ofstream(dir.file("empty.gltf"))
        << R"({"asset":{"version":"2.0"},"nodes":[{"name":"nothing"}]})";
    EXPECT_TRUE(has_note(read_gltf_scene(dir.file("empty.gltf"), {}),
                         "the file has no meshes: the image shows only the background"));
    GltfWriter empty;
    const QuadAccessors unused = quad(empty);
    empty.write_gltf(
        dir.file("undrawn.gltf"),
        fmt::format(R"("nodes":[{{"name":"nothing"}}],"meshes":[{{"primitives":[{}]}}])",
                    quad_primitive(unused, -1)));
    EXPECT_TRUE(has_note(read_gltf_scene(dir.file("undrawn.gltf"), {}),
                         "no node of the scene draws a mesh"));
}

TEST(GltfReader, ANodeFlattenedOntoAPlaneIsDrawnFlat) {
    // scale [1, 0, 1] flattens the quad's node onto a plane: drawn flat, as viewers draw it (it
    // was "scaled to nothing" and dropped); onto a line ([0, 0, 1]) nothing keeps an area.
    test::TempDir dir("gltf_flat");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    w.write_gltf(
        dir.file("flat.gltf"),
        fmt::format(R"("nodes":[{{"mesh":0,"scale":[1,1,0]}},{{"mesh":0,"scale":[0,1,0]}}],)"
                    R"("meshes":[{{"primitives":[{}]}}])",
                    quad_primitive(q, -1)));
    const SceneDescription d = read_gltf_scene(dir.file("flat.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    const Affine& m = *d.objects[0].placement.matrix;
    EXPECT_GT(std::fabs(m.determinant()), 1e-18f);
    const Vec3 corner = m.apply_point({1, 1, 0});
    EXPECT_NEAR(corner.x, 1.0f, 1e-5f);
    EXPECT_NEAR(corner.y, 1.0f, 1e-5f);
    EXPECT_NEAR(corner.z, 0.0f, 1e-5f);
    EXPECT_EQ(count_notes(d, "scaled to nothing"), 1);
}

TEST(GltfReader, EmissionTooFaintToLightTheFileGetsTheStudioLight) {
    // A 1 x 1 grey quad beside a small emissive quad (scaled 0.02, an LED): the LED's power
    // spread over the surfaces is far below the studio light's, and the file rendered black
    // (the emission counted as light). A large emissive panel lights the file itself.
    test::TempDir dir("gltf_faint");
    const auto write = [&](const std::string& file, double led_scale, double strength) {
        GltfWriter w;
        const QuadAccessors q = quad(w);
        w.write_gltf(
            dir.file(file),
            fmt::format(
                R"("materials":[{{"name":"grey"}},{{"name":"led","emissiveFactor":[0,1,0],)"
                R"("extensions":{{"KHR_materials_emissive_strength":{{"emissiveStrength":{}}}}}}}],)"
                R"("nodes":[{{"mesh":0}},{{"mesh":1,"scale":[{},{},1],"translation":[0,0,0.1]}}],)"
                R"("meshes":[{{"primitives":[{}]}},{{"primitives":[{}]}}])",
                strength, led_scale, led_scale, quad_primitive(q, 0), quad_primitive(q, 1)));
        return read_gltf_scene(dir.file(file), {});
    };
    const SceneDescription led = write("led.gltf", 0.02, 5.0);
    EXPECT_EQ(led.lights.size(), 1u);
    EXPECT_TRUE(has_note(led, "emission too faint to light it"));
    // (Power 5 pi 4e-4 over 1.0004 square units: irradiance 0.006.)
    const SceneDescription panel = write("panel.gltf", 1.0, 4.0);
    EXPECT_TRUE(panel.lights.empty());
    EXPECT_FALSE(has_note(panel, "default studio light"));
    EXPECT_TRUE(has_note(panel, "the file's only light is its emission (radiance up to 4)"));
    // The same panel at radiance 1 (emissive factor 1 without a strength: a label, a screen,
    // as the Khronos test models' labels are) is glow: the studio light is added beside it
    // (those models rendered nearly black, their labels taken for their light).
    const SceneDescription label = write("label.gltf", 1.0, 1.0);
    EXPECT_EQ(label.lights.size(), 1u);
    EXPECT_TRUE(has_note(label, "emission of radiance at most 1"));
}

TEST(GltfReader, LightsThatLeaveTheFileNearlyBlackAreSaid) {
    // A sun of 3 lux is 0.0044 W/m^2 at 683 lm/W: a file made for a viewer that reads it without
    // units rendered black without a word. 1000 lux (1.5 W/m^2) is said nothing of.
    test::TempDir dir("gltf_dim");
    const auto write = [&](const std::string& file, double lux) {
        GltfWriter w;
        const QuadAccessors q = quad(w);
        w.write_gltf(dir.file(file),
                     fmt::format(R"("extensionsUsed":["KHR_lights_punctual"],"extensions":)"
                                 R"({{"KHR_lights_punctual":{{"lights":[{{"type":"directional",)"
                                 R"("intensity":{}}}]}}}},"nodes":[{{"mesh":0}},)"
                                 R"({{"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}}],)"
                                 R"("meshes":[{{"primitives":[{}]}}])",
                                 lux, quad_primitive(q, -1)));
        return read_gltf_scene(dir.file(file), {});
    };
    const SceneDescription dim = write("dim.gltf", 3.0);
    EXPECT_TRUE(has_note(dim, "the file's lights give about 0.0044 W/m^2")) << dim.notes.size();
    EXPECT_TRUE(has_note(dim, "569 times less than the studio key light's"));
    EXPECT_FALSE(has_note(write("bright.gltf", 1000.0), "the file's lights give"));
    // With --env the map lights it too: not said.
    SceneReadOptions env;
    env.environment = test::asset_dir() + "/env/studio.exr";
    EXPECT_FALSE(has_note(read_scene(dir.file("dim.gltf"), env), "the file's lights give"));
}

TEST(GltfReader, PunctualLightsTakeTheirNodesPlaceAndPhotometricUnits) {
    test::TempDir dir("gltf_lights");
    GltfWriter w;
    const QuadAccessors q = quad(w);
    // A spot at (0, 3, 0) pointing down (-z turned to -y), a point and a sun.
    const std::string body = fmt::format(
        R"("extensionsUsed":["KHR_lights_punctual"],)"
        R"("extensions":{{"KHR_lights_punctual":{{"lights":[)"
        R"({{"type":"point","color":[1,0.5,0.25],"intensity":683,"range":4}},)"
        R"({{"type":"spot","intensity":1366,"spot":{{"innerConeAngle":0.2,"outerConeAngle":0.6}}}},)"
        R"({{"type":"directional","intensity":6.83}}]}}}},)"
        R"("nodes":[{{"mesh":0}},{{"translation":[1,2,3],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}},)"
        R"({{"translation":[0,3,0],"rotation":[-0.7071068,0,0,0.7071068],"extensions":{{"KHR_lights_punctual":{{"light":1}}}}}},)"
        R"({{"rotation":[-0.7071068,0,0,0.7071068],"extensions":{{"KHR_lights_punctual":{{"light":2}}}}}}],)"
        R"("meshes":[{{"primitives":[{}]}}])",
        quad_primitive(q, -1));
    w.write_gltf(dir.file("lights.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("lights.gltf"), {});
    ASSERT_EQ(d.lights.size(), 3u);
    EXPECT_FALSE(d.environment);
    // 683 cd is 1 W/sr at 555 nm.
    EXPECT_NEAR(d.lights[0].intensity, 1.0, 1e-12);
    EXPECT_EQ(d.lights[0].color->rgb.y, 0.5f);
    EXPECT_EQ(d.lights[0].color->space, "lin_rec709");
    const auto& point = std::get<PointLightDesc>(d.lights[0].shape);
    EXPECT_NEAR(point.position.z, 3.0f, kTol);
    const auto& spot = std::get<SpotLightDesc>(d.lights[1].shape);
    EXPECT_NEAR(spot.look_at.y - spot.position.y, -1.0f, kTol);
    EXPECT_NEAR(spot.cone_angle, 0.6 * 180.0 / M_PI, 1e-6);
    EXPECT_NEAR(spot.cone_falloff, 0.4 * 180.0 / M_PI, 1e-6);
    EXPECT_NEAR(d.lights[1].intensity, 2.0, 1e-12);
    const auto& sun = std::get<DistantLightDesc>(d.lights[2].shape);
    EXPECT_NEAR(sun.direction.y, 1.0f, kTol);  // towards the light: up
    EXPECT_NEAR(d.lights[2].intensity, 0.01, 1e-12);
    EXPECT_TRUE(has_note(d, "range is dropped"));
    // The builder puts each light on an entity without complaint.
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    EXPECT_NO_THROW(build_scene(d, color, registry));
}

}  // namespace
}  // namespace spangle::test_gltf_reader
