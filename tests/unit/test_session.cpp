// Progressive passes and the incremental session behind watch mode: the last pass equals a
// one-pass render bit for bit; a stop request keeps the completed passes; the component diff
// sees what changed; a reload runs only what the change needs and a bad scene changes nothing.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "color/image_output.h"
#include "geometry/mesh_load.h"
#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "shading/plugin_loader.h"
#include "test_support.h"

namespace fs = std::filesystem;

namespace spangle::test_session {
namespace {

/** A quiet request for `scene` with the shipped OCIO config. */
FrameRequest request(const std::string& scene, int threads, uint32_t spp) {
    FrameRequest req;
    req.scene = scene;
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.threads = threads;
    req.options.spp_override = spp;
    return req;
}

FrameResult render(const std::string& scene, bool progressive, uint32_t spp,
                   std::function<bool()> stop = {}) {
    FrameRequest req = request(scene, 2, spp);
    req.options.progressive = progressive;
    req.options.stop = std::move(stop);
    return render_frame(req);
}

TEST(Passes, DoubleUpToTheSampleCount) {
    EXPECT_EQ(pass_ends(1), (std::vector<uint32_t>{1}));
    EXPECT_EQ(pass_ends(2), (std::vector<uint32_t>{1, 2}));
    EXPECT_EQ(pass_ends(16), (std::vector<uint32_t>{1, 2, 4, 8, 16}));
    EXPECT_EQ(pass_ends(24), (std::vector<uint32_t>{1, 2, 4, 8, 16, 24}));
}

TEST(Passes, LastPassEqualsOnePassRenderBitForBit) {
    // Glitter (a plugin batch per wave) and glossy light: the passes split the samples
    // differently into waves, yet every pixel adds the same samples in the same order.
    for (const char* scene : {"flake_uvless.toml", "glossy_sphere_light.toml"}) {
        const std::string path = test::test_dir() + "/scenes/" + scene;
        const FrameResult passes = render(path, true, 24);
        const FrameResult one = render(path, false, 24);
        ASSERT_EQ(passes.image.size(), one.image.size());
        EXPECT_EQ(passes.stats.passes, 6u) << scene;
        EXPECT_EQ(passes.stats.spp_reached, 24u);
        EXPECT_EQ(
            std::memcmp(passes.image.data(), one.image.data(), one.image.size() * sizeof(float)), 0)
            << scene;
        double sum = 0.0;
        for (float x : one.image) sum += x;
        EXPECT_GT(sum, 0.0) << scene;
    }
}

TEST(Passes, PreviewPassIsBlockwiseAndLeavesTheImageAlone) {
    EXPECT_EQ(preview_stride(1280, 720), 8u);
    EXPECT_EQ(preview_stride(640, 360), 4u);
    EXPECT_EQ(preview_stride(320, 180), 2u);
    EXPECT_EQ(preview_stride(200, 100), 1u);
    EXPECT_EQ(preview_stride(16384, 16384), 16u);
    // A preview pass before the passes: reported with 0 spp, one value per block (each the
    // value of the block's own traced pixel), and the final image is bit for bit the same.
    const std::string path = test::test_dir() + "/scenes/glossy_sphere_light.toml";
    FrameRequest req = request(path, 2, 8);
    req.options.width_override = 330;  // not a multiple of the block: edge blocks are partial
    req.options.height_override = 170;
    req.options.preview_pass = true;
    std::vector<uint32_t> spps;
    std::vector<float> preview;
    uint32_t block = 0;
    req.options.on_pass = [&](const PassImage& p) {
        spps.push_back(p.spp);
        if (p.spp == 0) {
            preview = p.image;
            block = p.block;
            EXPECT_EQ(p.target, 8u);
        }
    };
    const FrameResult with = render_frame(req);
    EXPECT_EQ(spps, (std::vector<uint32_t>{0, 1, 2, 4}));
    ASSERT_EQ(block, 2u);
    const uint32_t w = with.width, h = with.height;
    ASSERT_EQ(preview.size(), 3u * w * h);
    double sum = 0.0;
    std::size_t off_block = 0;
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x) {
            const uint32_t sx = std::min((x / block) * block + block / 2, w - 1);
            const uint32_t sy = std::min((y / block) * block + block / 2, h - 1);
            for (uint32_t c = 0; c < 3; ++c) {
                const float v = preview[3 * (y * w + x) + c];
                off_block += v != preview[3 * (sy * w + sx) + c];
                sum += v;
            }
        }
    EXPECT_EQ(off_block, 0u);
    EXPECT_GT(sum, 0.0);
    req.options.preview_pass = false;
    req.options.on_pass = {};
    const FrameResult without = render_frame(req);
    ASSERT_EQ(with.image.size(), without.image.size());
    EXPECT_EQ(
        std::memcmp(with.image.data(), without.image.data(), with.image.size() * sizeof(float)), 0);
    // The preview resembles the image: its mean is within 10% of the final one.
    double final_sum = 0.0;
    for (float x : with.image) final_sum += x;
    EXPECT_NEAR(sum / final_sum, 1.0, 0.1);
}

TEST(Passes, StopKeepsTheCompletedPasses) {
    // Stop during the fourth pass: the image is that of the first three (4 spp), exactly.
    const std::string path = test::test_dir() + "/scenes/flake_uvless.toml";
    std::atomic<int> polls{0};
    int passes_seen = 0;
    FrameRequest req = request(path, 1, 64);
    req.options.on_pass = [&](const PassImage&) { ++passes_seen; };
    req.options.stop = [&] { return passes_seen >= 3 && ++polls > 3; };
    const FrameResult stopped = render_frame(req);
    EXPECT_EQ(stopped.stats.spp_reached, 4u);
    EXPECT_EQ(stopped.stats.spp_target, 64u);
    const FrameResult four = render(path, false, 4);
    ASSERT_EQ(stopped.image.size(), four.image.size());
    EXPECT_EQ(
        std::memcmp(stopped.image.data(), four.image.data(), four.image.size() * sizeof(float)), 0);
}

/** A scene in a temporary directory, edited by text replacement. */
struct TempScene {
    fs::path dir, file;
    TempScene() {
        dir = fs::temp_directory_path() / ("spangle_session_" + std::to_string(::getpid()));
        fs::create_directories(dir);
        fs::copy_file(test::test_dir() + "/scenes/uvless_ball.obj", dir / "uvless_ball.obj",
                      fs::copy_options::overwrite_existing);
        std::ifstream in(test::test_dir() + "/scenes/flake_uvless.toml");
        std::stringstream ss;
        ss << in.rdbuf();
        text = ss.str();
        file = dir / "scene.toml";
        save();
    }
    ~TempScene() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
    void replace(const std::string& from, const std::string& to) {
        const auto at = text.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        text.replace(at, from.size(), to);
        save();
    }
    void save() const { std::ofstream(file) << text; }
    std::string text;
};

bool contains(const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
}

TEST(Session, ReloadRunsOnlyWhatTheChangeNeeds) {
    TempScene scene;
    RenderOptions options;
    options.threads = 2;
    options.spp_override = 2;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());

