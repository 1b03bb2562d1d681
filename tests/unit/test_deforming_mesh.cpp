// Deforming meshes: a numbered mesh sequence ("plane.####.ply") reads the file of the frame it
// renders, every frame's topology is checked against the rest pose, and object-space shading
// inputs come from the rest pose, so that object-space flakes stay on their spot of a surface
// that moves in its own files.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "core/error.h"
#include "geometry/ply_writer.h"
#include "geometry/rest_pose.h"
#include "pipeline/session.h"
#include "render/surface.h"
#include "scene/frame_sequence.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "scene/toml_scene_writer.h"
#include "test_support.h"

namespace spangle::test_deforming_mesh {
namespace {

TEST(FrameSequence, TheRunOfHashesBecomesTheZeroPaddedFrame) {
    EXPECT_EQ(expand_frame_pattern("body.####.ply", 7), "body.0007.ply");
    EXPECT_EQ(expand_frame_pattern("/a/b/body.##.ply", 123), "/a/b/body.123.ply");
    EXPECT_EQ(expand_frame_pattern("body_#.obj", 0), "body_0.obj");
    EXPECT_EQ(expand_frame_pattern("body.####.ply", -3), "body.-003.ply");
    EXPECT_EQ(expand_frame_pattern("body.ply", 5), "body.ply");
    // Only the file name numbers frames: a '#' in a folder's name is part of the folder.
    EXPECT_EQ(expand_frame_pattern("take#2/body.###.ply", 12), "take#2/body.012.ply");
    EXPECT_FALSE(is_frame_pattern("take#2/body.ply"));
    EXPECT_TRUE(find_frame_run("a.##.##.ply").several);
    EXPECT_FALSE(find_frame_run("a.####.ply").several);
}

TEST(FrameSequence, TheFrameOfATimeIsFrameStartPlusTheTimeInFrames) {
    EXPECT_EQ(frame_at(1, 24.0, 0.0), 1);
    EXPECT_EQ(frame_at(1, 24.0, 2.0 / 24.0), 3);
    EXPECT_EQ(frame_at(101, 30.0, 29.0 / 30.0), 130);
    EXPECT_EQ(frame_at(-5, 24.0, 1.0), 19);
}

/** A plane of n x n quads over [-2, 2]^2 at z = 0, each vertex moved by `move`. */
template <class Move>
TriangleMesh grid(int n, const Move& move) {
    TriangleMesh m;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const Vec3 p =
                move(Vec3(-2.0f + 4.0f * static_cast<float>(i) / static_cast<float>(n),
                          -2.0f + 4.0f * static_cast<float>(j) / static_cast<float>(n), 0.0f));
            m.positions.insert(m.positions.end(), {p.x, p.y, p.z});
        }
    const auto v = [n](int i, int j) { return static_cast<uint32_t>(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            m.indices.insert(m.indices.end(), {v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j),
                                               v(i + 1, j + 1), v(i, j + 1)});
    return m;
}

TEST(RestPose, ADifferentTopologyIsAnErrorNamingBothFiles) {
    TriangleMesh a = grid(2, [](Vec3 p) { return p; });
    TriangleMesh b = grid(3, [](Vec3 p) { return p; });
    a.source = "plane.0002.ply";
    b.source = "plane.0001.ply";
    try {
        check_same_topology(a, b, FileLoc{"scene.toml", 12, 8});
        FAIL() << "meshes of 9 and 16 vertices passed";
    } catch (const SpangleError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("scene.toml:12:8"), std::string::npos) << what;
        EXPECT_NE(what.find("plane.0002.ply"), std::string::npos) << what;
        EXPECT_NE(what.find("plane.0001.ply"), std::string::npos) << what;
        EXPECT_NE(what.find("9 vertices"), std::string::npos) << what;
    }
    // The same counts, but one triangle turned: still another topology.
    TriangleMesh c = a;
    std::swap(c.indices[1], c.indices[2]);
    c.source = "turned.ply";
    EXPECT_THROW(check_same_topology(a, c, {}), SpangleError);
}

TEST(RestPose, AMeshInItsRestPoseCarriesNoRestPositions) {
    auto mesh = std::make_shared<const TriangleMesh>(grid(2, [](Vec3 p) { return p; }));
    EXPECT_EQ(with_rest_pose(mesh, *mesh, {}), mesh);
    const TriangleMesh moved = grid(2, [](Vec3 p) { return p + Vec3(0, 0, 1); });
    const auto posed = with_rest_pose(mesh, moved, {});
    EXPECT_NE(posed, mesh);
    EXPECT_EQ(posed->positions, mesh->positions);
    EXPECT_EQ(posed->rest_positions, moved.positions);
}

// The shading inputs of a hit on a stretched and moved triangle are those of the same
// barycentrics on the rest triangle, and the footprint axes go through the triangle's affine map.
TEST(RestPose, ObjectSpaceInputsAreTheRestPosesAtTheHit) {
    TriangleMesh m;
    // Deformed: the rest triangle stretched 2x along x, sheared and lifted by 1 in z.
    m.rest_positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    m.positions = {0, 0, 1, 2, 0, 1, 0.5f, 1, 1};
    m.indices = {0, 1, 2};
    Instance inst;
    Hit h;
    h.b1 = 0.25f;
    h.b2 = 0.5f;
    SurfacePoint sp = surface_at(m, inst, h, {0, 0, 5}, {0, 0, -1});
    EXPECT_NEAR(sp.p.x, 0.25f * 2 + 0.5f * 0.5f, 1e-6f);
    EXPECT_NEAR(sp.p.z, 1.0f, 1e-6f);
    EXPECT_NEAR(sp.p_obj.x, 0.25f, 1e-6f);
    EXPECT_NEAR(sp.p_obj.y, 0.5f, 1e-6f);
    EXPECT_NEAR(sp.p_obj.z, 0.0f, 1e-6f);
    EXPECT_NEAR(sp.ng_obj.z, 1.0f, 1e-6f);
    // A step along the deformed x edge is half as long on the rest pose; one along the deformed
    // second edge (0.5, 1) is the rest's (0, 1).
    sp.dpdx = {0.02f, 0, 0};
    sp.dpdy = {0.005f, 0.01f, 0};
    object_footprint(sp, inst, m, 0);
    EXPECT_NEAR(sp.dpdx_obj.x, 0.01f, 1e-7f);
    EXPECT_NEAR(sp.dpdx_obj.y, 0.0f, 1e-7f);
    EXPECT_NEAR(sp.dpdy_obj.x, 0.0f, 1e-7f);
    EXPECT_NEAR(sp.dpdy_obj.y, 0.01f, 1e-7f);
    EXPECT_NEAR(sp.dpdy_obj.z, 0.0f, 1e-7f);
}

/** A plane in object-space glitter facing a camera 4 units away (48 x 48 pixels, 0.0447 units
 *  each at the plane); `object` is the rest of its [[object]] table. */
std::string plane_scene(const std::string& object) {
    return R"([render]
width = 48
height = 48
spp = 16
max_depth = 1
filter = "box"
working_space = "lin_rec709"
frame_start = 1
frame_end = 3

[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]
fov = 30

[[material]]
name = "glitter"
plugin = "flake"
params = { base_color = 0.0, flake_weight = 1.0, density = 400, density_space = "object", flake_roughness = 0.2, gamma = 3, min_flakes = 100000000, max_flakes = 1000000000 }

[[light]]
type = "sphere"
center = [0.8, 0.6, 4.2]
radius = 1.0
intensity = 21

[[object]]
material = "glitter"
)" + object +
           "\n";
}

