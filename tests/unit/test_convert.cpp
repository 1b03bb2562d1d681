// `spangle convert`: a scene read from any format, written as TOML (scene/toml_scene_writer.h),
// reads back as a scene that renders the same image bit for bit: every setting, colour,
// placement, key and material survives, and the meshes a scene held itself become PLY files.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "geometry/mesh_load.h"
#include "pipeline/session.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "scene/toml_scene_writer.h"
#include "test_support.h"

namespace spangle::test_convert {
namespace {

namespace fs = std::filesystem;

/** Small, quick renders: the same options for a scene and its converted twin. */
RenderOptions small_options() {
    RenderOptions o;
    o.threads = 2;
    o.spp_override = 2;
    o.width_override = 40;
    o.height_override = 24;
    return o;
}

std::vector<float> render_path(const std::string& path) {
    Session s({}, test::shipped_ocio(), small_options(), test::quiet_log());
    s.load(path);
    s.render();
    return s.result().image;
}

std::vector<float> render_description(const SceneDescription& d) {
    Session s({}, test::shipped_ocio(), small_options(), test::quiet_log());
    s.load(d);
    s.render();
    return s.result().image;
}

std::string read_text(const std::string& path) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

TEST(Convert, ShippedScenesReadBackAsScenesThatRenderTheSameBitForBit) {
    // The shipped scenes between them use every TOML feature the writer has to say again:
    // subdivision, flakes, textures and uv transforms, camera and object
    // keys over a shutter, light groups, delta lights, environment maps, uv-less meshes.
    const std::vector<std::string> scenes = {
        test::asset_dir() + "/scenes/demo.toml",
        test::asset_dir() + "/scenes/materials.toml",
        test::test_dir() + "/scenes/textured.toml",
        test::test_dir() + "/scenes/motion_blur.toml",
        test::test_dir() + "/scenes/moving_camera.toml",
        test::test_dir() + "/scenes/delta_hard_cases.toml",
        test::test_dir() + "/scenes/subdiv_near_far.toml",
        test::test_dir() + "/scenes/flake_uvless.toml",
        test::test_dir() + "/scenes/uvless_uv_layout.toml",
    };
    test::TempDir dir("convert_shipped");
    for (const std::string& scene : scenes) {
        SCOPED_TRACE(scene);
        const std::string out = dir.file("converted.toml");
        const SceneWriteReport rep =
            write_toml_scene(read_scene(scene), out, dir.file("converted_meshes"));
        EXPECT_TRUE(rep.meshes.empty());  // every mesh of a TOML scene is a file already
        EXPECT_EQ(render_path(out), render_path(scene));
    }
}

TEST(Convert, InlineMeshesBecomePlyFilesOnePerMeshAndRenderTheSame) {
    // As a pbrt or glTF scene holds them: triangles in the scene, two objects sharing one.
    const std::string file = test::test_dir() + "/scenes/small_lit.toml";
    SceneDescription d = read_scene(file);
    std::shared_ptr<const TriangleMesh> first;
    std::size_t inline_objects = 0;
    for (ObjectDesc& o : d.objects)
        if (const auto* m = std::get_if<MeshFileShape>(&o.shape)) {
            auto mesh = std::make_shared<const TriangleMesh>(load_mesh(m->path, m->loc));
            if (!first) first = mesh;
            o.shape = InlineMeshShape{inline_objects == 1 ? first : mesh, m->loc};
            ++inline_objects;
        }
    ASSERT_GE(inline_objects, 3u);  // the second object shares the first one's mesh

    test::TempDir dir("convert_inline");
    const SceneWriteReport rep =
        write_toml_scene(d, dir.file("scene.toml"), dir.file("scene_meshes"));
    EXPECT_EQ(rep.meshes.size(), inline_objects - 1);
    for (const std::string& ply : rep.meshes) EXPECT_TRUE(fs::exists(ply)) << ply;
    const std::string text = read_text(dir.file("scene.toml"));
    EXPECT_NE(text.find("mesh = \"scene_meshes/mesh_000.ply\""), std::string::npos) << text;
    EXPECT_EQ(render_path(dir.file("scene.toml")), render_description(d));
    // Each object keeps the name it renders under (its Cryptomatte id): an unnamed inline mesh
    // went by "object2" and came back as "mesh_000", its PLY file's name.
    const SceneDescription back = read_scene(dir.file("scene.toml"));
    ASSERT_EQ(back.objects.size(), d.objects.size());
    for (uint32_t i = 0; i < d.objects.size(); ++i)
        EXPECT_EQ(object_name(back.objects[i], i), object_name(d.objects[i], i)) << i;
}

TEST(Convert, ATexturesWrapPerAxisIsReadAndWrittenBack) {
    // wrap = [s, t] (glTF's wrapS and wrapT, which differed and were taken as one).
    test::TempDir dir("convert_wrap");
    // The scene with the albedo's texture wrapped as `wrap` says.
    const auto write = [&](const std::string& file, const std::string& wrap) {
        std::ofstream(dir.file(file)) << fmt::format(R"(
[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
[[material]]
name = "m"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = {{ texture = "{0}/scenes/textures/roughness_ramp.png", wrap = {2} }} }}
[[object]]
mesh = "{1}/meshes/sphere.obj"
material = "m"
)",
                                                     test::test_dir(), test::asset_dir(), wrap);
    };
    write("s.toml", R"(["clamp", "mirror"])");
    const auto wrap_of = [](const SceneDescription& d) {
        const ParamDesc& p = d.materials.at(0).params.at(0);
        return std::pair{p.texture.wrap, p.texture.wrap_t};
    };
    const SceneDescription d = read_scene(dir.file("s.toml"));
    EXPECT_EQ(wrap_of(d), (std::pair{1, 3}));
    write_toml_scene(d, dir.file("back.toml"), dir.file("meshes"));
    EXPECT_EQ(wrap_of(read_scene(dir.file("back.toml"))), (std::pair{1, 3}));
    // A wrong mode in the array is an error at the key.
    write("bad.toml", R"(["clamp", "tile"])");
    try {
        read_scene(dir.file("bad.toml"));
        ADD_FAILURE() << "no error";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("got \"tile\""), std::string::npos) << e.what();
    }
}

