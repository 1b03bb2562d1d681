// `spangle new`'s scene (engine/scene/new_scene.h): it loads, stands the model on the ground and
// frames it; and every "not found" names the absolute path it looked for.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <variant>

#include "core/error.h"
#include "pipeline/frame.h"
#include "scene/new_scene.h"
#include "scene/object_placement.h"
#include "scene/scene_loader.h"
#include "scene_request.h"
#include "test_support.h"

namespace fs = std::filesystem;

namespace spangle::test_new_scene {
namespace {

/** A box from lo to hi as an OBJ (12 triangles), away from the origin on purpose. */
void write_box_obj(const std::string& path, Vec3 lo, Vec3 hi) {
    std::ofstream f(path);
    for (int i = 0; i < 8; ++i)
        f << "v " << ((i & 1) ? hi.x : lo.x) << ' ' << ((i & 2) ? hi.y : lo.y) << ' '
          << ((i & 4) ? hi.z : lo.z) << '\n';
    const int faces[6][4] = {{1, 3, 7, 5}, {2, 6, 8, 4}, {1, 5, 6, 2},
                             {3, 4, 8, 7}, {1, 2, 4, 3}, {5, 7, 8, 6}};
    for (const auto& q : faces)
        f << "f " << q[0] << ' ' << q[1] << ' ' << q[2] << "\nf " << q[0] << ' ' << q[2] << ' '
          << q[3] << '\n';
}

/** Where `p` lands in the camera's image, in units of the half-height (y) and half-width (x):
 *  inside the image when both are in [-1, 1]. */
std::pair<double, double> project(const CameraDesc& cam, Vec3 p, double aspect) {
    const Vec3 fwd = normalize(cam.look_at - cam.position);
    const Vec3 right = normalize(cross(fwd, cam.up));
    const Vec3 up = cross(right, fwd);
    const Vec3 d = p - cam.position;
    const double z = dot(d, fwd);
    const double t = std::tan(cam.fov_deg * 3.14159265358979 / 360.0);
    return {dot(d, right) / z / (t * aspect), dot(d, up) / z / t};
}

TEST(NewScene, StandsTheModelOnTheGroundAndFramesItsBounds) {
    test::TempDir dir("new_scene");
    const Vec3 lo{10, 5, -3}, hi{14, 6, 1};
    fs::create_directories(dir.path() / "models");
    write_box_obj(dir.file("models/box.obj"), lo, hi);
    NewSceneRequest req;
    req.model = dir.file("models/box.obj");
    req.output = dir.file("box.toml");
    req.env_map = test::asset_dir() + "/env/studio_hdri.exr";
    const NewSceneReport rep = write_new_scene(req);
    EXPECT_NEAR(rep.model_bounds.lo.x, 10.0f, 1e-6f);
    EXPECT_NEAR(rep.model_bounds.hi.y, 6.0f, 1e-6f);

    const SceneDescription scene = read_scene(req.output);
    ASSERT_TRUE(scene.environment && scene.environment->map);
    EXPECT_EQ(fs::canonical(scene.environment->map->path), fs::canonical(req.env_map));
    ASSERT_EQ(scene.objects.size(), 2u) << "the ground and the model";
    const ObjectDesc& model = scene.objects[1];
    const auto* mesh = std::get_if<MeshFileShape>(&model.shape);
    ASSERT_NE(mesh, nullptr);
    EXPECT_EQ(fs::canonical(mesh->path), fs::canonical(req.model))
        << "written relative to the scene, read back as the model";
    // Stood on y = 0, centred over the origin: the box spans x -2..2, y 0..1, z -2..2.
    const Vec3 t = model.placement.parts.translate;
    EXPECT_NEAR(t.x, -12.0f, 1e-4f);
    EXPECT_NEAR(t.y, -5.0f, 1e-4f);
    EXPECT_NEAR(t.z, 1.0f, 1e-4f);
    EXPECT_NEAR(scene.camera.look_at.y, 0.5f, 1e-3f) << "looks at the bounds' centre";
    // Every corner of the placed box is inside the image, and the box is not a speck: its
    // corners reach past half the frame's height or width (the framing keeps them within 85%,
    // up to the 4-digit rounding of the written camera).
    const double aspect = double(scene.render.width) / scene.render.height;
    double reach = 0.0;
    for (int i = 0; i < 8; ++i) {
        const Vec3 c{(i & 1) ? 2.0f : -2.0f, (i & 2) ? 1.0f : 0.0f, (i & 4) ? 2.0f : -2.0f};
        const auto [x, y] = project(scene.camera, c, aspect);
        EXPECT_LE(std::abs(x), 0.86) << "corner " << i;
        EXPECT_LE(std::abs(y), 0.86) << "corner " << i;
        reach = std::max({reach, std::abs(x), std::abs(y)});
    }
    EXPECT_GT(reach, 0.8) << "framed tightly, not from afar";
    // The paint's density gives about 30 flakes per pixel at the look_at distance.
    EXPECT_NEAR(rep.flakes_per_pixel, 30.0, 1.0);

    // It renders: the plugins accept the parameters written, and the box (red glitter paint)
    // covers the image's centre while the ground and sky fill its corner.
    FrameRequest fr = test::quiet_request(req.output);
    fr.options.threads = 2;
    fr.options.spp_override = 4;
    fr.options.width_override = 64;
    fr.options.height_override = 36;
    const FrameResult img = render_frame(fr);
    ASSERT_EQ(img.width, 64u);
    const auto px = [&](uint32_t x, uint32_t y, int c) {
        return img.image[3 * (std::size_t(y) * img.width + x) + std::size_t(c)];
    };
    EXPECT_GT(px(32, 18, 0), 2.0f * px(32, 18, 2)) << "the centre shows the red paint";
    EXPECT_LT(px(0, 0, 0), 2.0f * px(0, 0, 2)) << "the corner does not";
    EXPECT_EQ(img.stats.nonfinite, 0u);
}

TEST(NewScene, AModelWhoseUpAxisIsNotYIsTurnedToStandUp) {
    // A tall box (5 units along its own z, 2 along y, 1 along x), as a CAD tool or a scan
    // writes a Z-up model: without --up it lay on its side. Each up axis stands its own extent
    // along y, on the ground, centred over the origin, in the scene as read back.
    test::TempDir dir("new_scene_up");
    struct Case {
        const char* up;
        Vec3 lo, hi;  ///< the box in its own coordinates, 5 units along the up axis
    };
    for (const Case& c : {Case{"z", {3, 1, -2}, {4, 3, 3}}, Case{"-z", {3, 1, -2}, {4, 3, 3}},
                          Case{"x", {-2, 1, 0}, {3, 3, 1}}, Case{"-x", {-2, 1, 0}, {3, 3, 1}},
                          Case{"-y", {0, -4, 0}, {1, 1, 2}}, Case{"y", {0, -4, 0}, {1, 1, 2}}}) {
        const std::string model = dir.file(std::string("tall") + c.up + ".obj");
        write_box_obj(model, c.lo, c.hi);
        NewSceneRequest req;
        req.model = model;
        req.output = dir.file(std::string("tall") + c.up + ".toml");
        req.env_map = test::asset_dir() + "/env/studio_hdri.exr";
        req.up = c.up;
        const NewSceneReport rep = write_new_scene(req);
        const SceneDescription scene = read_scene(req.output);
        ASSERT_EQ(scene.objects.size(), 2u) << c.up;
        const Affine m = matrix_of(scene.objects[1].placement);
        Box placed;
        for (int i = 0; i < 8; ++i)
            placed.add(m.apply_point(
                {(i & 1) ? c.hi.x : c.lo.x, (i & 2) ? c.hi.y : c.lo.y, (i & 4) ? c.hi.z : c.lo.z}));
        // The end its up axis points to is on top (an extent alone cannot tell z from -z).
        const Vec3 mid = (c.lo + c.hi) * 0.5f;
        const std::string axis = c.up;
        const bool negative = axis[0] == '-';
        const char which = axis.back();
        Vec3 top = mid;
        const auto end = [&](float lo, float hi) { return negative ? lo : hi; };
        if (which == 'x') top.x = end(c.lo.x, c.hi.x);
        if (which == 'y') top.y = end(c.lo.y, c.hi.y);
        if (which == 'z') top.z = end(c.lo.z, c.hi.z);
        EXPECT_NEAR(m.apply_point(top).y, 5.0f, 1e-4f) << c.up << ": its up end on top";
        EXPECT_NEAR(placed.lo.y, 0.0f, 1e-4f) << c.up << ": on the ground";
        EXPECT_NEAR(placed.hi.y, 5.0f, 1e-4f) << c.up << ": its up axis along y";
        EXPECT_NEAR(placed.lo.x + placed.hi.x, 0.0f, 1e-4f) << c.up;
        EXPECT_NEAR(placed.lo.z + placed.hi.z, 0.0f, 1e-4f) << c.up;
        // The report's bounds are the turned model's (5 tall) and the camera looks at its middle.
        EXPECT_NEAR(rep.model_bounds.hi.y - rep.model_bounds.lo.y, 5.0f, 1e-4f) << c.up;
        EXPECT_NEAR(scene.camera.look_at.y, 2.5f, 1e-3f) << c.up;
    }
    EXPECT_THROW(up_rotation("w"), SpangleError);
}

TEST(NewScene, NamesWithQuotesAndNewlinesAreWrittenAsTomlReadsThem) {
    // A glTF material named with a quote, a backslash and a newline (a user's file): `new` wrote
    // the newline raw, inside a string and a comment, and its scene did not load ("unescaped
    // control characters"). The command it suggests is one a shell reads.
    test::TempDir dir("new_names");
    std::ifstream in(test::test_dir() + "/scenes/gltf/cube.gltf");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string from = "\"name\": \"Painted\"";
    ASSERT_NE(text.find(from), std::string::npos);
    text.replace(text.find(from), from.size(), R"("name": "Paint \"Red\"\\ v2\nline\ttab")");
    std::ofstream(dir.file("names.gltf")) << text;
    NewSceneRequest req;
    req.model = dir.file("names.gltf");
    req.output = dir.file("my car's scene.toml");
    req.env_map = test::asset_dir() + "/env/studio_hdri.exr";
    const NewSceneReport rep = write_new_scene(req);
    const std::string name = "Paint \"Red\"\\ v2\nline\ttab";
    EXPECT_EQ(rep.paint, name);
    const SceneDescription scene = read_scene(req.output);
    ASSERT_FALSE(scene.materials.empty());
    EXPECT_EQ(scene.materials.front().name, name) << "read back as written in the glTF";
    std::ifstream written(req.output);
    const std::string toml((std::istreambuf_iterator<char>(written)),
                           std::istreambuf_iterator<char>());
    EXPECT_NE(
        toml.find("#     spangle render 'my car'\\''s scene.toml' -o 'my car'\\''s scene.exr'"),
        std::string::npos)
        << toml.substr(0, 400);
    EXPECT_EQ(shell_word("plain-name_1.toml"), "plain-name_1.toml");
    EXPECT_EQ(shell_word("a b"), "'a b'");
    EXPECT_EQ(shell_word(""), "''");
}

TEST(NewScene, AGltfsNodeScaleIsInThePaintsDensityAndItsKeysInItsBounds) {
    // The cube scene with its meshes under node scales a hundred times smaller (centimetre data
    // under a scale of 0.01, as converters write it): the scene is the same model, smaller, so
    // the paint's density per square unit of its meshes is the same. It was 10,000 times
    // denser (per square unit of the scaled scene): no glint, a smooth sheen.
    test::TempDir dir("new_node_scale");
    std::ifstream in(test::test_dir() + "/scenes/gltf/cube.gltf");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string gltf = dir.file("cube.gltf");
    std::ofstream(gltf) << text;
    const std::vector<std::pair<std::string, std::string>> edits = {
        {R"("mesh": 0,
   "translation": [
    0,
    0.5,
    0
   ])",
         R"("mesh": 0, "scale": [0.01, 0.01, 0.01], "translation": [0, 0.005, 0])"},
        {R"("scale": [
    6,
    0.05,
    6
   ],
   "translation": [
    0,
    -0.025,
    0
   ])",
         R"("scale": [0.06, 0.0005, 0.06], "translation": [0, -0.00025, 0])"}};
    for (const auto& [from, to] : edits) {
        ASSERT_NE(text.find(from), std::string::npos) << from;
        text.replace(text.find(from), from.size(), to);
    }
    const std::string small = dir.file("cube_small.gltf");
    std::ofstream(small) << text;
    const auto density = [&](const std::string& model, const std::string& out) {
        NewSceneRequest req;
        req.model = model;
        req.output = dir.file(out);
        req.env_map = test::asset_dir() + "/env/studio_hdri.exr";
        return write_new_scene(req);
    };
    const NewSceneReport full = density(gltf, "full.toml"), scaled = density(small, "small.toml");
    // The cube is animated: its bounds are where its keys place it at the first frame, standing
    // on the floor (they were its mesh's at the origin, and the model floated half a cube up).
    EXPECT_NEAR(full.model_bounds.hi.y, 1.0f, 1e-3f);
    EXPECT_NEAR(scaled.model_bounds.hi.x - scaled.model_bounds.lo.x,
                0.01f * (full.model_bounds.hi.x - full.model_bounds.lo.x), 1e-4f);
    EXPECT_NEAR(scaled.density / full.density, 1.0, 0.05)
        << "full " << full.density << ", scaled " << scaled.density;
    EXPECT_NEAR(scaled.flakes_per_pixel, 30.0, 2.0);
    // The painted cube is at scale 1: its density gives 30 flakes a pixel at the camera by the
    // paint's own objects alone (the floor, under a scale of 6 x 0.05 x 6 and another material,
    // made it 6.6 times denser when every object's area counted).
    const double dist = length(full.camera - full.look_at);
    const double pixel = 2.0 * dist * std::tan(full.fov_deg * M_PI / 360.0) / 720.0;
    EXPECT_NEAR(full.density * pixel * pixel / 30.0, 1.0, 0.1) << full.density;
}