/** Width of a pixel at the plane z = 0 (fov 30, 48 pixels, 4 units away). */
constexpr float kPixel = static_cast<float>(2.0 * 4.0 * 0.26794919243 / 48.0);

/** The render of a session at frame f: the image and the layers. */
struct Rendered {
    std::vector<float> image, layers;
    std::vector<std::string> names;
    /** Layer `name` of pixel (x, y). */
    float at(const std::string& name, int x, int y) const {
        const std::size_t c =
            static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
        return layers[(static_cast<std::size_t>(y) * 48 + static_cast<std::size_t>(x)) *
                          names.size() +
                      c];
    }
};

Rendered render_at(Session& session, const std::string& scene, int64_t frame) {
    session.load_frame(scene, frame);
    session.render();
    const RenderResult& r = session.result();
    return {r.image, r.layers, r.layer_names};
}

Session layer_session() {
    RenderOptions options;
    options.threads = 2;
    options.layers = true;
    return Session({}, test::shipped_ocio(), options, test::quiet_log());
}

TEST(DeformingMesh, EachFrameReadsItsOwnFile) {
    test::TempDir dir("deform_frames");
    for (int f = 1; f <= 3; ++f) {
        const float z = 0.1f * static_cast<float>(f - 1);  // towards the camera
        write_ply(grid(2, [z](Vec3 p) { return p + Vec3(0, 0, z); }),
                  dir.file(fmt::format("plane.{:04}.ply", f)), "test");
    }
    const std::string scene = dir.file("scene.toml");
    std::ofstream(scene) << plane_scene("mesh = \"plane.####.ply\"");
    Session session = layer_session();
    for (int f : {3, 1, 2}) {
        const Rendered r = render_at(session, scene, f);
        EXPECT_NEAR(r.at("Z", 24, 24), 4.0f - 0.1f * static_cast<float>(f - 1), 1e-3f)
            << "frame " << f;
        EXPECT_TRUE(session.info().animated);
    }
    // The one-shot render (time 0) is frame_start's.
    session.load(scene);
    session.render();
    const std::vector<float>& l = session.result().layers;
    const Rendered first{{}, l, session.result().layer_names};
    EXPECT_NEAR(first.at("Z", 24, 24), 4.0f, 1e-3f);
}