    const ReloadReport first = session.load(scene.file.string());
    EXPECT_TRUE(first.first);
    EXPECT_TRUE(contains(first.ran, "mesh_load"));
    EXPECT_TRUE(contains(first.ran, "materials"));
    EXPECT_TRUE(contains(first.ran, "accelerate"));
    session.render();
    const std::vector<float> before = session.result().image;
    const MaterialInstance* material =
        session.world().products.get<MaterialSet>().instances[0].get();

    // Nothing changed: nothing runs, the same material instance stays.
    const ReloadReport same = session.load(scene.file.string());
    EXPECT_TRUE(same.changed.empty());
    EXPECT_TRUE(same.ran.empty());
    EXPECT_EQ(session.world().products.get<MaterialSet>().instances[0].get(), material);

    // A material parameter: that one material is recreated, nothing else runs.
    scene.replace("gamma = 3", "gamma = 4");
    const ReloadReport mat = session.load(scene.file.string());
    EXPECT_EQ(mat.changed, (std::vector<std::string>{"Material"}));
    EXPECT_EQ(mat.ran, (std::vector<std::string>{"materials"}));
    EXPECT_NE(session.world().products.get<MaterialSet>().instances[0].get(), material);
    session.render();
    EXPECT_NE(session.result().image, before);

