// [[import]]: a scene brings in another scene file and overrides its materials by name; its own
// camera, lights and render settings win or add as documented (scene/scene_import.h).

#include <gtest/gtest.h>

#include <fstream>

#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "scene/scene_loader.h"
#include "test_support.h"

namespace spangle::test_scene_import {
namespace {

/** A small "car": a red sphere on a plane under a quad light, written in `dir`. */
void write_car(const test::TempDir& dir, const std::string& paint = "[0.8, 0.1, 0.1]",
               const std::string& offset = "0") {
    std::ofstream(dir.file("car.toml"))
        << fmt::format(R"(
[render]
width = 48
height = 32
spp = 8
seed = 3

[camera]
position = [0, 1.5, 5]
look_at = [0, 0.5, 0]
fov = 35

[environment]
color = [0.2, 0.2, 0.25]

[[material]]
name = "paint"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = {} }}

[[material]]
name = "ground"
plugin = "smooth"
model = "diffuse"

[[object]]
name = "body"
mesh = "{}/meshes/sphere.obj"
material = "paint"
translate = [{}, 0.5, 0]
scale = 0.5

[[object]]
mesh = "{}/meshes/plane.ply"
material = "ground"
translate = [{}, 0, 0]
scale = 4

[[light]]
type = "point"
position = [{}, 3, 2]
intensity = 4
)",
                       paint, test::asset_dir(), offset, test::asset_dir(), offset, offset);
}

RenderOptions quiet_options() {
    RenderOptions o;
    o.threads = 2;
    return o;
}

std::vector<float> render_file(const std::string& path) {
    FrameRequest req;
    req.scene = path;
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options = quiet_options();
    return render_frame(req).image;
}

TEST(Import, AnImportedSceneWearsTheImportingFilesMaterialOfTheSameName) {
    test::TempDir dir("import_override");
    write_car(dir);
    std::ofstream(dir.file("look.toml")) << R"(
[[import]]
file = "car.toml"

[[material]]
name = "paint"
plugin = "smooth"
model = "diffuse"
params = { albedo = [0.1, 0.2, 0.8] }
)";
    const SceneDescription d = read_scene(dir.file("look.toml"));
    ASSERT_EQ(d.objects.size(), 2u);
    ASSERT_EQ(d.materials.size(), 2u) << "the car's paint is replaced, its ground kept";
    EXPECT_EQ(d.materials[0].name, "paint");
    EXPECT_EQ(d.materials[0].loc.file, dir.file("look.toml")) << "the override";
    EXPECT_EQ(d.materials[1].name, "ground");
    EXPECT_TRUE(d.has_camera);
    EXPECT_EQ(d.camera.fov_deg, 35.0) << "the import's camera: the look has none";
    EXPECT_EQ(d.lights.size(), 1u);
    EXPECT_EQ(d.render.width, 48u) << "render settings the look does not write: the import's";
    ASSERT_EQ(d.files.size(), 1u);
    EXPECT_EQ(d.files[0], dir.file("car.toml"));

    // The look renders as the car painted blue does, bit for bit.
    test::TempDir blue("import_blue");
    write_car(blue, "[0.1, 0.2, 0.8]");
    EXPECT_EQ(render_file(dir.file("look.toml")), render_file(blue.file("car.toml")));
}

TEST(Import, ThePlacementMovesEverythingImportedAndOwnSettingsWin) {
    test::TempDir dir("import_placed");
    write_car(dir);
    std::ofstream(dir.file("look.toml")) << R"(
[render]
spp = 4

[[import]]
file = "car.toml"
translate = [1, 0, 0]
camera = false

[camera]
position = [0, 1.5, 5]
look_at = [0, 0.5, 0]
fov = 35
)";
    const SceneDescription d = read_scene(dir.file("look.toml"));
    EXPECT_EQ(d.render.spp, 4u) << "written by the look";
    EXPECT_EQ(d.render.width, 48u) << "not written: the import's";
    EXPECT_EQ(d.render.seed, 3u);
    // Moved 1 m along x: the same as the car written there (the camera stays).
    test::TempDir moved("import_moved");
    write_car(moved, "[0.8, 0.1, 0.1]", "1");
    std::ofstream(moved.file("spp4.toml")) << R"(
