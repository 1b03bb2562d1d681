// Scene readers apart from the builder: the TOML reader describes a file as written, with the
// place of everything it records; the builder turns a description made by hand (no file) into
// the registry the TOML of the same scene loads; keyframes become the camera's and the objects'
// motion steps through one routine; load_scene picks the reader by the file's extension.

#include <gtest/gtest.h>

#include <fstream>

#include "scene/keyed_motion.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "scene/toml_scene_reader.h"
#include "test_support.h"

namespace spangle::test_scene_builder {
namespace {

/** A small scene using every kind of element; MESH stands for the mesh's path. */
constexpr const char* kScene = R"([render]
width = 32
height = 24
color_space = "srgb_texture"
fps = 2
shutter = [0, 1]

[camera]
position = [0, 1, 5]
look_at = [0, 0, 0]
interpolation = "linear"

[[camera.keys]]
frame = 1

[[camera.keys]]
frame = 3
position = [1, 1, 5]

[environment]
color = [0.1, 0.2, 0.3]
light_group = "sky"

[[material]]
name = "red"
plugin = "smooth"
model = "diffuse"
params = { albedo = { rgb = [0.8, 0.1, 0.1], space = "lin_rec709" }, roughness = 0.5 }

[[object]]
name = "ball"
mesh = "MESH"
material = "red"
scale = 2
translate = [0, 1, 0]
emission = [1, 1, 1]
emission_intensity = 3

[[light]]
type = "sphere"
center = [0, 4, 0]
radius = 0.5
color = [1, 0.5, 0.25]
light_group = "key"
)";

/** The mesh the scene names (any mesh file will do: load_scene only finds it). */
std::string mesh_path() {
    return test::test_dir() + "/scenes_bad/meshes/ok.obj";
}

/** kScene written to `dir`; its path. */
std::string write_scene(const test::TempDir& dir) {
    std::string text = kScene;
    test::replace_all(text, "MESH", mesh_path());
    const std::string path = dir.file("scene.toml");
    std::ofstream(path) << text;
    return path;
}

/** Expects `at` to be line:column of `file`. */
void expect_at(const FileLoc& at, const std::string& file, int line, int column) {
    EXPECT_EQ(at.file, file);
    EXPECT_EQ(at.line, line) << at.str();
    EXPECT_EQ(at.column, column) << at.str();
}

TEST(SceneReader, TomlDescribesTheFileAsWrittenWithLocations) {
    const test::TempDir dir("scene_reader");
    const std::string path = write_scene(dir);
    const SceneDescription d = read_toml_scene(path);
    EXPECT_EQ(d.path, path);
    EXPECT_EQ(d.render.width, 32u);
    EXPECT_EQ(d.render.spp, 16u) << "not written: the default";
    EXPECT_EQ(d.render.color_space, "srgb_texture");
    expect_at(d.render.color_space_loc, path, 4, 15);
    EXPECT_FALSE(d.render.working_space) << "not written: the builder decides";
    EXPECT_EQ(d.render.shutter_close, 1.0);

    ASSERT_EQ(d.camera.keys.keys.size(), 2u);
    EXPECT_FALSE(d.camera.keys.smooth);
    const CameraKey& key = d.camera.keys.keys[1];
    EXPECT_EQ(key.time.frame, 3) << "kept as a frame: the builder converts";
    EXPECT_EQ(key.position, Vec3(1, 1, 5));
    EXPECT_FALSE(key.look_at) << "not written: the camera's own, filled in by the builder";
    EXPECT_EQ(key.what, "[[camera.keys]] #2");
    expect_at(key.loc, path, 16, 1);
    EXPECT_FALSE(d.camera.focus_distance);

    ASSERT_TRUE(d.environment && d.environment->color);
    EXPECT_EQ(d.environment->color->rgb, Vec3(0.1f, 0.2f, 0.3f)) << "the numbers as written";
    EXPECT_FALSE(d.environment->color->space) << "bare";
    expect_at(d.environment->color->loc, path, 21, 9);
    EXPECT_EQ(d.environment->group.name, "sky");

    ASSERT_EQ(d.materials.size(), 1u);
    const MaterialDesc& m = d.materials[0];
    expect_at(m.name_loc, path, 25, 8);
    ASSERT_EQ(m.params.size(), 2u);
    EXPECT_EQ(m.params[0].kind, ParamDesc::Kind::Color);
    EXPECT_EQ(m.params[0].color.space, "lin_rec709");
    expect_at(m.params[0].color.space_loc, path, 28, 54);
    EXPECT_EQ(m.params[1].kind, ParamDesc::Kind::Number);
    EXPECT_EQ(m.params[1].number, 0.5);
    expect_at(m.params[1].key_loc, path, 28, 70);

    ASSERT_EQ(d.objects.size(), 1u);
    const ObjectDesc& o = d.objects[0];
    EXPECT_EQ(o.what, "[[object]] #1 'ball'");
    ASSERT_TRUE(std::holds_alternative<MeshFileShape>(o.shape));
    EXPECT_EQ(std::get<MeshFileShape>(o.shape).path, mesh_path());
    EXPECT_EQ(o.material, "red");
    expect_at(o.material_loc, path, 33, 12);
    EXPECT_EQ(o.placement.parts.scale, Vec3(2, 2, 2));
    ASSERT_TRUE(o.emission);
    EXPECT_EQ(o.emission->intensity, 3.0);
    EXPECT_EQ(o.emission->group.name, "default") << "not written";

    ASSERT_EQ(d.lights.size(), 1u);
    ASSERT_TRUE(std::holds_alternative<SphereLightDesc>(d.lights[0].shape));
    EXPECT_EQ(std::get<SphereLightDesc>(d.lights[0].shape).radius, 0.5);
    expect_at(d.lights[0].group.loc, path, 44, 15);
}

/** A colour written bare. */
ColorDesc bare(Vec3 rgb) {
    ColorDesc c;
    c.rgb = rgb;
    return c;
}

/** kScene, made by hand. */
SceneDescription hand_made_scene() {
    SceneDescription d;
    d.path = "hand-made";
    d.render.width = 32;
    d.render.height = 24;
    d.render.color_space = "srgb_texture";
    d.render.fps = 2;
    d.render.shutter_close = 1;
    d.camera.position = {0, 1, 5};
    d.camera.look_at = {0, 0, 0};
    d.camera.keys.smooth = false;
    CameraKey first, second;
    first.time.frame = 1;
    second.time.frame = 3;
    second.position = Vec3(1, 1, 5);
    d.camera.keys.keys = {first, second};
    EnvironmentDesc env;
    env.color = bare({0.1f, 0.2f, 0.3f});
    env.group.name = "sky";
    d.environment = env;
    MaterialDesc m;
    m.name = "red";
    m.plugin = "smooth";
    m.model = "diffuse";
    ParamDesc albedo, roughness;
    albedo.name = "albedo";
    albedo.kind = ParamDesc::Kind::Color;
    albedo.color = bare({0.8f, 0.1f, 0.1f});
    albedo.color.space = "lin_rec709";
    roughness.name = "roughness";
    roughness.number = 0.5;
    m.params = {albedo, roughness};
    d.materials = {m};
    ObjectDesc o;
    o.name = "ball";
    o.shape = MeshFileShape{mesh_path(), {}, false, {}, {}};
    o.material = "red";
    o.placement.parts.scale = Vec3(2);
    o.placement.parts.translate = {0, 1, 0};
    o.emission = EmissionDesc{};
    o.emission->color = bare({1, 1, 1});
    o.emission->intensity = 3.0;
    d.objects = {o};
    LightDesc l;
    l.shape = SphereLightDesc{{0, 4, 0}, 0.5};
    l.color = bare({1, 0.5f, 0.25f});
    l.group.name = "key";
    d.lights = {l};
    return d;
}

TEST(SceneBuilder, AHandMadeDescriptionBuildsTheRegistryOfItsToml) {
    const test::TempDir dir("scene_builder");
    ColorConfig from_file_color = test::shipped_config();
    ColorConfig by_hand_color = test::shipped_config();
    ecs::Registry from_file, by_hand;
    const SceneInfo a = load_scene(write_scene(dir), from_file_color, from_file, 0.0);
    const SceneInfo b = build_scene(hand_made_scene(), by_hand_color, by_hand, 0.0);
    // Same entities in the same order with the same values in every pool (where a value is
    // written does not count, as for hot reload's diff).
    EXPECT_EQ(ecs::Registry::changed_types(from_file, by_hand, {}), std::vector<std::string>{});
    EXPECT_EQ(from_file.live_count(), by_hand.live_count());
    EXPECT_EQ(by_hand.count<CameraMotion>(), 1u) << "the camera moves while the shutter is open";
    EXPECT_EQ(by_hand.count<Emission>(), 1u);
    EXPECT_EQ(a.working_space, b.working_space);
    EXPECT_EQ(a.color_space, b.color_space);
    EXPECT_EQ(a.material_names, b.material_names);
    EXPECT_EQ(a.light_groups, (std::vector<std::string>{"sky", "default", "key"}));
    EXPECT_EQ(a.light_groups, b.light_groups);
    EXPECT_TRUE(Camera::same(a.camera, b.camera));
    EXPECT_EQ(a.object_to_world, b.object_to_world);
    EXPECT_EQ(a.animated, b.animated);
    EXPECT_EQ(a.motion_blur, b.motion_blur);
    EXPECT_EQ(a.notes, b.notes);
}

/** The notes building `d` gives, a line each. */
std::string notes_of(const SceneDescription& d) {
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    std::string all;
    for (const std::string& n : build_scene(d, color, registry, 0.0).notes) all += n + "\n";
    return all;
}

TEST(SceneBuilder, ASceneWithNoObjectsIsSaid) {
    // Nothing to see at all was not said; an environment alone is a panorama, on purpose.
    SceneDescription d = hand_made_scene();
    ASSERT_FALSE(d.objects.empty());
    EXPECT_EQ(notes_of(d).find("no objects"), std::string::npos) << notes_of(d);
    d.objects.clear();
    EXPECT_EQ(notes_of(d).find("no objects"), std::string::npos)
        << "a panorama of the environment, on purpose: " << notes_of(d);
    d.environment.reset();
    EXPECT_NE(notes_of(d).find("hand-made: the scene has no objects and no environment"),
              std::string::npos)
        << notes_of(d);
}

TEST(SceneBuilder, ACameraInsideASphereLightIsSaid) {
    // It emits outward: from within it is black and lights nothing.
    SceneDescription d = hand_made_scene();
    ASSERT_TRUE(std::holds_alternative<SphereLightDesc>(d.lights[0].shape));
    EXPECT_EQ(notes_of(d).find("inside this sphere light"), std::string::npos) << notes_of(d);
    std::get<SphereLightDesc>(d.lights[0].shape).radius = 10.0;  // around the camera, 5.8 away
    EXPECT_NE(notes_of(d).find("the camera is inside this sphere light, which emits outward"),
              std::string::npos)
        << notes_of(d);
}

TEST(SceneBuilder, ObjectsOfOneNameAreSaid) {
    // Found by a user: two objects named alike merged into one Cryptomatte matte without a word.
    SceneDescription d = hand_made_scene();
    ASSERT_FALSE(d.objects.empty());
    EXPECT_EQ(notes_of(d).find("share"), std::string::npos) << notes_of(d);
    d.objects[0].name = "twin";
    d.objects[0].loc = FileLoc{"hand-made", 3, 1};
    d.objects.push_back(d.objects[0]);
    d.objects.back().loc = FileLoc{"hand-made", 9, 1};
    d.objects.push_back(d.objects[0]);
    d.objects.back().name = "";  // unnamed ones are named by the reader, not alike
    EXPECT_NE(notes_of(d).find("hand-made: 1 object shares a name with an earlier one ('twin' at "
                               "hand-made:3:1 and hand-made:9:1)"),
              std::string::npos)
        << notes_of(d);
}

TEST(SceneBuilder, ErrorsPointWhereTheDescriptionSaysAndAMatrixPlacesAnObject) {
    SceneDescription d = hand_made_scene();
    d.objects[0].material = "gold";
    d.objects[0].material_loc = {"hand.scene", 7, 3};
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    try {
        build_scene(d, color, registry);
        FAIL() << "an unknown material built";
    } catch (const SpangleError& e) {
        EXPECT_STREQ(e.what(), "hand.scene:7:3: error: unknown material 'gold' (defined: red)");
    }

    d = hand_made_scene();
    Affine m = Affine::translate({1, 2, 3});
    m.m[0][1] = 0.5f;  // a shear: no scale, rotate, translate gives it
    d.objects[0].placement.matrix = m;
    ecs::Registry placed;
    const SceneInfo info = build_scene(d, color, placed);
    ASSERT_EQ(info.object_to_world.size(), 1u);
    EXPECT_EQ(info.object_to_world[0], m);

    d.objects[0].shape = InlineMeshShape{nullptr, {"hand.scene", 9, 1}};
    ecs::Registry no_mesh;
    try {
        build_scene(d, color, no_mesh);
        FAIL() << "an inline shape without a mesh built";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("hand.scene:9:1: error: "), std::string::npos)
            << e.what();
    }
    auto mesh = std::make_shared<TriangleMesh>();
    mesh->positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    mesh->indices = {0, 1, 2};
    d.objects[0].shape = InlineMeshShape{mesh, {"hand.scene", 9, 1}};
    ecs::Registry inline_mesh;
    build_scene(d, color, inline_mesh);
    ASSERT_EQ(inline_mesh.count<InlineMesh>(), 1u);
    const InlineMesh built = inline_mesh.pool<InlineMesh>().columns().get(0);
    EXPECT_EQ(built.mesh.get(), mesh.get());
    EXPECT_EQ(built.content, mesh_content_hash(*mesh));
}