    // A transform: instances and the top level, the mesh's BVH reused; lights (bounds) rerun.
    scene.replace("rotate = [30, 20, 0]", "rotate = [30, 60, 0]");
    const ReloadReport xf = session.load(scene.file.string());
    EXPECT_EQ(xf.changed, (std::vector<std::string>{"Transform"}));
    EXPECT_FALSE(contains(xf.ran, "mesh_load"));
    EXPECT_FALSE(contains(xf.ran, "materials"));
    EXPECT_TRUE(contains(xf.ran, "accelerate"));
    EXPECT_EQ(xf.reused.at("mesh BVHs"), 1);

    // The camera: nothing is rebuilt.
    scene.replace("fov = 32", "fov = 30");
    const ReloadReport cam = session.load(scene.file.string());
    EXPECT_EQ(cam.changed, (std::vector<std::string>{"Camera"}));
    EXPECT_TRUE(cam.ran.empty());
    EXPECT_TRUE(cam.built.empty());

    // A bad save: an error with file:line, and the live scene is untouched.
    const std::vector<float> good = (session.render(), session.result().image);
    scene.replace("fov = 30", "fov = 300");
    try {
        session.load(scene.file.string());
        ADD_FAILURE() << "a field of view of 300 degrees loaded";
    } catch (const SpangleError& e) {
        EXPECT_TRUE(std::regex_search(e.what(), std::regex("scene\\.toml:[0-9]+:[0-9]+: error")))
            << e.what();
    }
    session.render();
    EXPECT_EQ(session.result().image, good);

    // The result of a reload equals a cold render of the edited scene.
    scene.replace("fov = 300", "fov = 30");
    session.load(scene.file.string());
    session.render();
    const FrameResult cold = render(scene.file.string(), true, 2);
    EXPECT_EQ(session.result().image, cold.image);
}

TEST(Session, ADroppedWorkingSpaceGoesBackToTheDefault) {
    // The scene names lin_rec709; the edit drops the key, so the reload must render in the
    // default working space (ACEScg), as a fresh session of the edited file does. It kept
    // lin_rec709: the live config's space carried over into every later scene (a Python
    // load() of another file too).
    TempScene scene;
    RenderOptions options;
    options.threads = 2;
    options.spp_override = 2;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(scene.file.string());
    EXPECT_EQ(session.info().working_space, "lin_rec709");
    scene.replace("working_space = \"lin_rec709\"", "");
    const ReloadReport edit = session.load(scene.file.string());
    EXPECT_TRUE(contains(edit.changed, "working space"));
    EXPECT_EQ(session.info().working_space, "ACEScg");
    session.render();
    Session fresh({}, test::shipped_ocio(), options, test::quiet_log());
    fresh.load(scene.file.string());
    fresh.render();
    EXPECT_EQ(session.result().image, fresh.result().image);
}

TEST(Session, TheSceneHashCoversTheFilesItsSystemsRead) {
    // spangle merge refuses parts whose sceneHash differs: an edited mesh (or texture, map)
    // between two crop parts must change it. It covered the scene files only, so parts of a
    // scaled sphere merged into a seam. A reload of an unchanged scene keeps it; a fresh session
    // of the same files gives the same hash (crop parts and MPI ranks are separate processes).
    TempScene scene;
    RenderOptions options;
    options.threads = 1;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(scene.file.string());
    const uint64_t before = session.info().content_hash;
    session.load(scene.file.string());
    EXPECT_EQ(session.info().content_hash, before);
    { std::ofstream(scene.dir / "uvless_ball.obj", std::ios::app) << "# edited\n"; }
    const ReloadReport edit = session.load(scene.file.string());
    EXPECT_TRUE(contains(edit.ran, "mesh_load"));
    const uint64_t after = session.info().content_hash;
    EXPECT_NE(after, before);
    Session fresh({}, test::shipped_ocio(), options, test::quiet_log());
    fresh.load(scene.file.string());
    EXPECT_EQ(fresh.info().content_hash, after);
}