TEST(DeformingMesh, AMissingFrameOrAnotherTopologyIsAClearErrorAndKeepsTheLiveScene) {
    test::TempDir dir("deform_errors");
    write_ply(grid(2, [](Vec3 p) { return p; }), dir.file("plane.0001.ply"), "test");
    write_ply(grid(3, [](Vec3 p) { return p; }), dir.file("plane.0002.ply"), "test");
    const std::string scene = dir.file("scene.toml");
    std::ofstream(scene) << plane_scene("mesh = \"plane.####.ply\"");
    Session session = layer_session();
    session.load_frame(scene, 1);
    const auto message = [&](int64_t f) {
        try {
            session.load_frame(scene, f);
        } catch (const SpangleError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string other = message(2);
    EXPECT_NE(other.find(scene + ":29:8: error:"), std::string::npos) << other;
    EXPECT_NE(other.find("plane.0002.ply"), std::string::npos) << other;
    EXPECT_NE(other.find("plane.0001.ply"), std::string::npos) << other;
    EXPECT_NE(other.find("topology"), std::string::npos) << other;
    const std::string missing = message(3);
    EXPECT_NE(missing.find(scene + ":29:8: error:"), std::string::npos) << missing;
    EXPECT_NE(missing.find("not found (looked for " + dir.file("plane.0003.ply")),
              std::string::npos)
        << missing;
    EXPECT_NEAR(session.info().time, 0.0, 0.0) << "a failed load leaves frame 1 live";
    // Without rest_mesh, frame_start's file is the rest pose: a frame whose own file is there
    // still needs it.
    std::filesystem::remove(dir.file("plane.0001.ply"));
    write_ply(grid(3, [](Vec3 p) { return p; }), dir.file("plane.0003.ply"), "test");
    const std::string no_rest = message(3);
    EXPECT_NE(no_rest.find(scene +
                           ":29:8: error: mesh file of frame_start 1 not found (looked "
                           "for " +
                           dir.file("plane.0001.ply")),
              std::string::npos)
        << no_rest;
}

TEST(DeformingMesh, EveryFramesFileIsCheckedBeforeAnyFrameRenders) {
    // --frames checks each frame's files first: a missing frame 5 failed after frames 1 to 4
    // had rendered.
    test::TempDir dir("deform_check");
    for (int f : {1, 2, 4})
        write_ply(grid(2, [](Vec3 p) { return p; }), dir.file(fmt::format("plane.{:04}.ply", f)),
                  "test");
    const std::string scene = dir.file("scene.toml");
    std::ofstream(scene) << plane_scene("mesh = \"plane.####.ply\"");
    const SceneDescription d = read_scene(scene);
    EXPECT_NO_THROW(check_sequence_files(d, 1, 2));
    try {
        check_sequence_files(d, 1, 4);
        ADD_FAILURE() << "frame 3 is missing";
    } catch (const SpangleError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find(scene + ":29:8: error: mesh file of frame 3 not found"), std::string::npos)
            << m;
    }
    // A PLY frame of another topology is found from its header before any frame renders (it
    // was found when its turn came, after the frames before it).
    write_ply(grid(2, [](Vec3 p) { return p; }), dir.file("plane.0003.ply"), "test");
    write_ply(grid(3, [](Vec3 p) { return p; }), dir.file("plane.0005.ply"), "test");
    EXPECT_NO_THROW(check_sequence_files(d, 1, 4));
    try {
        check_sequence_files(d, 1, 5);
        ADD_FAILURE() << "frame 5 has another topology";
    } catch (const SpangleError& e) {
        const std::string m = e.what();
        EXPECT_NE(
            m.find("frame 5 (" + dir.file("plane.0005.ply") + ") has 16 vertices and 18 faces"),
            std::string::npos)
            << m;
        EXPECT_NE(m.find("has 9 and 8: every frame of a deforming mesh has one topology"),
                  std::string::npos)
            << m;
    }
    // So is an OBJ frame, by a scan of its lines (found after frames 1 and 2 had rendered):
    // another count of vertices or faces, or the same counts in faces of other sizes.
    const std::string quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
    std::ofstream(dir.file("quad.1.obj")) << quad << "f 1 2 3 4\n";
    std::ofstream(dir.file("quad.2.obj")) << quad << "vt 0 0\nf 1 2 3 4\r\n# f 1 2\nf 3 4\n";
    std::ofstream(dir.file("quad.3.obj")) << quad << "f 1 2 3\n";
    std::ofstream(dir.file("quad.4.obj")) << quad << "v 2 2 0\nf 1 2 3 4\n";
    std::ofstream(scene) << plane_scene("mesh = \"quad.#.obj\"");
    const SceneDescription objs = read_scene(scene);
    EXPECT_NO_THROW(check_sequence_files(objs, 1, 2));
    const auto error = [&](int64_t last) {
        try {
            check_sequence_files(objs, 1, last);
        } catch (const SpangleError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(error(3).find("frame 3 (" + dir.file("quad.3.obj") +
                            ") has faces of 3 corners in all, " + dir.file("quad.1.obj") +
                            " of 4: every frame of a deforming mesh has one topology"),
              std::string::npos)
        << error(3);
    std::ofstream(dir.file("quad.3.obj")) << quad << "f 4 3 2 1\n";
    EXPECT_NE(error(4).find("frame 4 (" + dir.file("quad.4.obj") + ") has 5 vertices and 1 faces"),
              std::string::npos)
        << error(4);
}

TEST(DeformingMesh, ASequenceOfIdenticalFramesRendersAsThePlainMeshBitForBit) {
    test::TempDir dir("deform_identical");
    const TriangleMesh m = grid(4, [](Vec3 p) { return Vec3(p.x, p.y, 0.05f * p.x * p.y); });
    write_ply(m, dir.file("plain.ply"), "test");
    for (int f = 1; f <= 2; ++f) write_ply(m, dir.file(fmt::format("seq.{:02}.ply", f)), "test");
    std::ofstream(dir.file("plain.toml")) << plane_scene("name = \"sheet\"\nmesh = \"plain.ply\"");
    std::ofstream(dir.file("seq.toml")) << plane_scene("name = \"sheet\"\nmesh = \"seq.##.ply\"");
    std::ofstream(dir.file("rest.toml"))
        << plane_scene("name = \"sheet\"\nmesh = \"seq.##.ply\"\nrest_mesh = \"plain.ply\"");
    Session a = layer_session(), b = layer_session(), c = layer_session();
    const Rendered plain = render_at(a, dir.file("plain.toml"), 2);
    const Rendered seq = render_at(b, dir.file("seq.toml"), 2);
    const Rendered rest = render_at(c, dir.file("rest.toml"), 2);
    EXPECT_EQ(seq.image, plain.image);
    EXPECT_EQ(seq.layers, plain.layers);
    EXPECT_EQ(rest.image, plain.image);
    EXPECT_EQ(rest.layers, plain.layers);
}

TEST(RestPose, TrianglesFlatInTheRestPoseAreSaid) {
    // A rest pose whose last column of vertices lies on the one before it: the two triangles of
    // each quad between them have no area there, so flakes (laid out on the rest pose) have no
    // room on them. That was silent (a patch without glitter); now the load says how many.
    const auto rest_move = [](Vec3 p) { return p.x > 1.5f ? Vec3(0.0f, p.y, p.z) : p; };
    const TriangleMesh drawn = grid(2, [](Vec3 p) { return p; });
    const TriangleMesh flat_rest = grid(2, rest_move);
    auto mesh = std::make_shared<const TriangleMesh>(drawn);
    EXPECT_EQ(flat_in_rest_pose(*with_rest_pose(mesh, flat_rest, {})), 4u);  // 2 quads x 2
    EXPECT_EQ(flat_in_rest_pose(*mesh), 0u) << "no rest pose";
    test::TempDir dir("deform_flat_rest");
    write_ply(drawn, dir.file("plane.ply"), "test");
    write_ply(flat_rest, dir.file("rest.ply"), "test");
    std::ofstream(dir.file("s.toml"))
        << plane_scene("mesh = \"plane.ply\"\nrest_mesh = \"rest.ply\"");
    RenderOptions options;
    options.threads = 2;
    const Logger log{LogLevel::Warning};  // the session keeps a reference: it must outlive it
    Session session({}, test::shipped_ocio(), options, log);
    testing::internal::CaptureStderr();
    session.load(dir.file("s.toml"));
    const std::string said = testing::internal::GetCapturedStderr();
    EXPECT_NE(said.find("4 of the 8 triangles"), std::string::npos) << said;
    EXPECT_NE(said.find("no area in the rest pose"), std::string::npos) << said;
    EXPECT_NE(said.find("material 'glitter' lays its pattern out there"), std::string::npos)
        << said;
    // A material that lays nothing out in object space loses nothing there: not said (it was,
    // for every posed mesh: a Draco-quantised glTF skin printed it for a file without flakes).
    std::string text = plane_scene("mesh = \"plane.ply\"\nrest_mesh = \"rest.ply\"");
    const std::string flake = R"(plugin = "flake")";
    const std::size_t at = text.find(flake);
    ASSERT_NE(at, std::string::npos);
    text.replace(at, flake.size(), "plugin = \"smooth\"\nmodel = \"diffuse\"");
    const std::size_t params = text.find("params = {", at);
    text.replace(params, text.find('\n', params) - params, "params = { albedo = 0.5 }");
    std::ofstream(dir.file("plain.toml")) << text;
    Session plain({}, test::shipped_ocio(), options, log);
    testing::internal::CaptureStderr();
    plain.load(dir.file("plain.toml"));
    const std::string quiet = testing::internal::GetCapturedStderr();
    EXPECT_EQ(quiet.find("rest pose"), std::string::npos) << quiet;
}

/** The glints layer's luminance of pixel (x, y). */
float luminance(const Rendered& r, int x, int y) {
    return 0.2126f * r.at("glints.R", x, y) + 0.7152f * r.at("glints.G", x, y) +
           0.0722f * r.at("glints.B", x, y);
}

/** The sparkle of pixel (x, y): its glint luminance less the mean of its 5 x 5 neighbourhood
 *  (the broad highlight, there whatever the flakes, taken away). */
float glint(const Rendered& r, int x, int y) {
    float sum = 0.0f;
    for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx) sum += luminance(r, x + dx, y + dy);
    return luminance(r, x, y) - sum / 25.0f;
}

/** Pearson correlation of frame b's glints at (x + shift, y) with frame a's at (x, y), over the
 *  pixels where both lie inside the image. */
double glint_correlation(const Rendered& a, const Rendered& b, int shift) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = 0;
    for (int y = 4; y < 44; ++y)
        for (int x = 4; x + shift < 44; ++x) {
            const double ga = glint(a, x, y), gb = glint(b, x + shift, y);
            sa += ga;
            sb += gb;
            saa += ga * ga;
            sbb += gb * gb;
            sab += ga * gb;
            n += 1;
        }
    const double cov = sab / n - sa / n * (sb / n);
    return cov / std::sqrt((saa / n - sa / n * (sa / n)) * (sbb / n - sb / n * (sb / n)));
}

// The plane's files move it 4 pixels along x from frame 1 to frame 2 (the object stands still):
// with the rest pose (frame 1's file) the surface points keep their object-space position and
// the flakes move with the surface; the plain file of frame 2 alone puts the plane's points
// elsewhere in object space, and the flakes stay where they were in the image.
TEST(DeformingMesh, WithARestPoseTheFlakesMoveWithTheSurface) {
    test::TempDir dir("deform_rest");
    constexpr int kShift = 4;
    const float dx = kShift * kPixel;
    write_ply(grid(2, [](Vec3 p) { return p; }), dir.file("plane.1.ply"), "test");
    write_ply(grid(2, [dx](Vec3 p) { return p + Vec3(dx, 0, 0); }), dir.file("plane.2.ply"),
              "test");
    std::ofstream(dir.file("seq.toml")) << plane_scene("mesh = \"plane.#.ply\"");
    std::ofstream(dir.file("moved.toml")) << plane_scene("mesh = \"plane.2.ply\"");
    Session s = layer_session(), t = layer_session();
    const Rendered first = render_at(s, dir.file("seq.toml"), 1);
    const Rendered second = render_at(s, dir.file("seq.toml"), 2);
    const Rendered moved = render_at(t, dir.file("moved.toml"), 2);
    // Pobj is the rest position: pixel x + 4 of frame 2 shows what pixel x showed in frame 1
    // (to within the scatter of 16 jittered samples' mean, well under a quarter pixel).
    for (int y = 8; y < 40; y += 8)
        for (int x = 8; x < 40; x += 8) {
            EXPECT_NEAR(second.at("Pobj.X", x + kShift, y), first.at("Pobj.X", x, y),
                        0.25f * kPixel);
            EXPECT_NEAR(moved.at("Pobj.X", x + kShift, y), first.at("Pobj.X", x, y) + dx,
                        0.25f * kPixel);
        }
    // The glints follow: frame 2's pattern is frame 1's shifted with the surface; without the
    // rest pose it is frame 1's where it was. Independent patterns correlate about 0 (+-0.1
    // over these ~1500 pixels); the same flakes seen through differently jittered samples
    // correlate far above that.
    const double with_rest = glint_correlation(first, second, kShift);
    const double without = glint_correlation(first, moved, kShift);
    EXPECT_GT(with_rest, 0.6);
    EXPECT_LT(without, 0.2);
    EXPECT_GT(glint_correlation(first, moved, 0), 0.6) << "the flakes stayed in object space";
    EXPECT_LT(glint_correlation(first, second, 0), 0.2);
}

/** A cage of n x n quads over [-2, 2]^2 at z = 0, moved by `move`. */
template <class Move>
Cage quad_cage(int n, const Move& move) {
    const TriangleMesh m = grid(n, move);
    Cage c;
    c.positions = m.positions;
    const auto v = [n](int i, int j) { return j * (n + 1) + i; };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            c.face_sizes.push_back(4);
            c.face_vertices.insert(c.face_vertices.end(),
                                   {v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)});
        }
    return c;
}