/** The camera of a track of (x of the eye, fov). */
Camera camera_of(const std::vector<double>& v) {
    Camera c;
    c.position = {static_cast<float>(v[0]), 0, 5};
    c.up = {0, 1, 0};
    c.fov_deg = static_cast<float>(v[1]);
    return c;
}

TEST(KeyedMotion, OneRoutineGivesTheCamerasAndTheObjectsSteps) {
    Track track;
    track.smooth = false;
    track.times = {0.0, 1.0};
    track.values = {{-1.0, 40.0}, {1.0, 40.0}};
    const Shutter open = frame_shutter(0.0, 1.0, 0.0, 1.0);
    const auto camera = [](const std::vector<double>& v, double) { return camera_of(v); };
    const KeyedMotion<Camera> slide = keyed_motion<Camera>(track, open, camera);
    EXPECT_EQ(slide.middle.position.x, 0.0f) << "at the shutter's middle";
    ASSERT_EQ(slide.steps.size(), 2u) << "a straight slide is one segment";
    EXPECT_EQ(slide.steps.front().position.x, -1.0f);
    EXPECT_EQ(slide.steps.back().position.x, 1.0f);

    // A turn of 90 degrees is cut into segments of about 2.5 degrees or less: 64 of them.
    Track turn;
    turn.smooth = false;
    turn.times = {0.0, 1.0};
    turn.values = {{0.0}, {90.0}};
    const auto placement = [](const std::vector<double>& v, double) {
        return Affine::rotate(static_cast<float>(v[0]), {0, 1, 0});
    };
    const KeyedMotion<Affine> turning = keyed_motion<Affine>(turn, open, placement);
    ASSERT_EQ(turning.steps.size(), static_cast<std::size_t>(kMaxMotionSegments) + 1);
    for (std::size_t k = 0; k < turning.steps.size(); ++k)
        EXPECT_EQ(turning.steps[k], placement({90.0 * static_cast<double>(k) / 64.0}, 0.0))
            << "step " << k << " is the placement at its time";

    // Nothing blurs with the shutter shut, nor when nothing moves while it is open.
    const KeyedMotion<Affine> shut =
        keyed_motion<Affine>(turn, frame_shutter(0.5, 1.0, 0.0, 0.0), placement);
    EXPECT_TRUE(shut.steps.empty());
    EXPECT_EQ(shut.middle, placement({45.0}, 0.0));
    track.values = {{1.0, 40.0}, {1.0, 40.0}};
    EXPECT_TRUE(keyed_motion<Camera>(track, open, camera).steps.empty());
}