TEST(Session, TheSceneHashIsTheSameWhereverTheFilesAreMounted) {
    // Farm nodes mount the same files in other places: the plugin here before the assets in
    // path order, there after them. The files' hashes were combined in path order, so crop
    // parts of one render from two such nodes were refused as different scenes.
    TempScene scene;
    std::string flake;
    for (const std::string& d : plugin_search_path({}))
        if (fs::exists(fs::path(d) / "libspangle_flake.so")) {
            flake = (fs::path(d) / "libspangle_flake.so").string();
            break;
        }
    ASSERT_FALSE(flake.empty());
    const fs::path base = fs::temp_directory_path();
    const std::string tag = std::to_string(::getpid());
    const fs::path early = base / ("a_spangle_plugins_" + tag);  // sorts before the scene
    const fs::path late = base / ("zz_spangle_plugins_" + tag);  // and after it
    ASSERT_LT(early.string(), scene.dir.string());
    ASSERT_GT(late.string(), scene.dir.string());
    for (const fs::path& d : {early, late}) {
        fs::create_directories(d);
        fs::copy_file(flake, d / "libspangle_flake.so", fs::copy_options::overwrite_existing);
    }
    RenderOptions options;
    options.threads = 1;
    Session here({early.string()}, test::shipped_ocio(), options, test::quiet_log());
    here.load(scene.file.string());
    Session there({late.string()}, test::shipped_ocio(), options, test::quiet_log());
    there.load(scene.file.string());
    EXPECT_EQ(here.plugins().opened_files().front(), (early / "libspangle_flake.so").string());
    EXPECT_EQ(there.plugins().opened_files().front(), (late / "libspangle_flake.so").string());
    EXPECT_EQ(here.info().content_hash, there.info().content_hash);
    std::error_code ec;
    fs::remove_all(early, ec);
    fs::remove_all(late, ec);
}

TEST(Session, AnEditedLutIsReadAgainAndHashed) {
    // A LUT a colour's conversion reads: an edit of it alone reloaded nothing, and a reload of
    // the config kept OpenColorIO's cached copy (the old colours, unlike a fresh render); two
    // renders with different LUT bytes (another node's, another $SHOT) had one scene hash.
    test::TempDir dir("session_lut");
    const auto lut = [&](float top) {
        std::ofstream(dir.file("luts/curve.spi1d"))
            << "Version 1\nFrom 0.0 1.0\nLength 2\nComponents 1\n{\n0.0\n"
            << top << "\n}\n";
    };
    fs::create_directories(dir.file("luts"));
    lut(1.0f);
    std::ofstream(dir.file("config.ocio")) << R"(ocio_profile_version: 2
search_path: "luts"
roles:
  default: Linear Ref
  scene_linear: Linear Ref
displays:
  Monitor:
    - !<View> {name: Raw, colorspace: Linear Ref}
colorspaces:
  - !<ColorSpace>
    name: Linear Ref
  - !<ColorSpace>
    name: Lut Space
    to_scene_reference: !<FileTransform> {src: curve.spi1d, interpolation: linear}
)";
    std::ofstream(dir.file("s.toml"))
        << "[render]\nwidth = 4\nheight = 4\nspp = 1\nworking_space = \"Linear Ref\"\n"
           "[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[environment]\n"
           "color = { rgb = [0.5, 0.5, 0.5], space = \"Lut Space\" }\n";
    RenderOptions options;
    options.threads = 1;
    const auto sky = [&](Session& s) {
        s.render();
        return s.result().image.at(0);
    };
    Session session({}, dir.file("config.ocio"), options, test::quiet_log());
    session.load(dir.file("s.toml"));
    EXPECT_FLOAT_EQ(sky(session), 0.5f);
    {
        // The config saved again as it was, once a conversion has read its LUT: not an edit
        // (the live config's hash holds the LUT's bytes, a fresh one's did not: every touch
        // rebuilt the scene).
        std::ifstream in(dir.file("config.ocio"));
        std::stringstream text;
        text << in.rdbuf();
        ::usleep(20000);
        std::ofstream(dir.file("config.ocio")) << text.str();
        const ReloadReport same = session.load(dir.file("s.toml"));
        EXPECT_TRUE(same.changed.empty()) << same.summary();
        EXPECT_TRUE(same.ran.empty()) << same.summary();
    }
    const uint64_t before = session.info().content_hash;
    const std::vector<std::string> watched = session.watched_files();
    EXPECT_NE(std::find(watched.begin(), watched.end(), dir.file("luts/curve.spi1d")),
              watched.end());
    ::usleep(20000);  // a new modification time on every file system
    lut(0.5f);
    const ReloadReport rep = session.load(dir.file("s.toml"));
    EXPECT_NE(std::find(rep.changed.begin(), rep.changed.end(), "the OCIO config's LUT files"),
              rep.changed.end());
    EXPECT_FLOAT_EQ(sky(session), 0.25f) << "the reload must read the edited LUT";
    EXPECT_NE(session.info().content_hash, before);
    Session fresh({}, dir.file("config.ocio"), options, test::quiet_log());
    fresh.load(dir.file("s.toml"));
    EXPECT_FLOAT_EQ(sky(fresh), 0.25f);
    EXPECT_EQ(fresh.info().content_hash, session.info().content_hash);

    // A reloaded config is offered to check_reloaded_config before it is taken: a throw keeps
    // the live scene and config (the watch loop refuses a config without its view so).
    // The edited config makes 'Lut Space' four times brighter: taken, the sky would be 2.
    session.check_reloaded_config = [](const ColorConfig&) {
        throw SpangleError("the view 'Raw' is gone");
    };
    ::usleep(20000);
    {
        std::ifstream in(dir.file("config.ocio"));
        std::stringstream text;
        text << in.rdbuf();
        std::string edited = text.str();
        const std::string from_lut = "!<FileTransform> {src: curve.spi1d, interpolation: linear}";
        ASSERT_NE(edited.find(from_lut), std::string::npos);
        edited.replace(edited.find(from_lut), from_lut.size(),
                       "!<MatrixTransform> {matrix: [4, 0, 0, 0, 0, 4, 0, 0, 0, 0, 4, 0, 0, 0, 0, "
                       "1]}");
        std::ofstream(dir.file("config.ocio")) << edited;
    }
    EXPECT_THROW(session.load(dir.file("s.toml")), SpangleError);
    EXPECT_FLOAT_EQ(sky(session), 0.25f) << "the refused config must not be taken";
    session.check_reloaded_config = nullptr;
    session.load(dir.file("s.toml"));
    EXPECT_FLOAT_EQ(sky(session), 2.0f) << "taken once nothing refuses it";
}

