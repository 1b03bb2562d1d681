// glTF skins and morph targets: meshes drawn in the shape their joints and weights give them,
// through time when animated, with the written shape as their rest pose.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "desc_support.h"
#include "gltf_writer.h"
#include "pipeline/session.h"
#include "scene/components.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/scene_builder.h"
#include "scene/toml_scene_writer.h"
#include "test_support.h"

namespace spangle {
namespace {

using test::GltfWriter;

constexpr float kS = 0.70710678f;  ///< sin 45 degrees: a quarter turn's quaternion parts

bool has_note(const SceneDescription& d, const std::string& text) {
    for (const std::string& n : d.notes)
        if (n.find(text) != std::string::npos) return true;
    return false;
}

/** A bar of 2 x 3 vertices in the xy plane (x 0..1, y 0, 1, 2), normals +x, skinned to two
 *  joints: the bottom row to the root joint, the middle row half and half, the top row to the
 *  "bend" joint at y = 1. `bend` is the bend joint's extra JSON (a rotation), `animations` the
 *  file's animations (or empty), `joints` the JOINTS_0 of the top row's first vertex. */
std::string skinned_bar(GltfWriter& w, const std::string& bend, const std::string& animations,
                        uint16_t top_joint = 1) {
    const int pos = w.floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0}, "VEC3", 3);
    const int nrm = w.floats({1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0}, "VEC3", 3);
    const int idx = w.u16({0, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4});
    const int joints =
        w.u16s({0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, top_joint, 0, 0, 0, 1, 0, 0, 0},
               "VEC4", 4);
    const int weights = w.floats(
        {1, 0, 0, 0, 1, 0, 0, 0, 0.5f, 0.5f, 0, 0, 0.5f, 0.5f, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0},
        "VEC4", 4);
    const int ibm = w.floats({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0,  0, 1,
                              1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, 0, 1},
                             "MAT4", 16);
    return fmt::format(
        R"("materials":[{{}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{},)"
        R"("NORMAL":{},"JOINTS_0":{},"WEIGHTS_0":{}}},"indices":{},"material":0}}]}}],)"
        R"("nodes":[{{"name":"body","mesh":0,"skin":0}},{{"name":"root","children":[2]}},)"
        R"({{"name":"bend","translation":[0,1,0]{}}}],)"
        R"("skins":[{{"joints":[1,2],"inverseBindMatrices":{}}}],{})"
        R"("scenes":[{{"nodes":[0,1]}}],"scene":0)",
        pos, nrm, joints, weights, idx, bend, ibm, animations);
}

/** The bar with its bend joint turning from nothing to a quarter over one second (LINEAR). */
std::string bending_bar(GltfWriter& w) {
    const int t = w.floats({0, 1}, "SCALAR", 1);
    const int q = w.floats({0, 0, 0, 1, 0, 0, kS, kS}, "VEC4", 4);
    return skinned_bar(w, "",
                       fmt::format(R"("animations":[{{"channels":[{{"sampler":0,)"
                                   R"("target":{{"node":2,"path":"rotation"}}}}],)"
                                   R"("samplers":[{{"input":{},"output":{}}}]}}],)",
                                   t, q));
}

const InlineMeshShape& shape_of(const SceneDescription& d, std::size_t i = 0) {
    return std::get<InlineMeshShape>(d.objects.at(i).shape);
}

void expect_vertex(const TriangleMesh& m, uint32_t i, Vec3 want, const char* what) {
    const Vec3 p = m.position(i);
    EXPECT_NEAR(p.x, want.x, 1e-5f) << what << " vertex " << i;
    EXPECT_NEAR(p.y, want.y, 1e-5f) << what << " vertex " << i;
    EXPECT_NEAR(p.z, want.z, 1e-5f) << what << " vertex " << i;
}