// A cage sequence: each frame refines its own cage, and the rest cage (here frame_start's) is
// refined alike, so the object-space inputs are those of the refined rest surface.
TEST(DeformingMesh, ACageSequenceRefinesEachFrameWithItsRestPose) {
    test::TempDir dir("deform_cages");
    constexpr int kShift = 4;
    const float dx = kShift * kPixel;
    write_obj_cage(quad_cage(3, [](Vec3 p) { return p; }), dir.file("cage.1.obj"), "test");
    write_obj_cage(quad_cage(3, [dx](Vec3 p) { return p + Vec3(dx, 0, 0); }),
                   dir.file("cage.2.obj"), "test");
    write_obj_cage(quad_cage(2, [](Vec3 p) { return p; }), dir.file("cage.3.obj"), "test");
    const std::string scene = dir.file("scene.toml");
    std::ofstream(scene) << plane_scene("mesh = \"cage.#.obj\"\nsubdiv = { level = 2 }");
    Session session = layer_session();
    const Rendered first = render_at(session, scene, 1);
    const Rendered second = render_at(session, scene, 2);
    for (int y = 8; y < 40; y += 8)
        for (int x = 8; x < 40; x += 8)
            EXPECT_NEAR(second.at("Pobj.X", x + kShift, y), first.at("Pobj.X", x, y),
                        0.25f * kPixel);
    try {
        session.load_frame(scene, 3);
        FAIL() << "a cage of 4 faces passed for one of 9";
    } catch (const SpangleError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find(scene + ":29:8: error:"), std::string::npos) << what;
        EXPECT_NE(what.find("cage.3.obj"), std::string::npos) << what;
        EXPECT_NE(what.find("cage.1.obj"), std::string::npos) << what;
    }
}