TEST(Convert, APixelFiltersRadiusIsReadWrittenBackAndGoesWithItsFilterOnImport) {
    test::TempDir dir("convert_filter_radius");
    std::ofstream(dir.file("s.toml")) << R"([render]
filter = "blackman-harris"
filter_radius = 1.5
[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
)";
    const SceneDescription d = read_scene(dir.file("s.toml"));
    EXPECT_EQ(d.render.filter, FilterKind::BlackmanHarris);
    EXPECT_EQ(d.render.filter_radius, 1.5f);
    write_toml_scene(d, dir.file("back.toml"), dir.file("meshes"));
    EXPECT_EQ(read_scene(dir.file("back.toml")).render.filter_radius, 1.5f);
    // Importing it: the importer's own filter without a radius takes that filter's own radius
    // (0), not the imported Blackman-Harris's 1.5; a radius it writes is kept.
    std::ofstream(dir.file("box.toml"))
        << "[render]\nfilter = \"box\"\n[[import]]\nfile = \"s.toml\"\n";
    const SceneDescription box = read_scene(dir.file("box.toml"));
    EXPECT_EQ(box.render.filter, FilterKind::Box);
    EXPECT_EQ(box.render.filter_radius, 0.0f);
    std::ofstream(dir.file("wide.toml"))
        << "[render]\nfilter_radius = 2\n[[import]]\nfile = \"s.toml\"\n";
    const SceneDescription wide = read_scene(dir.file("wide.toml"));
    EXPECT_EQ(wide.render.filter, FilterKind::BlackmanHarris);
    EXPECT_EQ(wide.render.filter_radius, 2.0f);
    std::ofstream(dir.file("plain.toml")) << "[[import]]\nfile = \"s.toml\"\n";
    EXPECT_EQ(read_scene(dir.file("plain.toml")).render.filter_radius, 1.5f);
}

TEST(Convert, AnImportingSceneIsWrittenWholeWithItsOverrides) {
    test::TempDir dir("convert_import");
    std::ofstream(dir.file("car.toml")) << fmt::format(R"(
[render]
width = 48
height = 32
[camera]
position = [0, 1.5, 5]
look_at = [0, 0.5, 0]
[[material]]
name = "paint"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0.8, 0.1, 0.1] }}
[[object]]
mesh = "{0}/meshes/sphere.obj"
material = "paint"
translate = [0, 0.5, 0]
scale = 0.5
[[light]]
type = "point"
position = [0, 3, 2]
intensity = 4
)",
                                                       test::asset_dir());
    std::ofstream(dir.file("shot.toml")) << R"(
[[import]]
file = "car.toml"
rotate = [0, 30, 0]
[[material]]
name = "paint"
plugin = "smooth"
model = "plastic"
params = { albedo = [0.1, 0.2, 0.7], roughness = 0.2 }
)";
    const SceneDescription shot = read_scene(dir.file("shot.toml"));
    const std::string out = dir.file("out/shot_whole.toml");
    fs::create_directories(dir.file("out"));
    write_toml_scene(shot, out, dir.file("out/meshes"));
    const std::string text = read_text(out);
    EXPECT_EQ(text.find("[[import]]"), std::string::npos);
    EXPECT_NE(text.find("\"plastic\""), std::string::npos);
    EXPECT_EQ(text.find("\"diffuse\""), std::string::npos);  // the override replaced it
    EXPECT_EQ(render_path(out), render_path(dir.file("shot.toml")));
}