TEST(GltfDeform, ABindPoseSkinLeavesTheMeshExactlyAsWritten) {
    test::TempDir dir("gltf_deform_bind");
    GltfWriter w;
    w.write_gltf(dir.file("bar.gltf"), skinned_bar(w, "", ""));
    const SceneDescription d = read_gltf_scene(dir.file("bar.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    const InlineMeshShape& s = shape_of(d);
    EXPECT_FALSE(s.deformation) << "nothing moves";
    ASSERT_TRUE(s.mesh);
    const std::vector<float> written{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0};
    EXPECT_EQ(s.mesh->positions, written) << "bit for bit";
    EXPECT_TRUE(s.mesh->rest_positions.empty()) << "a mesh in its rest pose carries none";
    for (const std::string& n : d.notes) EXPECT_EQ(n.find("skin"), std::string::npos) << n;
}

TEST(GltfDeform, APosedSkinBendsItsVerticesByTheirWeightsAndKeepsTheBindShapeAsRest) {
    // The bend joint turned a quarter about z: the top row swings round the joint at (0, 1),
    // the middle row (half on each joint) goes half way, the bottom row stays.
    test::TempDir dir("gltf_deform_pose");
    GltfWriter w;
    w.write_gltf(dir.file("bar.gltf"),
                 skinned_bar(w, fmt::format(R"(,"rotation":[0,0,{},{}])", kS, kS), ""));
    const SceneDescription d = read_gltf_scene(dir.file("bar.gltf"), {});
    const InlineMeshShape& s = shape_of(d);
    EXPECT_FALSE(s.deformation) << "a still pose is computed once";
    const TriangleMesh& m = *s.mesh;
    expect_vertex(m, 0, {0, 0, 0}, "bottom");
    expect_vertex(m, 1, {1, 0, 0}, "bottom");
    expect_vertex(m, 2, {0, 1, 0}, "middle");        // (0,1) and its turn (0,1) averaged
    expect_vertex(m, 3, {0.5f, 1.5f, 0}, "middle");  // (1,1) and (0,2) averaged
    expect_vertex(m, 4, {-1, 1, 0}, "top");
    expect_vertex(m, 5, {-1, 2, 0}, "top");
    // Normals: +x turned a quarter is +y at the top; half-way (normalised) in the middle.
    ASSERT_EQ(m.normals.size(), 18u);
    EXPECT_NEAR(m.normals[3 * 4], 0.0f, 1e-5f);
    EXPECT_NEAR(m.normals[3 * 4 + 1], 1.0f, 1e-5f);
    EXPECT_NEAR(m.normals[3 * 2], kS, 1e-5f);
    EXPECT_NEAR(m.normals[3 * 2 + 1], kS, 1e-5f);
    // The written shape is the rest pose: flakes stay where they were laid out.
    const std::vector<float> written{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0};
    EXPECT_EQ(m.rest_positions, written);
    // The builder flags it as posed (the layers' Pobj is its rest pose).
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo info = build_scene(d, color, registry);
    ASSERT_EQ(info.rest_pose.size(), 1u);
    EXPECT_EQ(info.rest_pose[0], 1);
}

TEST(GltfDeform, AnAnimatedSkinDeformsAtTheTimeTheSceneIsBuiltAt) {
    // The bend joint turns from nothing to a quarter over one second (LINEAR).
    test::TempDir dir("gltf_deform_anim");
    GltfWriter w;
    w.write_gltf(dir.file("bar.gltf"), bending_bar(w));
    const SceneDescription d = read_gltf_scene(dir.file("bar.gltf"), {});
    const InlineMeshShape& s = shape_of(d);
    ASSERT_TRUE(s.deformation);
    EXPECT_DOUBLE_EQ(s.deformation->first, 0.0);
    EXPECT_DOUBLE_EQ(s.deformation->last, 1.0);
    // At 0 s the bind shape (the mesh itself, no rest pose); at 1 s the quarter turn; half way
    // an eighth (the joint slerped, as the builder interpolates matrix keys).
    EXPECT_TRUE(s.deformation->at(0.0)->rest_positions.empty());
    const auto end = s.deformation->at(1.0);
    expect_vertex(*end, 4, {-1, 1, 0}, "1 s");
    const auto half = s.deformation->at(0.5);
    expect_vertex(*half, 4, {-kS, 1 + kS, 0}, "0.5 s");
    expect_vertex(*s.deformation->at(7.0), 5, {-1, 2, 0}, "held after the last key");
    EXPECT_EQ(d.render.frame_end, d.render.frame_start + 24) << "1 s at 24 fps";
    // The builder draws the frame's shape and knows the scene moves.
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo info = build_scene(d, color, registry, 1.0);
    EXPECT_TRUE(info.animated);
    ASSERT_EQ(info.rest_pose.size(), 1u);
    EXPECT_EQ(info.rest_pose[0], 1);
    auto* pool = registry.find_pool<InlineMesh>();
    ASSERT_TRUE(pool);
    ASSERT_EQ(pool->size(), 1u);
    const InlineMesh m = pool->columns().get(0);
    expect_vertex(*m.mesh, 4, {-1, 1, 0}, "built at 1 s");
    EXPECT_FALSE(m.mesh->rest_positions.empty());
}

/** A small render of `scene` (a file, or a description) at `time`. */
template <class Scene>
std::vector<float> render_at(const Scene& scene, double time) {
    RenderOptions o;
    o.threads = 2;
    o.spp_override = 2;
    o.width_override = 40;
    o.height_override = 32;
    Session s({}, test::shipped_ocio(), o, test::quiet_log());
    s.load(scene, time);
    s.render();
    return s.result().image;
}

TEST(GltfDeform, ConvertWritesADeformingMeshAsAFrameSequenceThatRendersTheSame) {
    test::TempDir dir("gltf_deform_convert");
    GltfWriter w;
    w.write_gltf(dir.file("bar.gltf"), bending_bar(w));
    const SceneDescription d = read_gltf_scene(dir.file("bar.gltf"), {});
    const std::string out = dir.file("bar.toml");
    const SceneWriteReport rep = write_toml_scene(d, out, dir.file("bar_meshes"));
    // Frames 1 to 25 (1 s at 24 fps) and the rest pose.
    EXPECT_EQ(rep.meshes.size(), 26u);
    std::ifstream in(out);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("deform_000.####.ply"), std::string::npos) << text;
    EXPECT_NE(text.find("rest_mesh"), std::string::npos) << text;
    for (const double time : {0.0, 0.5, 1.0}) {
        SCOPED_TRACE(time);
        const std::vector<float> theirs = render_at(d, time);
        EXPECT_EQ(render_at(out, time), theirs);
        if (time > 0.0) {
            EXPECT_NE(render_at(d, 0.0), theirs) << "the bar bends";
        }
    }
}

TEST(GltfDeform, AVertexNamingAJointTheSkinLacksIsNotedAndKeepsItsOtherInfluences) {
    test::TempDir dir("gltf_deform_badjoint");
    GltfWriter w;
    w.write_gltf(dir.file("bar.gltf"),
                 skinned_bar(w, fmt::format(R"(,"rotation":[0,0,{},{}])", kS, kS), "", 7));
    const SceneDescription d = read_gltf_scene(dir.file("bar.gltf"), {});
    EXPECT_TRUE(has_note(d, "names a joint the skin does not have"));
    // Vertex 4 lost its only influence: it stays where it was written.
    expect_vertex(*shape_of(d).mesh, 4, {0, 2, 0}, "no influence");
    expect_vertex(*shape_of(d).mesh, 5, {-1, 2, 0}, "its neighbour still turns");
}

TEST(GltfDeform, TooFewInverseBindMatricesAreAnErrorAtTheSkin) {
    test::TempDir dir("gltf_deform_ibm");
    GltfWriter w;
    std::string body = skinned_bar(w, "", "");
    // Point the skin at a one-matrix accessor (the bar's joints need two).
    const int one = w.floats({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, "MAT4", 16);
    const std::string key = R"("inverseBindMatrices":)";
    const std::size_t at = body.find(key) + key.size();
    body.replace(at, body.find('}', at) - at, std::to_string(one));
    w.write_gltf(dir.file("bar.gltf"), body);
    try {
        read_gltf_scene(dir.file("bar.gltf"), {});
        ADD_FAILURE() << "read";
    } catch (const SpangleError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("2 joints and 1 inverse bind matrices"), std::string::npos) << m;
        EXPECT_NE(m.find("bar.gltf:1:"), std::string::npos) << m;
    }
}

/** A triangle with one morph target lifting every vertex by 1 in z (and tilting its normal),
 *  `mesh_extra` and `node_extra` the mesh's and node's extra JSON, `animations` the file's. */
std::string morphing_triangle(GltfWriter& w, const std::string& mesh_extra,
                              const std::string& node_extra, const std::string& animations) {
    const int pos = w.floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3", 3);
    const int nrm = w.floats({0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 3);
    const int dp = w.floats({0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 3);
    const int dn = w.floats({1, 0, -1, 1, 0, -1, 1, 0, -1}, "VEC3", 3);
    return fmt::format(
        R"("materials":[{{}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{},)"
        R"("NORMAL":{}}},"targets":[{{"POSITION":{},"NORMAL":{}}}],"material":0}}]{}}}],)"
        R"("nodes":[{{"mesh":0{}}}],{}"scenes":[{{"nodes":[0]}}],"scene":0)",
        pos, nrm, dp, dn, mesh_extra, node_extra, animations);
}

TEST(GltfDeform, MorphTargetsTakeTheNodesWeightsElseTheMeshs) {
    test::TempDir dir("gltf_deform_morph");
    {
        GltfWriter w;
        w.write_gltf(dir.file("mesh.gltf"), morphing_triangle(w, R"(,"weights":[0.25])", "", ""));
        const SceneDescription d = read_gltf_scene(dir.file("mesh.gltf"), {});
        const TriangleMesh& m = *shape_of(d).mesh;
        expect_vertex(m, 1, {1, 0, 0.25f}, "mesh weights");
        EXPECT_NEAR(m.normals[0], 0.25f / std::hypot(0.25f, 0.75f), 1e-5f);
        EXPECT_EQ(m.rest_positions, (std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}));
        EXPECT_FALSE(shape_of(d).deformation);
    }
    {
        GltfWriter w;
        w.write_gltf(dir.file("node.gltf"),
                     morphing_triangle(w, R"(,"weights":[0.25])", R"(,"weights":[0.5])", ""));
        const SceneDescription d = read_gltf_scene(dir.file("node.gltf"), {});
        expect_vertex(*shape_of(d).mesh, 2, {0, 1, 0.5f}, "node weights");
    }
    {
        GltfWriter w;
        w.write_gltf(dir.file("none.gltf"), morphing_triangle(w, "", "", ""));
        const SceneDescription d = read_gltf_scene(dir.file("none.gltf"), {});
        EXPECT_TRUE(shape_of(d).mesh->rest_positions.empty()) << "weights 0: the base shape";
        expect_vertex(*shape_of(d).mesh, 2, {0, 1, 0}, "no weights");
    }
    {
        GltfWriter w;
        w.write_gltf(dir.file("nan.gltf"), morphing_triangle(w, R"(,"weights":[1e39])", "", ""));
        EXPECT_THROW(read_gltf_scene(dir.file("nan.gltf"), {}), SpangleError);
    }
}

TEST(GltfDeform, NodesDrawingOnePrimitiveWithTheSameWeightsShareOneMesh) {
    // Linked duplicates of a morphed mesh (a crowd): one still shape, one mesh in memory.
    test::TempDir dir("gltf_deform_shared");
    GltfWriter w;
    std::string body = morphing_triangle(w, R"(,"weights":[0.5])", "", "");
    const std::string nodes = R"("nodes":[{"mesh":0}])";
    body.replace(body.find(nodes), nodes.size(),
                 R"("nodes":[{"mesh":0},{"mesh":0,"translation":[2,0,0]},)"
                 R"({"mesh":0,"weights":[0.25]}])");
    const std::string roots = R"("nodes":[0])";
    body.replace(body.find(roots), roots.size(), R"("nodes":[0,1,2])");
    w.write_gltf(dir.file("crowd.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("crowd.gltf"), {});
    ASSERT_EQ(d.objects.size(), 3u);
    EXPECT_EQ(shape_of(d, 0).mesh, shape_of(d, 1).mesh) << "same weights: one mesh";
    EXPECT_NE(shape_of(d, 0).mesh, shape_of(d, 2).mesh) << "its own weights: its own shape";
    expect_vertex(*shape_of(d, 2).mesh, 0, {0, 0, 0.25f}, "node weights");
}

TEST(GltfDeform, AFirstJointThatFlattensTheMeshDeformsItInWorldSpace) {
    // The first joint's inverse bind matrix scales z to 0: no placement the vertices can be
    // expressed in. The mesh is deformed in world space (placed by none), not refused.
    test::TempDir dir("gltf_deform_flat");
    GltfWriter w;
    std::string body = skinned_bar(w, fmt::format(R"(,"rotation":[0,0,{},{}])", kS, kS), "");
    const int flat = w.floats({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0,  0, 1,
                               1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, 0, 1},
                              "MAT4", 16);
    const std::string key = R"("inverseBindMatrices":)";
    const std::size_t at = body.find(key) + key.size();
    body.replace(at, body.find('}', at) - at, std::to_string(flat));
    w.write_gltf(dir.file("bar.gltf"), body);
    const SceneDescription d = read_gltf_scene(dir.file("bar.gltf"), {});
    EXPECT_TRUE(has_note(d, "is not invertible: its mesh is deformed in world space"));
    ASSERT_EQ(d.objects.size(), 1u);
    ASSERT_TRUE(d.objects[0].placement.matrix);
    EXPECT_EQ(*d.objects[0].placement.matrix, Affine{}) << "placed by none";
    // The top row follows the bend joint (an ordinary inverse bind matrix) as before.
    expect_vertex(*shape_of(d).mesh, 5, {-1, 2, 0}, "top");
}

TEST(GltfDeform, AnimatedWeightsFollowTheirChannel) {
    test::TempDir dir("gltf_deform_anim_w");
    GltfWriter w;
    const int t = w.floats({0, 2}, "SCALAR", 1);
    const int v = w.floats({0, 1}, "SCALAR", 1);
    w.write_gltf(dir.file("w.gltf"),
                 morphing_triangle(w, "", "",
                                   fmt::format(R"("animations":[{{"channels":[{{"sampler":0,)"
                                               R"("target":{{"node":0,"path":"weights"}}}}],)"
                                               R"("samplers":[{{"input":{},"output":{}}}]}}],)",
                                               t, v)));
    const SceneDescription d = read_gltf_scene(dir.file("w.gltf"), {});
    const InlineMeshShape& s = shape_of(d);
    ASSERT_TRUE(s.deformation);
    expect_vertex(*s.deformation->at(1.0), 0, {0, 0, 0.5f}, "1 s");
    expect_vertex(*s.deformation->at(5.0), 0, {0, 0, 1.0f}, "held");
    EXPECT_EQ(d.render.frame_end, d.render.frame_start + 48) << "2 s at 24 fps";
    for (const std::string& n : d.notes) EXPECT_EQ(n.find("weights "), std::string::npos) << n;
}

}  // namespace
}  // namespace spangle