TEST(KeyedMotion, KeysInFramesAreInSecondsOfTheFrameRange) {
    KeyTime t;
    t.frame = 13;
    EXPECT_EQ(key_seconds(t, 1, 24.0), 0.5);
    t.frame.reset();
    t.seconds = 2.25;
    EXPECT_EQ(key_seconds(t, 1, 24.0), 2.25);
}

TEST(SceneLoader, PicksTheReaderByTheFilesExtension) {
    EXPECT_STREQ(scene_format_for("a/scene.toml").name, "TOML");
    EXPECT_STREQ(scene_format_for("a/SCENE.TOML").name, "TOML");
    EXPECT_STREQ(scene_format_for("a/scene.txt").name, "TOML") << "as scenes were always read";
    for (const SceneFormat& f : scene_formats()) EXPECT_NE(f.read, nullptr) << f.extension;
}

TEST(SceneLoader, AMeshOrAnotherProgramsSceneIsNamedAsSuch) {
    // Read as TOML, an OBJ given to `spangle render` failed with "invalid TOML: expected '='"
    // at its first line.
    const test::TempDir dir("scene_loader");
    const auto message = [&](const std::string& name) {
        const std::string path = dir.file(name);
        std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        try {
            read_scene(path);
        } catch (const SpangleError& e) {
            return std::string(e.what());
        }
        return std::string("read");
    };
    EXPECT_NE(message("car.obj").find("this is a mesh (obj), not a scene: `spangle new --mesh"),
              std::string::npos)
        << message("car.obj");
    EXPECT_NE(message("car.PLY").find("this is a mesh (ply), not a scene"), std::string::npos);
    EXPECT_NE(message("car.fbx").find("Spangle does not read fbx files"), std::string::npos);
    // STL is not a mesh Spangle reads either (spangle new and `mesh` refuse it); a .ply.gz is.
    EXPECT_NE(message("car.stl").find("Spangle does not read stl files"), std::string::npos);
    EXPECT_NE(message("car.ply.gz").find("this is a mesh (ply.gz), not a scene"),
              std::string::npos);
    EXPECT_NE(message("car.txt").find("invalid TOML"), std::string::npos)
        << "other names are read as TOML, as always";
}

}  // namespace
}  // namespace spangle::test_scene_builder