TEST(Session, AConfigSavedAgainWithTheSameContentIsNotAnEdit) {
    // A touch of the OCIO config, a save without an edit, or a bad edit put back reloaded the
    // whole scene (every mesh read and subdivided again) and threw the finished image away; an
    // edit that changes the config is one.
    test::TempDir dir("session_config_touch");
    const std::string config = R"(ocio_profile_version: 2
roles:
  default: Linear Ref
  scene_linear: Linear Ref
displays:
  Monitor:
    - !<View> {name: Raw, colorspace: Linear Ref}
colorspaces:
  - !<ColorSpace>
    name: Linear Ref
  - !<ColorSpace>
    name: Twice
    to_scene_reference: !<MatrixTransform> {matrix: [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]}
)";
    std::ofstream(dir.file("config.ocio")) << config;
    std::ofstream(dir.file("s.toml"))
        << "[render]\nwidth = 4\nheight = 4\nspp = 1\nworking_space = \"Linear Ref\"\n"
           "[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[environment]\n"
           "color = { rgb = [0.25, 0.25, 0.25], space = \"Twice\" }\n";
    RenderOptions options;
    options.threads = 1;
    Session session({}, dir.file("config.ocio"), options, test::quiet_log());
    session.load(dir.file("s.toml"));
    ::usleep(20000);  // a new modification time on every file system
    std::ofstream(dir.file("config.ocio")) << config;
    const ReloadReport same = session.load(dir.file("s.toml"));
    EXPECT_TRUE(same.changed.empty()) << same.summary();
    EXPECT_TRUE(same.ran.empty()) << same.summary();
    ::usleep(20000);
    std::string edited = config;
    edited.replace(edited.find("[2, 0, 0, 0, 0, 2"), 17, "[4, 0, 0, 0, 0, 4");
    edited.replace(edited.find("0, 0, 2, 0, 0"), 13, "0, 0, 4, 0, 0");
    std::ofstream(dir.file("config.ocio")) << edited;
    const ReloadReport changed = session.load(dir.file("s.toml"));
    EXPECT_FALSE(changed.ran.empty()) << changed.summary();
    session.render();
    EXPECT_FLOAT_EQ(session.result().image.at(0), 1.0f) << "the edited config taken";
}

