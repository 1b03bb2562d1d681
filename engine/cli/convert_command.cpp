// `spangle convert SCENE -o OUT.toml`: any scene Spangle reads (with its imports) written as a
// TOML scene to start editing from, the meshes the scene file held itself as PLY files in
// OUT_meshes/ beside it. The TOML renders the same image as the scene, bit for bit.

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "cli/output_paths.h"
#include "cli/usage.h"
#include "core/error.h"
#include "core/log.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/scene_loader.h"
#include "scene/toml_scene_writer.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** Options of `spangle convert`. */
struct ConvertArgs {
    std::string scene;   ///< the scene file to read
    std::string output;  ///< the TOML file to write
    std::string camera;  ///< the camera of a file with several (by name)
    std::string env;     ///< a lat-long map instead of the scene's environment
    bool quiet = false;  ///< no line saying what was written
    bool force = false;  ///< write over an existing TOML scene
};

int run_convert(const ConvertArgs& a) {
    if (fs::path(a.output).extension() != ".toml")
        usage_error("output '{}' must end in .toml", a.output);
    if (same_file(a.output, a.scene)) usage_error("the output '{}' is the scene file", a.output);
    check_writable(a.output, "TOML scene");
    // A converted scene is where editing starts: converting again over it would lose the edits.
    std::error_code exists_ec;
    if (!a.force && fs::exists(a.output, exists_ec))
        usage_error("'{}' exists; --force writes over it",
                    fs::absolute(a.output, exists_ec).string());
    SceneDescription scene = read_scene(a.scene, SceneReadOptions{a.camera, a.env});
    Logger log;
    if (a.quiet) log.threshold = LogLevel::Warning;
    for (const std::string& note : scene.notes) log.warn("{}", note);
    const fs::path out(a.output);
    const fs::path meshes = out.parent_path() / (out.stem().string() + "_meshes");
    // Images a glTF held itself (data URIs, a .glb's buffer views) were written to the user's
    // cache for the texture system: copied beside the meshes, so that the converted scene moves
    // whole (it named the cache, and broke on another machine or when the cache was cleared).
    std::error_code ec;
    std::vector<fs::path> caches;
    for (const std::string& dir : gltf_embedded_image_dirs())
        caches.push_back(fs::absolute(dir, ec).lexically_normal());
    std::size_t images = 0;
    const auto carry = [&](TextureDesc& t) {
        if (t.path.empty()) return;  // vertex colours alone
        const fs::path from = fs::absolute(t.path, ec).lexically_normal();
        if (std::find(caches.begin(), caches.end(), from.parent_path()) == caches.end()) return;
        fs::create_directories(meshes, ec);
        const fs::path to = meshes / from.filename();
        if (!fs::exists(to, ec)) {
            fs::copy_file(from, to, ec);
            if (ec)
                throw_error("cannot copy the embedded image {} to {}: {}", from.string(),
                            to.string(), ec.message());
            ++images;
        }
        t.path = to.string();
    };
    for (MaterialDesc& m : scene.materials) {
        for (ParamDesc& p : m.params)
            if (p.kind == ParamDesc::Kind::Texture) carry(p.texture);
        for (ParamDesc& p : m.maps)
            if (p.kind == ParamDesc::Kind::Texture) carry(p.texture);
        if (m.alpha && m.alpha->kind == ParamDesc::Kind::Texture) carry(m.alpha->texture);
    }
    for (ObjectDesc& o : scene.objects)
        if (o.emission && o.emission->texture) carry(*o.emission->texture);
    const SceneWriteReport rep = write_toml_scene(scene, a.output, meshes.string());
    std::string beside;
    if (!rep.meshes.empty())
        beside = fmt::format("{} mesh{}", rep.meshes.size(), rep.meshes.size() == 1 ? "" : "es");
    if (images > 0)
        beside += fmt::format("{}{} image{}", beside.empty() ? "" : " and ", images,
                              images == 1 ? "" : "s");
    log.info(
        "wrote {}{}", a.output,
        beside.empty() ? std::string() : fmt::format(" and {} in {}", beside, meshes.string()));
    return 0;
}

}  // namespace

Command add_convert_command(CLI::App& app) {
    auto a = std::make_shared<ConvertArgs>();
    CLI::App* sub = app.add_subcommand(
        "convert", "write any scene Spangle reads as a TOML scene (its meshes as PLY beside it)");
    sub->add_option("scene", a->scene, "scene file (any format Spangle reads)")->required();
    sub->add_option("-o,--output", a->output, "the TOML scene to write")->required();
    sub->add_option("--camera", a->camera, "the camera of a file with several, by name");
    sub->add_option("--env", a->env, "a lat-long image (EXR, HDR) instead of the environment")
        ->check(CLI::ExistingFile);
    sub->add_flag("-q,--quiet", a->quiet, "no info output");
    sub->add_flag("--force", a->force,
                  "write over an existing TOML scene (a converted scene is where edits start)");
    return {sub, [a] { return run_convert(*a); }};
}

}  // namespace spangle
