// `spangle plugins`: the plugin search path, then every plugin found with its models and their
// parameters; a plugin that cannot be opened is listed with why (exit status 1).

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/usage.h"
#include "core/error.h"
#include "shading/material.h"
#include "shading/plugin_loader.h"

namespace spangle {
namespace {

/** Lists the plugins of the search path (`dirs` first); 1 when one is not usable. */
int run_plugins(const std::vector<std::string>& dirs) {
    check_plugin_dirs(dirs);
    PluginLoader loader(plugin_search_path(dirs));
    fmt::print("plugin search path:\n");
    for (const auto& d : loader.search_path()) fmt::print("  {}\n", d);
    const auto files = loader.discover();
    if (files.empty()) fmt::print("no plugins found\n");
    // Files of the same name later on the path: a render never opens them (the first wins).
    std::map<std::string, std::vector<std::string>> shadowed;
    std::set<std::string> first;
    for (const auto& f : files) first.insert(f);
    for (const auto& dir : loader.search_path()) {
        std::error_code ec;
        for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
            const std::string name = e.path().filename().string();
            if (name.rfind("libspangle_", 0) != 0 || e.path().extension() != ".so" ||
                first.count(e.path().string()))
                continue;
            shadowed[name].push_back(e.path().string());
        }
    }
    int bad = 0;
    for (const auto& f : files) {
        const std::string file = std::filesystem::path(f).filename().string();
        for (const auto& other : shadowed[file])
            fmt::print("\n{}: not used: {} comes first on the search path\n", other, f);
        try {
            // The name a scene opens it by, as a render checks it.
            const std::string stem = std::filesystem::path(f).stem().string();
            auto p = PluginLoader::open_file(f, stem.substr(std::string("libspangle_").size()));
            const SpangleMaterialPlugin_v3& t = p->table();
            fmt::print("\n{} ({}): {}\n", t.name, f, t.doc ? t.doc : "");
            for (uint32_t m = 0; m < t.model_count; ++m) {
                const SpangleMaterialModel_v3& model = t.models[m];
                fmt::print("  model {}: {}\n", model.name, model.doc ? model.doc : "");
                for (uint32_t k = 0; k < model.param_count; ++k)
                    fmt::print("    {}\n", describe_param(model.params[k]));
            }
        } catch (const SpangleError& e) {
            fmt::print("\n{}: not usable: {}\n", f, e.what());
            ++bad;
        }
    }
    return bad > 0 ? 1 : 0;
}

}  // namespace

Command add_plugins_command(CLI::App& app) {
    auto dirs = std::make_shared<std::vector<std::string>>();
    CLI::App* sub = app.add_subcommand("plugins", "list the plugins found and their parameters");
    sub->add_option("--plugin-path", *dirs, "directory searched for plugins first (repeatable)")
        ->allow_extra_args(false);  // one folder each: the scene after it is not a folder
    return {sub, [dirs] { return run_plugins(*dirs); }};
}

}  // namespace spangle