TEST(Session, EachEditRerunsTheSystemsThatReadWhatItChanged) {
    // Every light kind, three materials, meshes: each edit reruns exactly the systems whose
    // declared reads it changed (and those reading what they wrote), and the reloaded scene
    // renders as a fresh session of the edited file does, bit for bit.
    test::TempDir dir("session_reruns");
    const std::string file = dir.file("scene.toml");
    std::string text = test::scene_text("delta_hard_cases.toml");
    std::ofstream(file) << text;
    RenderOptions options;
    options.threads = 2;
    options.spp_override = 2;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(file);
    const auto edit = [&](const std::string& from, const std::string& to) {
        const auto at = text.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        text.replace(at, from.size(), to);
        std::ofstream(file) << text;
        const ReloadReport rep = session.load(file);
        session.render();
        const FrameResult cold = render(file, true, 2);
        EXPECT_EQ(session.result().image, cold.image) << from << " -> " << to;
        return rep;
    };
    using names = std::vector<std::string>;
    ReloadReport rep = edit("intensity = 3", "intensity = 4");
    EXPECT_EQ(rep.changed, names{"PointLight"});
    EXPECT_EQ(rep.ran, (names{"point_lights", "light_selection"}));
    rep = edit("color = [0.1, 0.1, 0.1]", "color = [0.2, 0.1, 0.1]");
    EXPECT_EQ(rep.changed, names{"Environment"});
    EXPECT_EQ(rep.ran, (names{"environment", "light_selection"}));
    rep = edit("radius = 0.1", "radius = 0.15");
    EXPECT_EQ(rep.changed, names{"SphereLight"});
    EXPECT_EQ(rep.ran, (names{"area_lights", "accelerate", "light_selection"}));
    EXPECT_EQ(rep.reused.at("mesh BVHs"), 2);
    rep = edit("roughness = 0.0, albedo = 0.5", "roughness = 0.1, albedo = 0.5");
    EXPECT_EQ(rep.changed, names{"Material"});
    EXPECT_EQ(rep.ran, names{"materials"});
    EXPECT_EQ(rep.built, names{"material 'coat'"});
    EXPECT_EQ(rep.reused.at("materials"), 2);
}

TEST(Session, AnEditToAnImageLargerThanMemoryIsRefusedAtItsSizeAndKeepsTheLiveScene) {
    // Refused only when the render began, such an edit stopped the render in progress and became
    // the live scene; refused at the load (watch mode), it is an error at the size's key like any
    // other.
    // A watch session's options: passes that can be stopped and are shown (120 bytes a pixel).
    RenderOptions options;
    options.spp_override = 64;
    options.progressive = true;
    options.stop = [] { return false; };
    options.on_pass = [](const PassImage&) {};
    options.film_memory_at_load = true;
    // Memory as a 1 GiB machine has it (the film needs 30 GiB), whatever this one has.
    struct Limit {
        Limit() { setenv("SPANGLE_MEMORY_LIMIT", "1G", 1); }
        ~Limit() { unsetenv("SPANGLE_MEMORY_LIMIT"); }
    } limit;
    test::TempDir dir("session_memory");
    const std::string file = dir.file("scene.toml");
    std::string text = test::scene_text("delta_hard_cases.toml");
    std::ofstream(file) << text;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(file);
    Film before;
    ASSERT_TRUE(session.film(before));
    std::string big = text;
    big = std::regex_replace(big, std::regex("width = [0-9]+"), "width = 16384");
    big = std::regex_replace(big, std::regex("height = [0-9]+"), "height = 16384");
    ASSERT_NE(big, text) << "the scene writes its size";
    std::ofstream(file) << big;
    try {
        session.load(file);
        FAIL() << "a 16384x16384 image larger than memory was loaded";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("scene.toml:"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("16384x16384 image needs about"), std::string::npos)
            << e.what();
    }
    Film after;
    ASSERT_TRUE(session.film(after));
    EXPECT_EQ(after.width, before.width);
    EXPECT_EQ(after.height, before.height);
}