[render]
spp = 4

[[import]]
file = "car.toml"
)";
    EXPECT_EQ(render_file(dir.file("look.toml")), render_file(moved.file("spp4.toml")));
}

TEST(Import, AFileThatImportsItselfIsRefusedAtTheImport) {
    test::TempDir dir("import_cycle");
    std::ofstream(dir.file("a.toml")) << "[[import]]\nfile = \"b.toml\"\n";
    std::ofstream(dir.file("b.toml")) << "\n[[import]]\nfile = \"a.toml\"\n";
    try {
        read_scene(dir.file("a.toml"));
        FAIL() << "an import cycle was read";
    } catch (const SpangleError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("b.toml:2:1: error: "), std::string::npos) << what;
        EXPECT_NE(what.find("a.toml' imports itself (through "), std::string::npos) << what;
    }
    // No camera anywhere: the importing file is missing it.
    std::ofstream(dir.file("c.toml")) << "[[import]]\nfile = \"d.toml\"\n";
    std::ofstream(dir.file("d.toml")) << "[render]\nspp = 1\n";
    EXPECT_THROW(read_scene(dir.file("d.toml")), SpangleError);
    try {
        read_scene(dir.file("c.toml"));
        FAIL() << "a scene without a camera was read";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("missing required key 'camera'"), std::string::npos)
            << e.what();
    }
}

TEST(Import, AnImportedFileNeedsNoCameraOfItsOwn) {
    // A model file (materials and objects only) imported into a look file with the camera: as
    // docs/import.md says (it failed: "car.toml: the scene is missing required key 'camera'").
    test::TempDir dir("import_no_camera");
    std::ofstream(dir.file("model.toml")) << fmt::format(
        "[[material]]\nname = \"paint\"\nplugin = \"smooth\"\nmodel = \"diffuse\"\n\n"
        "[[object]]\nmesh = \"{}/meshes/sphere.obj\"\nmaterial = \"paint\"\n",
        test::asset_dir());
    std::ofstream(dir.file("look.toml"))
        << "[render]\nwidth = 16\nheight = 12\nspp = 1\n\n[camera]\nposition = [0, 0, 5]\n"
           "look_at = [0, 0, 0]\n\n[environment]\ncolor = [1, 1, 1]\n\n[[import]]\nfile = "
           "\"model.toml\"\n";
    const SceneDescription d = read_scene(dir.file("look.toml"));
    EXPECT_EQ(d.objects.size(), 1u);
    EXPECT_EQ(d.camera.position.z, 5.0f);
    EXPECT_EQ(render_file(dir.file("look.toml")).size(), 16u * 12u * 3u);
    // Read alone, the model file still needs its camera.
    EXPECT_THROW(read_scene(dir.file("model.toml")), SpangleError);
}

TEST(Import, AWatchSessionWatchesTheImportedFiles) {
    test::TempDir dir("import_watch");
    write_car(dir);
    std::ofstream(dir.file("look.toml")) << "[[import]]\nfile = \"car.toml\"\n";
    Session session({}, test::shipped_ocio(), quiet_options(), test::quiet_log());
    session.load(dir.file("look.toml"));
    const std::vector<std::string> files = session.watched_files();
    EXPECT_NE(std::find(files.begin(), files.end(), dir.file("car.toml")), files.end());
    // An edit of the imported file reaches the scene.
    write_car(dir, "[0.1, 0.8, 0.1]");
    const ReloadReport rep = session.load(dir.file("look.toml"));
    EXPECT_EQ(rep.changed, std::vector<std::string>{"Material"});
}

}  // namespace
}  // namespace spangle::test_scene_import