namespace spangle {
namespace {

MatrixKey matrix_key(double seconds, const Affine& m) {
    MatrixKey k;
    k.time.seconds = seconds;
    k.matrix = m;
    k.what = "a key";
    return k;
}

float largest_difference(const Affine& a, const Affine& b) {
    float d = length(a.t - b.t);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) d = std::max(d, std::fabs(a.m[i][j] - b.m[i][j]));
    return d;
}

TEST(KeyedMotion, MatrixKeysTurnAlongTheShorterArcAndKeepTheirStretch) {
    // Keys as whole matrices (pbrt's ActiveTransform, glTF's animations): a placement turning
    // 90 degrees about y while it doubles in x and slides, and a mirrored one. Halfway, the
    // turn is 45 degrees (slerp), the stretch and the slide halfway; at the keys, the keys.
    const auto place = [](float deg, float sx, float tx, float mirror) {
        return Affine::translate({tx, 0, 0})
            .compose(Affine::rotate(deg, {0, 1, 0}))
            .compose(Affine::scale({sx * mirror, 1, 1}));
    };
    for (const float mirror : {1.0f, -1.0f}) {
        const Affine a = place(0, 1, 0, mirror), b = place(90, 2, 4, mirror);
        const DecomposedAffine da = decompose(a), db = decompose(b);
        EXPECT_LT(largest_difference(interpolate(da, db, 0.0), a), 1e-5f);
        EXPECT_LT(largest_difference(interpolate(da, db, 1.0), b), 1e-5f);
        EXPECT_LT(largest_difference(interpolate(da, db, 0.5), place(45, 1.5f, 2, mirror)), 1e-5f)
            << "mirror " << mirror;
        Keys<MatrixKey> keys;
        keys.keys.push_back(matrix_key(0.0, a));
        keys.keys.push_back(matrix_key(1.0, b));
        const KeyedMotion<Affine> m =
            matrix_motion(keys, 1, 24.0, frame_shutter(0.5, 1.0, -0.5, 0.5));
        EXPECT_LT(largest_difference(m.middle, place(45, 1.5f, 2, mirror)), 1e-5f);
        ASSERT_GE(m.steps.size(), 2u);
        EXPECT_EQ(m.steps.front(), a) << "the shutter opens at the first key: that key";
        EXPECT_EQ(m.steps.back(), b);
        // The steps follow the turn: every step is the placement at its time.
        for (std::size_t i = 0; i < m.steps.size(); ++i) {
            const float f = static_cast<float>(i) / static_cast<float>(m.steps.size() - 1);
            EXPECT_LT(largest_difference(m.steps[i], place(90 * f, 1 + f, 4 * f, mirror)), 1e-4f)
                << "step " << i;
        }
    }
    Keys<MatrixKey> flat;
    flat.keys.push_back(matrix_key(0.0, Affine::scale({1, 0, 1})));
    EXPECT_THROW(matrix_motion(flat, 1, 24.0, frame_shutter(0.0, 24.0, 0, 0)), SpangleError);
}

}  // namespace
}  // namespace spangle
