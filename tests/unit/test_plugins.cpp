#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/hash.h"
#include "pipeline/frame.h"
#include "scene_request.h"
#include "shading/material.h"
#include "shading/plugin_loader.h"
#include "test_support.h"

namespace spangle::test_plugins {
namespace {

namespace fs = std::filesystem;

std::string broken(const std::string& variant) {
    return std::string(SPANGLE_TEST_PLUGIN_DIR) + "/libspangle_" + variant + ".so";
}

/** Runs f and returns the SpangleError message it throws (or fails the test). */
template <class F>
std::string error_of(F&& f) {
    try {
        f();
    } catch (const SpangleError& e) {
        return e.what();
    }
    ADD_FAILURE() << "expected a SpangleError";
    return {};
}

#define EXPECT_HAS(msg, text)                                                  \
    do {                                                                       \
        const std::string spangle_msg_ = (msg);                                \
        EXPECT_NE(spangle_msg_.find(text), std::string::npos) << spangle_msg_; \
    } while (0)

TEST(PluginLoader, FindsSmoothBesideTheBinary) {
    ::unsetenv("SPANGLE_PLUGIN_PATH");
    PluginLoader loader(plugin_search_path({}));
    auto p = loader.open("smooth", {});
    EXPECT_STREQ(p->table().name, "smooth");
    EXPECT_NE(p->model("diffuse"), nullptr);
    EXPECT_EQ(loader.open("smooth", {}).get(), p.get()) << "a plugin is opened once";
    EXPECT_EQ(loader.opened(), std::vector<std::string>{"smooth"});
}

TEST(PluginLoader, NotFoundNamesEveryDirectory) {
    PluginLoader loader({"/nowhere/a", "/nowhere/b"});
    const std::string msg = error_of([&] { loader.open("chrome", FileLoc{"s.toml", 3, 10}); });
    EXPECT_EQ(msg.rfind("s.toml:3:10: error: plugin 'chrome' not found", 0), 0u) << msg;
    EXPECT_HAS(msg, "libspangle_chrome.so");
    EXPECT_HAS(msg, "/nowhere/a, /nowhere/b");
}

TEST(PluginLoader, RejectsPathLikeNames) {
    PluginLoader loader({});
    EXPECT_HAS(error_of([&] { loader.open("../smooth", {}); }), "is not valid");
}

TEST(PluginLoader, AbiMismatch) {
    EXPECT_HAS(error_of([] { PluginLoader::open_file(broken("abi"), "abi"); }),
               "was built for material ABI version 999, but this spangle uses version 3");
}

TEST(PluginLoader, NotAPluginWithoutEntryPoint) {
    EXPECT_HAS(error_of([] { PluginLoader::open_file(broken("noentry"), "noentry"); }),
               "is not a Spangle plugin: it has no entry point 'spangle_material_plugin'");
}

TEST(PluginLoader, PluginRefusingTheHost) {
    EXPECT_HAS(error_of([] { PluginLoader::open_file(broken("refuses"), "refuses"); }),
               "refused this host's material ABI version 3");
}

TEST(PluginLoader, FileNameAndPluginNameMustAgree) {
    EXPECT_HAS(error_of([] { PluginLoader::open_file(broken("misnamed"), "misnamed"); }),
               "calls itself 'someone_else', expected 'misnamed'");
}

TEST(PluginLoader, MalformedTable) {
    EXPECT_HAS(error_of([] { PluginLoader::open_file(broken("malformed"), "malformed"); }),
               "declares closure_size 0");
}

TEST(PluginLoader, GarbageFileIsNotALibrary) {
    test::TempDir dir("garbage_plugin");
    std::ofstream(dir.file("libspangle_garbage.so")) << "not an ELF file\n";
    PluginLoader loader({dir.path().string()});
    const std::string msg = error_of([&] { loader.open("garbage", {}); });
    EXPECT_HAS(msg, "is not a shared library (no ELF header)");
    EXPECT_HAS(msg, "libspangle_garbage.so");
}

TEST(PluginLoader, PipeTruncatedLibraryAndDataEntryAreRefusedSafely) {
    // Before: a named pipe hung dlopen, a truncated library died with SIGBUS, an entry point
    // exported as data was called and crashed.
    test::TempDir dir("unsafe_plugins");
    const std::string pipe = dir.file("libspangle_pipe.so");
    ASSERT_EQ(::mkfifo(pipe.c_str(), 0600), 0);
    EXPECT_HAS(error_of([&] { PluginLoader::open_file(pipe, "pipe"); }),
               "is not a regular file (a folder, a device or a pipe)");
    PluginLoader loader({dir.path().string()});
    EXPECT_HAS(error_of([&] { loader.open("pipe", {}); }), "is not a regular file");

    const std::string whole = broken("misnamed");
    const auto size = fs::file_size(whole);
    for (const double keep : {0.3, 0.6, 0.9}) {
        const std::string cut = dir.file("libspangle_cut.so");
        fs::copy_file(whole, cut, fs::copy_options::overwrite_existing);
        fs::resize_file(cut, static_cast<std::uintmax_t>(keep * static_cast<double>(size)));
        SCOPED_TRACE(keep);
        EXPECT_HAS(error_of([&] { PluginLoader::open_file(cut, "cut"); }), "is truncated");
    }
    EXPECT_HAS(error_of([] { PluginLoader::open_file(broken("dataentry"), "dataentry"); }),
               "its 'spangle_material_plugin' is data, not a function");
}

TEST(PluginLoader, SearchOrderCliThenEnvironmentThenBinary) {
    test::TempDir cli("plugins_cli"), env("plugins_env");
    // A broken plugin called "smooth" in the CLI directory must shadow the real one.
    fs::copy_file(broken("abi"), cli.file("libspangle_smooth.so"));
    fs::copy_file(broken("failcreate"), env.file("libspangle_failcreate.so"));
    fs::copy_file(broken("refuses"), env.file("libspangle_smooth.so"));
    ::setenv("SPANGLE_PLUGIN_PATH", (std::string("/nowhere:") + env.path().string()).c_str(), 1);
    const auto dirs = plugin_search_path({cli.path().string()});
    ::unsetenv("SPANGLE_PLUGIN_PATH");
    ASSERT_GE(dirs.size(), 4u);
    EXPECT_EQ(dirs[0], cli.path().string());
    EXPECT_EQ(dirs[1], "/nowhere");
    EXPECT_EQ(dirs[2], env.path().string());
    PluginLoader loader(dirs);
    EXPECT_HAS(error_of([&] { loader.open("smooth", {}); }), "ABI version 999");
    EXPECT_NO_THROW(loader.open("failcreate", {})) << "found through $SPANGLE_PLUGIN_PATH";
    PluginLoader without_cli(plugin_search_path({}));
    EXPECT_NO_THROW(without_cli.open("smooth", {})) << "the binary's own directory comes last";
}

/** A schema exercising every parameter type, validated without any plugin. */
const SpangleParamDesc_v3 kSchema[] = {
    {"roughness", SPANGLE_PARAM_FLOAT, {0.5, 0, 0}, nullptr, 0.0, 1.0, nullptr, "r", 0},
    {"count", SPANGLE_PARAM_INT, {4, 0, 0}, nullptr, 1.0, 64.0, nullptr, "n", 0},
    {"coat", SPANGLE_PARAM_BOOL, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "c", 0},
    {"tint", SPANGLE_PARAM_COLOR, {1, 1, 1}, nullptr, 0.0, 1.0, nullptr, "t", 0},
    {"fresnel",
     SPANGLE_PARAM_STRING,
     {0, 0, 0},
     "schlick",
     0.0,
     0.0,
     "schlick|conductor|dielectric",
     "f",
     0},
};
SpangleMaterialModel_v3 schema_model() {
    SpangleMaterialModel_v3 m{};
    m.name = "test";
    m.params = kSchema;
    m.param_count = 5;
    return m;
}

ParamEntry entry(const std::string& name, ParamEntry::Kind kind, double x, bool integer = false,
                 std::string text = {}) {
    ParamEntry p;
    p.name = name;
    p.kind = kind;
    p.number[0] = p.number[1] = p.number[2] = x;
    p.is_integer = integer;
    p.text = std::move(text);
    p.loc = FileLoc{"m.toml", 7, 3};
    p.key_loc = FileLoc{"m.toml", 7, 1};
    return p;
}

TEST(ValidateParams, DefaultsInSchemaOrder) {
    ColorConfig color = test::shipped_config();
    Material m;
    m.name = "x";
    const ValidatedParams v = validate_params(schema_model(), m, color);
    ASSERT_EQ(v.values.size(), 5u);
    EXPECT_DOUBLE_EQ(v.values[0].number[0], 0.5);
    EXPECT_DOUBLE_EQ(v.values[1].number[0], 4.0);
    EXPECT_STREQ(v.values[4].string, "schlick");
}

TEST(ValidateParams, TypesRangesAndChoices) {
    ColorConfig color = test::shipped_config();
    const auto fails = [&](ParamEntry p) {
        Material m;
        m.name = "x";
        m.params = {std::move(p)};
        return error_of([&] { validate_params(schema_model(), m, color); });
    };
    using K = ParamEntry::Kind;
    EXPECT_HAS(fails(entry("count", K::Number, 2.5)), "'count' must be an integer");
    EXPECT_HAS(fails(entry("count", K::Number, 65, true)), "'count' must be in [1, 64], got 65");
    // A large whole number as written, not rounded to seven digits (2.147484e+09).
    EXPECT_HAS(fails(entry("count", K::Number, 2147483648.0, true)),
               "'count' must be in [1, 64], got 2147483648");
    EXPECT_HAS(fails(entry("roughness", K::Number, 1.25)), "'roughness' must be in");
    EXPECT_HAS(fails(entry("coat", K::Number, 1)), "'coat' must be true or false");
    EXPECT_HAS(fails(entry("roughness", K::String, 0, false, "high")),
               "'roughness' must be a number");
    EXPECT_HAS(fails(entry("fresnel", K::String, 0, false, "fancy")),
               "'fresnel' must be one of schlick, conductor, dielectric, got \"fancy\"");
    const std::string unknown = fails(entry("roughnes", K::Number, 0.1));
    EXPECT_EQ(unknown.rfind("m.toml:7:1: error:", 0), 0u)
        << "unknown names point at the key: " << unknown;
    EXPECT_HAS(unknown,
               "has no parameter 'roughnes'; did you mean 'roughness'? (parameters: roughness, "
               "count, coat, tint, fresnel)");
}

TEST(ValidateParams, ColoursAreConvertedToTheWorkingSpace) {
    ColorConfig color = test::shipped_config();
    color.set_working_space("lin_rec709");
    Material m;
    ParamEntry p = entry("tint", ParamEntry::Kind::Color, 0.5);
    p.text = "srgb_texture";
    m.params = {p};
    const ValidatedParams v = validate_params(schema_model(), m, color);
    EXPECT_NEAR(v.values[3].number[0], 0.214041, 1e-5);
}

TEST(Materials, CreateFailureIsReportedWithThePluginsReason) {
    test::TempDir dir("failcreate");
    fs::copy_file(broken("failcreate"), dir.file("libspangle_failcreate.so"));
    PluginLoader loader({dir.path().string()});
    ColorConfig color = test::shipped_config();
    HostServices host(color, test::quiet_log());
    Material m;
    m.name = "bad";
    m.plugin = "failcreate";
    m.loc = FileLoc{"s.toml", 4, 1};
    const std::string msg = error_of([&] { create_material(loader, m, host); });
    EXPECT_EQ(msg.rfind("s.toml:4:1: error: material 'bad'", 0), 0u) << msg;
    EXPECT_HAS(msg, "could not create model 'broken': x and y cannot both be set");
}

/** A diffuse closure of the real smooth plugin, driven through the ABI. */
class DiffuseThroughAbi : public ::testing::Test {
protected:
    void SetUp() override {
        plugin_ = PluginLoader(plugin_search_path({})).open("smooth", {});
        model_ = plugin_->model("diffuse");
        ASSERT_NE(model_, nullptr);
        SpangleParamValue_v3 albedo{"albedo", SPANGLE_PARAM_COLOR, {1.0, 1.0, 1.0}, nullptr};
        SpangleParams_v3 params{&albedo, 1};
        char err[256];
        instance_ = model_->create(&params, host_.api(), err, sizeof(err));
        ASSERT_NE(instance_, nullptr) << err;
        const float zero = 0.0f, one = 1.0f;
        const float wox = 0.3f, woy = 0.0f, woz = std::sqrt(1.0f - 0.09f);
        const uint32_t flags = 0, id = 0;
        SpangleShadingBatch_v3 b{1,     &zero, &zero,  &zero, &wox,    &woy,   &woz,  &zero,
                                 &zero, &zero, &zero,  &zero, &zero,   &one,   &zero, &zero,
                                 &zero, &zero, &zero,  &one,  &zero,   &zero,  &zero, &zero,
                                 &zero, &zero, &flags, &id,   nullptr, nullptr};
        closure_.resize(model_->closure_size);
        model_->prepare(instance_, &b, closure_.data(), nullptr);
    }
    void TearDown() override {
        if (instance_) model_->destroy(instance_);
    }