TEST(Convert, NumbersAreWrittenWithTheFewestDigitsThatReadBackExactly) {
    test::TempDir dir("convert_numbers");
    const std::string scene = test::test_dir() + "/scenes/motion_blur.toml";
    write_toml_scene(read_scene(scene), dir.file("m.toml"), dir.file("m_meshes"));
    const std::string text = read_text(dir.file("m.toml"));
    EXPECT_NE(text.find("[0.8, 0.15, 0.1]"), std::string::npos) << text;  // floats, not doubles
    EXPECT_EQ(text.find("0.800000011920929"), std::string::npos);
}

TEST(Convert, AnEnvironmentFromTheCommandLineReplacesTheScenesAndIsWrittenOut) {
    // --env (SceneReadOptions::environment) lights the scene with a map instead of its own
    // environment; the converted scene names that map and renders the same.
    const std::string scene = test::test_dir() + "/scenes/small_lit.toml";
    const std::string map = test::asset_dir() + "/env/studio.exr";
    SceneReadOptions with_env;
    with_env.environment = map;
    const SceneDescription d = read_scene(scene, with_env);
    ASSERT_TRUE(d.environment && d.environment->map);
    EXPECT_EQ(d.environment->map->path, map);
    EXPECT_FALSE(d.environment->color);
    test::TempDir dir("convert_env");
    write_toml_scene(d, dir.file("lit.toml"), dir.file("lit_meshes"));
    EXPECT_NE(read_text(dir.file("lit.toml")).find(map), std::string::npos);
    const std::vector<float> lit = render_path(dir.file("lit.toml"));
    EXPECT_EQ(lit, render_description(d));
    EXPECT_NE(lit, render_path(scene));  // the map, not the scene's own sky, lights it
}

TEST(Convert, APbrtSceneKeepsWhatOnlyPbrtSaysAndRendersTheSameBitForBit) {
    // pbrt's left-handed camera (mirror), its screen window and crop window, a z-up map in the
    // light's frame, a two-sided area light and a loopsubdiv cage written in the file (an OBJ
    // cage beside the TOML).
    test::TempDir dir("convert_pbrt");
    std::ofstream(dir.file("all.pbrt")) << fmt::format(R"(
LookAt 0 -5 1.5  0 0 0.5  0 0 1
Camera "perspective" "float fov" [40] "float screenwindow" [-1.2 1.0 -0.8 0.9]
Film "image" "integer xresolution" [64] "integer yresolution" [36] "float cropwindow" [0.1 0.9 0 1]
WorldBegin
AttributeBegin
  Rotate 90 1 0 0
  LightSource "infinite" "string mapname" "{}/env/studio.exr" "float scale" [0.5]
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [3 3 3] "bool twosided" true
  Translate 0 0 3
  Shape "trianglemesh" "integer indices" [0 1 2 0 2 3] "point P" [-1 -1 0 1 -1 0 1 1 0 -1 1 0]
AttributeEnd
Material "matte" "rgb Kd" [0.6 0.2 0.1]
AttributeBegin
  Translate 0 0 0.6
  Shape "loopsubdiv" "integer levels" [2] "integer indices" [0 1 2 0 2 3 0 3 1 1 3 2]
        "point P" [0 0 0.7 0.6 0 -0.3 -0.3 0.5 -0.3 -0.3 -0.5 -0.3]
AttributeEnd
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3] "point P" [-5 -5 0 5 -5 0 5 5 0 -5 5 0]
WorldEnd
)",
                                                       test::asset_dir());
    const SceneDescription d = read_scene(dir.file("all.pbrt"));
    ASSERT_TRUE(d.camera.mirror && d.camera.screen && d.render.crop);
    ASSERT_TRUE(d.environment && d.environment->map);
    EXPECT_EQ(d.environment->map->projection, MapProjection::LatLongZUp);
    const SceneWriteReport rep = write_toml_scene(d, dir.file("all.toml"), dir.file("all_meshes"));
    EXPECT_EQ(rep.meshes.size(), 3u);  // two triangle meshes and the cage
    const SceneDescription back = read_scene(dir.file("all.toml"));
    EXPECT_TRUE(back.camera.mirror);
    EXPECT_EQ(back.camera.screen, d.camera.screen);
    EXPECT_EQ(back.render.crop, d.render.crop);
    EXPECT_EQ(back.environment->map->projection, MapProjection::LatLongZUp);
    EXPECT_EQ(render_path(dir.file("all.toml")), render_path(dir.file("all.pbrt")));
}

TEST(Convert, AnUnresolvedImportIsRefusedNotDropped) {
    SceneDescription d;
    d.path = "shot.toml";
    d.imports.push_back(ImportDesc{});
    test::TempDir dir("convert_refused");
    EXPECT_THROW(write_toml_scene(d, dir.file("x.toml"), dir.file("x_meshes")), SpangleError);
    EXPECT_FALSE(fs::exists(dir.file("x.toml")));
}

}  // namespace
}  // namespace spangle::test_convert