TEST(DeformingMesh, ConvertWritesThePatternAndTheRestMeshBack) {
    test::TempDir dir("deform_convert");
    write_ply(grid(2, [](Vec3 p) { return p; }), dir.file("plane.0001.ply"), "test");
    write_ply(grid(2, [](Vec3 p) { return p; }), dir.file("plane.rest.ply"), "test");
    std::ofstream(dir.file("scene.toml"))
        << plane_scene("mesh = \"plane.####.ply\"\nrest_mesh = \"plane.rest.ply\"");
    write_toml_scene(read_scene(dir.file("scene.toml")), dir.file("out.toml"),
                     dir.file("out_meshes"));
    std::ifstream in(dir.file("out.toml"));
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("mesh = \"plane.####.ply\""), std::string::npos) << text;
    EXPECT_NE(text.find("rest_mesh = \"plane.rest.ply\""), std::string::npos) << text;
    const SceneDescription back = read_scene(dir.file("out.toml"));
    const auto& m = std::get<MeshFileShape>(back.objects.at(0).shape);
    EXPECT_TRUE(m.sequence);
    EXPECT_EQ(m.path, dir.file("plane.####.ply"));
    EXPECT_EQ(m.rest_path, dir.file("plane.rest.ply"));
}

}  // namespace
}  // namespace spangle::test_deforming_mesh