    ColorConfig color_ = test::shipped_config();
    HostServices host_{color_, test::quiet_log()};
    std::shared_ptr<LoadedPlugin> plugin_;
    const SpangleMaterialModel_v3* model_ = nullptr;
    void* instance_ = nullptr;
    std::vector<std::byte> closure_;
};

TEST_F(DiffuseThroughAbi, WhiteFurnaceWithAlbedoOneIsExactlyOne) {
    constexpr uint32_t kN = 4096;
    std::vector<float> u0(kN), u1(kN), u2(kN), x(kN), y(kN), z(kN), r(kN), g(kN), b(kN), pdf(kN);
    std::vector<uint32_t> flags(kN), idx(kN, 0);
    for (uint32_t i = 0; i < kN; ++i) {
        u0[i] = sample_1d(1, i, 0, 0);
        u1[i] = sample_1d(1, i, 0, 1);
        u2[i] = sample_1d(1, i, 0, 2);
    }
    SpangleSampleBatch_v3 q{kN,           idx.data(), u0.data(), u1.data(), u2.data(), x.data(),
                            y.data(),     z.data(),   r.data(),  g.data(),  b.data(),  pdf.data(),
                            flags.data(), nullptr,    nullptr,   nullptr,   nullptr};
    model_->sample(instance_, closure_.data(), &q);
    std::vector<float> er(kN), eg(kN), eb(kN), epdf(kN);
    SpangleEvalBatch_v3 e{kN,        idx.data(), x.data(),    y.data(), z.data(), er.data(),
                          eg.data(), eb.data(),  epdf.data(), nullptr,  nullptr,  nullptr};
    model_->eval(instance_, closure_.data(), &e);
    for (uint32_t i = 0; i < kN; ++i) {
        if (flags[i] == 0) continue;  // the cosine sampler only fails exactly on the horizon
        ASSERT_GT(pdf[i], 0.0f);
        // f cos / pdf = (1/pi) cos / (cos/pi) = 1 for every sample; float rounding only.
        EXPECT_NEAR(r[i] * z[i] / pdf[i], 1.0f, 1e-5f);
        EXPECT_NEAR(epdf[i], pdf[i], 1e-6f) << "eval's pdf must equal sample's pdf";
        EXPECT_NEAR(er[i], r[i], 1e-7f);
    }
}

TEST(PluginLoader, AWatchedPluginOverwrittenInPlaceKeepsRunning) {
    // `cp new.so libspangle_x.so` writes into the file a watched render had mapped: its pages
    // changed under the process, which died of SIGBUS. A watched plugin is now mapped from a
    // private copy from its first load, as reloads always were.
    test::TempDir dir("plugin_in_place");
    fs::copy_file(broken("kernels"), dir.file("libspangle_kernels.so"));
    PluginLoader loader({dir.path().string()});
    loader.reopen_changed = true;
    loader.copy_on_first_open = true;
    const auto plugin = loader.open("kernels", {});
    EXPECT_EQ(plugin->path(), dir.file("libspangle_kernels.so")) << "named as the user's file";
    std::ofstream(dir.file("libspangle_kernels.so"), std::ios::trunc) << "not a library any more";
    EXPECT_STREQ(plugin->table().name, "kernels");
    EXPECT_STREQ(plugin->table().models[0].doc,
                 "a diffuse model whose kernels misbehave as x asks");
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(fs::temp_directory_path(), ec))
        EXPECT_EQ(e.path().filename().string().find(fmt::format("spangle-{}-", ::getpid())),
                  std::string::npos)
            << "private copy left behind: " << e.path();
}

TEST(PluginLoader, SchemasThatContradictThemselvesAreRefused) {
    // A default outside the parameter's own range was handed to create() as "validated".
    EXPECT_HAS(error_of([] { PluginLoader::open_file(broken("badschema"), "badschema"); }),
               "parameter 'x' has the default 5 outside its range [0, 1]");
    // An entry point that throws was reported as the bare exception text, and stopped
    // `spangle plugins` from listing the other plugins.
    const std::string threw =
        error_of([] { PluginLoader::open_file(broken("throwentry"), "throwentry"); });
    EXPECT_HAS(threw, "libspangle_throwentry.so");
    EXPECT_HAS(threw, "its entry point threw");
    EXPECT_HAS(threw, "boom from the entry point");
}

/** Renders a 16 x 16 quad in the `kernels` test plugin's mode (see broken_plugin.cpp). */
FrameResult render_kernels(const test::TempDir& dir, int mode) {
    const std::string scene = dir.file(fmt::format("mode{}.toml", mode));
    std::ofstream(scene) << fmt::format(R"([render]
width = 16
height = 16
spp = 4
max_depth = 3

[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]

[environment]
color = [1, 1, 1]

[[light]]
type = "distant"
direction = [0.3, -0.2, 1]
intensity = 2

[[material]]
name = "m"
plugin = "kernels"
params = {{ x = {} }}

[[object]]
mesh = "{}/scenes/uvless_ball.obj"
material = "m"
)",
                                        mode / 10.0, test::test_dir());
    FrameRequest req = test::quiet_request(scene);
    req.plugin_dirs = {SPANGLE_TEST_PLUGIN_DIR};
    req.options.threads = 1;
    req.options.layers = true;
    return render_frame(req);
}