TEST(Session, AnInlineMeshRendersAsItsFileDoesAndReloadsAsUnchanged) {
    // The meshes a scene file holds itself (a pbrt trianglemesh, glTF primitives) go through
    // mesh_load as inline meshes: the same triangles as a file render the same image, a second
    // read of the same triangles (a new mesh object) changes nothing, and two objects sharing
    // one mesh share one BVH.
    const std::string file = test::test_dir() + "/scenes/small_lit.toml";
    RenderOptions options;
    options.threads = 2;
    options.spp_override = 2;
    Session from_files({}, test::shipped_ocio(), options, test::quiet_log());
    from_files.load(file);
    from_files.render();
    const auto inline_copy = [&] {
        SceneDescription d = read_scene(file);
        for (ObjectDesc& o : d.objects)
            if (const auto* m = std::get_if<MeshFileShape>(&o.shape))
                o.shape = InlineMeshShape{
                    std::make_shared<const TriangleMesh>(load_mesh(m->path, m->loc)), m->loc};
        return d;
    };
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(inline_copy());
    session.render();
    EXPECT_EQ(session.result().image, from_files.result().image);
    const ReloadReport again = session.load(inline_copy());
    EXPECT_TRUE(again.changed.empty());
    EXPECT_TRUE(again.ran.empty());

    SceneDescription shared = inline_copy();
    auto& first = std::get<InlineMeshShape>(shared.objects[0].shape);
    for (ObjectDesc& o : shared.objects) o.shape = first;
    const ReloadReport one = session.load(shared);
    EXPECT_EQ(session.world().products.get<LoadedMeshes>().meshes.size(), 1u);
    EXPECT_TRUE(contains(one.ran, "mesh_load"));
}

TEST(Session, AnEditedTextureRemakesItsMaterial) {
    test::TempDir dir("session_texture");
    const ColorConfig color = test::shipped_config();
    const auto write_flat = [&](float value) {
        ExrOptions o;
        o.half = false;
        write_exr(dir.file("albedo.exr"), std::vector<float>(3 * 4 * 4, value), 4, 4, color, o);
    };
    write_flat(0.2f);
    std::ofstream(dir.file("scene.toml")) << fmt::format(R"(
[render]
width = 16
height = 16
working_space = "lin_rec709"
[camera]
position = [0, 3, 0.01]
look_at = [0, 0, 0]
[environment]
color = [1, 1, 1]
[[material]]
name = "m"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = {{ texture = "albedo.exr" }} }}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "m"
scale = 4
)",
                                                         test::asset_dir());
    RenderOptions options;
    options.threads = 2;
    options.spp_override = 2;
    options.texture_cache = dir.file("cache");
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(dir.file("scene.toml"));
    session.render();
    const std::vector<float> before = session.result().image;
    EXPECT_TRUE(std::find(session.watched_files().begin(), session.watched_files().end(),
                          dir.file("albedo.exr")) != session.watched_files().end());

    write_flat(0.6f);
    const ReloadReport rep = session.load(dir.file("scene.toml"));
    EXPECT_EQ(rep.changed, (std::vector<std::string>{"texture file " + dir.file("albedo.exr")}));
    EXPECT_EQ(rep.ran, (std::vector<std::string>{"materials"}));
    session.render();
    // A diffuse plane filling the view under a white sky of radiance 1 reflects its albedo:
    // 0.2, then the edited image's 0.6, in every pixel.
    for (std::size_t i = 0; i < before.size(); ++i) {
        ASSERT_NEAR(before[i], 0.2f, 1e-3f) << "value " << i;
        ASSERT_NEAR(session.result().image[i], 0.6f, 1e-3f) << "value " << i;
    }
}

TEST(Session, RegistryDiffIgnoresWhereValuesAreWritten) {
    TempScene scene;
    ColorConfig color = ColorConfig::load(test::shipped_ocio(), {});
    ecs::Registry a, b;
    load_scene(scene.file.string(), color, a);
    scene.replace("[camera]", "# a comment line moves everything below\n[camera]");
    load_scene(scene.file.string(), color, b);
    EXPECT_TRUE(ecs::Registry::changed_types(a, b, {}).empty());
    scene.replace("intensity = 21", "intensity = 22");
    ecs::Registry c;
    load_scene(scene.file.string(), color, c);
    EXPECT_EQ(ecs::Registry::changed_types(a, c, {}), (std::vector<std::string>{"SphereLight"}));
}

}  // namespace
}  // namespace spangle::test_session