TEST(NewScene, ModelsOfNoSizeFlatOrHugeGiveScenesThatLoadOrAClearError) {
    test::TempDir dir("new_scene_odd");
    NewSceneRequest req;
    req.env_map = test::asset_dir() + "/env/studio_hdri.exr";
    const auto make = [&](const std::string& name, Vec3 lo, Vec3 hi) {
        write_box_obj(dir.file(name + ".obj"), lo, hi);
        req.model = dir.file(name + ".obj");
        req.output = dir.file(name + ".toml");
        return write_new_scene(req);
    };
    // Every vertex alike (a degenerate export): the density was NaN and the scene did not load.
    const NewSceneReport point = make("point", Vec3(1, 2, 3), Vec3(1, 2, 3));
    EXPECT_TRUE(std::isfinite(point.density)) << point.density;
    EXPECT_NO_THROW(read_scene(req.output));
    // A flat card lying in y = const is lifted off the ground's plane (they fought for every
    // pixel).
    const NewSceneReport card = make("card", Vec3(0, 0, 0), Vec3(1, 0, 1));
    EXPECT_NEAR(card.offset.y, 1e-3f, 1e-6f);
    EXPECT_NO_THROW(read_scene(req.output));
    // 2 cm across, in metres: it wants more flakes per square unit than the paint takes. Said,
    // and the scene's comment no longer asks for a higher density at the largest one.
    const NewSceneReport cm = make("cm", Vec3(0.0f), Vec3(0.02f));
    EXPECT_LT(cm.flakes_per_pixel, 15.0);
    ASSERT_EQ(cm.notes.size(), 1u);
    EXPECT_NE(cm.notes[0].find("a pixel sees about"), std::string::npos) << cm.notes[0];
    {
        std::ifstream in(req.output);
        const std::string text((std::istreambuf_iterator<char>(in)), {});
        EXPECT_NE(text.find("as many as the largest density gives"), std::string::npos) << text;
        EXPECT_EQ(text.find("Raise density"), std::string::npos) << text;
    }
    EXPECT_NO_THROW(read_scene(req.output));
    // 1e20 across: the extent's square overflowed a float (an infinite position was written).
    const NewSceneReport big = make("big", Vec3(-1e20f), Vec3(1e20f));
    EXPECT_TRUE(std::isfinite(big.camera.x) && std::isfinite(big.density));
    EXPECT_NO_THROW(read_scene(req.output));
    // Beyond what a scene can hold: a clear error, nothing written.
    try {
        make("huge", Vec3(-1e30f), Vec3(1e30f));
        FAIL() << "a 3e30 model was accepted";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("too large for a scene"), std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(fs::exists(dir.file("huge.toml")));
}

TEST(NewScene, WhatReadingTheModelLeftOutIsReported) {
    // A model's skipped faces were said when the scene rendered, not by `spangle new`.
    test::TempDir dir("new_scene_notes");
    std::ofstream(dir.file("edges.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 3\nf 1 2\n";
    NewSceneRequest req;
    req.env_map = test::asset_dir() + "/env/studio_hdri.exr";
    req.model = dir.file("edges.obj");
    req.output = dir.file("edges.toml");
    const NewSceneReport rep = write_new_scene(req);
    ASSERT_EQ(rep.notes.size(), 1u);
    EXPECT_EQ(rep.notes[0], "mesh '" + dir.file("edges.obj") +
                                "': 1 face of fewer than 3 corners (points or edges, not "
                                "surfaces) skipped");
    write_box_obj(dir.file("box.obj"), Vec3(0.0f), Vec3(1.0f));
    req.model = dir.file("box.obj");
    req.output = dir.file("box.toml");
    EXPECT_TRUE(write_new_scene(req).notes.empty());
}

TEST(NewScene, AMissingModelNamesTheAbsolutePathItLookedFor) {
    test::TempDir dir("new_scene_missing");
    NewSceneRequest req;
    req.model = dir.file("nowhere/model.obj");
    req.output = dir.file("model.toml");
    req.env_map = test::asset_dir() + "/env/studio_hdri.exr";
    try {
        write_new_scene(req);
        FAIL() << "a missing model was accepted";
    } catch (const SpangleError& e) {
        EXPECT_NE(
            std::string(e.what()).find("not found (looked for " + dir.file("nowhere/model.obj")),
            std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(fs::exists(req.output)) << "nothing written";
}

TEST(NewScene, TheMapIsReadInItsOwnSpaceAndACutShortOneIsRefused) {
    // "lin_rec709" was written for every map: an 8-bit sRGB PNG was read as linear.
    test::TempDir dir("new_scene_map");
    write_box_obj(dir.file("box.obj"), {0, 0, 0}, {1, 1, 1});
    NewSceneRequest req;
    req.model = dir.file("box.obj");
    req.output = dir.file("box.toml");
    req.env_map = test::asset_dir() + "/textures/concrete.png";
    write_new_scene(req);
    const SceneDescription scene = read_scene(req.output);
    ASSERT_TRUE(scene.environment && scene.environment->map);
    EXPECT_FALSE(scene.environment->map->color_space) << "left to the map: srgb_texture for a PNG";
    // A map cut short was taken, and the scene failed when it first rendered.
    std::ifstream in(test::asset_dir() + "/env/studio_hdri.exr", std::ios::binary);
    std::string head(3000, '\0');
    in.read(head.data(), 3000);
    std::ofstream(dir.file("cut.exr"), std::ios::binary) << head;
    req.env_map = dir.file("cut.exr");
    req.output = dir.file("cut.toml");
    try {
        write_new_scene(req);
        FAIL() << "a cut-short map was accepted";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot read environment map"), std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(fs::exists(req.output)) << "nothing written";
}

/** Runs `fn` with the working directory set to `dir`, restoring it after. */
template <class Fn>
void in_directory(const fs::path& dir, Fn fn) {
    const fs::path before = fs::current_path();
    fs::current_path(dir);
    try {
        fn();
    } catch (...) {
        fs::current_path(before);
        throw;
    }
    fs::current_path(before);
}

TEST(ScenePaths, NotFoundNamesTheAbsolutePathOfAFileNamedRelativeToTheScene) {
    // A scene copied to another folder, read by a relative name: its map (named relative to the
    // scene) and its mesh are missing there, and the messages say where they were looked for.
    test::TempDir dir("not_found_abs");
    fs::create_directories(dir.path() / "copied");
    std::ofstream(dir.file("copied/scene.toml"))
        << "[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\n"
           "[environment]\nmap = \"../env/studio.exr\"\n";
    std::ofstream(dir.file("copied/mesh.toml"))
        << "[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\n"
           "[[material]]\nname = \"m\"\nplugin = \"smooth\"\nmodel = \"diffuse\"\n"
           "[[object]]\nmesh = \"../meshes/car.obj\"\nmaterial = \"m\"\n";
    const std::string want_map = (dir.path() / "env" / "studio.exr").string();
    const std::string want_mesh = (dir.path() / "meshes" / "car.obj").string();
    in_directory(dir.path() / "copied", [&] {
        try {
            read_scene("scene.toml");
            FAIL() << "a missing map was accepted";
        } catch (const SpangleError& e) {
            EXPECT_NE(std::string(e.what()).find(
                          "map file '../env/studio.exr' not found (looked for " + want_map + ")"),
                      std::string::npos)
                << e.what();
        }
        try {
            read_scene("mesh.toml");
            FAIL() << "a missing mesh was accepted";
        } catch (const SpangleError& e) {
            EXPECT_NE(std::string(e.what()).find("(looked for " + want_mesh + ")"),
                      std::string::npos)
                << e.what();
        }
        try {
            read_scene("absent.toml");
            FAIL() << "a missing scene was accepted";
        } catch (const SpangleError& e) {
            EXPECT_NE(std::string(e.what()).find(
                          "(looked for " + (dir.path() / "copied" / "absent.toml").string() + ")"),
                      std::string::npos)
                << e.what();
        }
    });
}

}  // namespace
}  // namespace spangle::test_new_scene