TEST(Materials, PluginOutputsTheRendererCannotUseAreDroppedAndSaid) {
    // A NaN direction from sample() was traced (the ray escaped to the sky: +12% brighter), a
    // reflection under the surface went into the object, a pdf of 0 or a negative f was lost
    // without a word, and a glint larger than f broke beauty = rest + glints. Each bad sample is
    // now dropped as the plugin's own "no sample" would be, and said once per material.
    test::TempDir dir("plugin_outputs");
    const FrameResult none = render_kernels(dir, 7);
    EXPECT_TRUE(none.stats.plugin_problems.empty());
    const std::pair<int, const char*> sample_modes[] = {{1, "a sampled direction not finite"},
                                                        {2, "a pdf not finite, negative, or 0"},
                                                        {3, "an f negative or not finite"},
                                                        {4, "a reflection leaving on the other"}};
    for (const auto& [mode, said] : sample_modes) {
        const FrameResult r = render_kernels(dir, mode);
        EXPECT_EQ(r.image, none.image) << "mode " << mode << ": dropped like no sample at all";
        ASSERT_EQ(r.stats.plugin_problems.size(), 1u) << "mode " << mode;
        EXPECT_HAS(r.stats.plugin_problems[0], "plugin 'kernels'");
        EXPECT_HAS(r.stats.plugin_problems[0], "material 'm'");
        EXPECT_HAS(r.stats.plugin_problems[0], said);
    }
    // eval(): a NaN f is dropped as an f of 0 would be.
    const FrameResult nan_eval = render_kernels(dir, 6), zero_eval = render_kernels(dir, 10);
    EXPECT_EQ(nan_eval.image, zero_eval.image);
    EXPECT_EQ(nan_eval.stats.nonfinite, 0u);
    ASSERT_EQ(nan_eval.stats.plugin_problems.size(), 1u);
    EXPECT_HAS(nan_eval.stats.plugin_problems[0], "an f negative or not finite");
    // A glint larger than f is clamped to f: the glints layer never exceeds the beauty.
    const FrameResult good = render_kernels(dir, 0), glint = render_kernels(dir, 5);
    EXPECT_EQ(glint.image, good.image);
    ASSERT_EQ(glint.stats.plugin_problems.size(), 1u);
    EXPECT_HAS(glint.stats.plugin_problems[0], "a glint outside [0, f]");
    const auto g = std::find(glint.layer_names.begin(), glint.layer_names.end(), "glints.G");
    ASSERT_NE(g, glint.layer_names.end());
    const std::size_t nl = glint.layer_names.size(), gc = g - glint.layer_names.begin();
    for (std::size_t i = 0; i < glint.image.size() / 3; ++i)
        EXPECT_LE(glint.layers[i * nl + gc], glint.image[3 * i + 1] * 1.0001f + 1e-6f)
            << "pixel " << i;
    // An exception out of eval() names the plugin, the material and the kernel.
    const std::string threw = error_of([&] { render_kernels(dir, 8); });
    EXPECT_HAS(threw, "plugin 'kernels'");
    EXPECT_HAS(threw, "material 'm'");
    EXPECT_HAS(threw, "eval() threw an exception");
    EXPECT_HAS(threw, "boom from eval");
}

}  // namespace
}  // namespace spangle::test_plugins
