// `spangle new --mesh MODEL [-o SCENE.toml]`: a TOML scene to start from around a model someone
// brings (engine/scene/new_scene.h): the model on a ground plane under the shipped studio map and
// a key light, the camera framed on its bounds, a flake paint on it.

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/output_paths.h"
#include "cli/usage.h"
#include "core/files.h"
#include "core/log.h"
#include "scene/new_scene.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** Options of `spangle new`. */
struct NewArgs {
    std::string mesh;      ///< the model: OBJ, PLY, glTF or GLB
    std::string output;    ///< the TOML scene to write (default: MODEL's stem + .toml, here)
    std::string env;       ///< the map to light it with (default: the shipped studio map)
    bool force = false;    ///< overwrite an existing scene
    bool quiet = false;    ///< no line saying what was written
    std::string up = "y";  ///< the model's up axis
};

constexpr const char* kStudioMap = "studio_hdri.exr";

/** Where the shipped studio map may lie: beside the binary (a build tree), in an install's
 *  share/spangle/env, or in the source tree this binary was built from. */
std::vector<fs::path> studio_map_locations() {
    std::vector<fs::path> out;
    const std::string exe = executable_dir();
    if (!exe.empty()) {
        out.push_back(fs::path(exe) / "env" / kStudioMap);
        out.push_back(
            (fs::path(exe) / ".." / "share" / "spangle" / "env" / kStudioMap).lexically_normal());
    }
#ifdef SPANGLE_SOURCE_DIR
    out.push_back(fs::path(SPANGLE_SOURCE_DIR) / "assets" / "env" / kStudioMap);
#endif
    return out;
}

std::string find_studio_map() {
    std::vector<std::string> tried;
    for (const fs::path& p : studio_map_locations()) {
        std::error_code ec;
        if (fs::is_regular_file(p, ec)) return p.string();
        tried.push_back(fs::absolute(p, ec).lexically_normal().string());
    }
    throw_error("the studio map {} was not found (looked for {}); give one with --env", kStudioMap,
                fmt::join(tried, ", "));
}

int run_new(const NewArgs& a) {
    std::string output = a.output;
    if (output.empty()) output = fs::path(a.mesh).stem().string() + ".toml";
    if (fs::path(output).extension() != ".toml")
        usage_error("output '{}' must end in .toml", output);
    std::error_code ec;
    if (!a.force && fs::exists(output, ec))
        usage_error("'{}' exists; --force overwrites it", fs::absolute(output, ec).string());
    // The ground plane's PLY goes beside it (new_scene.h): not over a file of the user's either.
    const fs::path ground = fs::absolute(output, ec).lexically_normal().parent_path() /
                            (fs::path(output).stem().string() + "_ground.ply");
    if (!a.force && fs::exists(ground, ec))
        usage_error("'{}' (the scene's ground plane) exists; --force overwrites it",
                    ground.string());
    // Never over the model itself, --force or not (`new --mesh t_ground.ply -o t.toml --force`
    // replaced the user's mesh with the ground plane).
    if (same_file(ground.string(), a.mesh) || same_file(output, a.mesh))
        usage_error(
            "the scene '{}' and its ground plane '{}' would overwrite the model '{}': "
            "give another -o",
            output, ground.string(), a.mesh);
    // The shipped studio map is copied beside the scene, so that the scene does not point into
    // the folder Spangle was built or installed in (a farm node without it failed).
    const fs::path studio =
        ground.parent_path() / (fs::path(output).stem().string() + "_studio.exr");
    if (a.env.empty()) {
        if (same_file(studio.string(), a.mesh))
            usage_error(
                "the scene's studio map '{}' would overwrite the model '{}': give another -o",
                studio.string(), a.mesh);
        if (!a.force && fs::exists(studio, ec))
            usage_error("'{}' (the scene's studio map) exists; --force overwrites it",
                        studio.string());
    }
    check_writable(output, "TOML scene");
    NewSceneRequest req;
    req.model = a.mesh;
    req.output = output;
    req.env_map = a.env;
    req.up = a.up;
    if (a.env.empty()) {
        const std::string shipped = find_studio_map();
        fs::copy_file(shipped, studio, fs::copy_options::overwrite_existing, ec);
        if (ec)
            throw_error("cannot copy the studio map {} to {}: {}", shipped, studio.string(),
                        ec.message());
        req.env_map = studio.string();
    }
    NewSceneReport rep;
    try {
        rep = write_new_scene(req);
    } catch (...) {
        if (a.env.empty()) fs::remove(studio, ec);  // a failed scene leaves no map behind
        throw;
    }
    Logger log;
    if (a.quiet) log.threshold = LogLevel::Warning;
    for (const std::string& note : rep.notes) log.warn("{}", note);
    log.info(
        "wrote {} and its ground plane {}{}: the model's bounds {:.3g} x {:.3g} x {:.3g}, "
        "paint '{}' with {:.3g} flakes per square unit (about {:.0f} per pixel); render it "
        "with: spangle render {}",
        output, rep.ground, a.env.empty() ? " and studio map " + studio.string() : std::string(),
        rep.model_bounds.hi.x - rep.model_bounds.lo.x,
        rep.model_bounds.hi.y - rep.model_bounds.lo.y,
        rep.model_bounds.hi.z - rep.model_bounds.lo.z, rep.paint, rep.density, rep.flakes_per_pixel,
        shell_word(output));
    return 0;
}

}  // namespace

Command add_new_command(CLI::App& app) {
    auto a = std::make_shared<NewArgs>();
    CLI::App* sub = app.add_subcommand(
        "new", "write a scene around a model: ground, studio light, framed camera, flake paint");
    sub->add_option("--mesh", a->mesh, "the model: an OBJ, PLY, glTF or GLB file")->required();
    sub->add_option("-o,--output", a->output,
                    "the TOML scene to write (default: the model's name with .toml, here)");
    sub->add_option("--env", a->env,
                    "a lat-long map (EXR, HDR) to light it (default: the shipped studio map)");
    sub->add_option("--up", a->up,
                    "the model's up axis: y (glTF's, the default), z (CAD, 3ds Max, many scans), "
                    "x, -x, -y or -z; the scene turns it to stand up")
        ->check(CLI::IsMember({"y", "z", "x", "-x", "-y", "-z", "+x", "+y", "+z"}));
    sub->add_flag("--force", a->force, "overwrite an existing scene file");
    sub->add_flag("-q,--quiet", a->quiet, "no info output");
    return {sub, [a] { return run_new(*a); }};
}

}  // namespace spangle
