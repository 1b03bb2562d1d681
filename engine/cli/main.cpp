// The spangle command. The only place in Spangle that turns errors into exit codes:
//   0  success
//   1  a problem with the input (scene, mesh, plugin, output path): one message, file:line:col
//   2  bad command line
//   3  internal error (a bug in Spangle)
// Each subcommand lives in its own file (commands.h); this file registers them, refuses an
// unknown one, parses, and runs the one chosen under the policy above.

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/launcher.h"
#include "cli/signals.h"
#include "cli/usage.h"
#include "core/error.h"
#include "core/text.h"

#ifndef SPANGLE_VERSION
#define SPANGLE_VERSION "0.0.0"
#endif

namespace spangle {
namespace {

/** An unknown first word is a misspelt command, not a missing one: says so (with the nearest
 *  command and the list) and returns true. */
bool refuse_unknown_command(const CLI::App& app, int argc, char** argv) {
    if (argc < 2 || argv[1][0] == '-') return false;
    const std::string word = argv[1];
    std::vector<std::string> commands;
    for (const CLI::App* sub : app.get_subcommands({})) commands.push_back(sub->get_name());
    if (std::find(commands.begin(), commands.end(), word) != commands.end()) return false;
    fmt::print(stderr,
               "spangle: error: unknown command '{}'{} (the commands are {}; spangle --help)\n",
               word, did_you_mean(word, commands), fmt::join(commands, ", "));
    return true;
}

/** An option given an empty value (`-o ''`, an unset shell variable) is an error: it fell
 *  back to the default (`-o ''` wrote SCENE.exr) or named the working folder. Says which and
 *  returns true. */
bool refuse_empty_values(const CLI::App& app) {
    for (const CLI::App* sub : app.get_subcommands({})) {
        if (!sub->parsed()) continue;
        for (const CLI::Option* opt : sub->get_options()) {
            if (opt->count() == 0 || opt->get_expected_min() == 0) continue;  // flags
            for (const std::string& v : opt->results())
                if (v.empty()) {
                    fmt::print(stderr, "spangle: error: {} needs a value, got an empty one\n",
                               opt->get_name());
                    return true;
                }
        }
    }
    return false;
}

/** Runs the command the line chose; an error becomes its message and exit status. */
int run_chosen(const std::vector<Command>& commands) {
    try {
        for (const Command& c : commands)
            if (c.app->parsed()) return c.run();
    } catch (const UsageError& e) {
        if (launcher_info().rank == 0) print_error(e.what());  // ranks > 0: rank 0 says it
        return 2;
    } catch (const SpangleError& e) {
        print_error(e.what());
        return 1;
    } catch (const std::logic_error& e) {
        fmt::print(stderr, "spangle: {}\n", e.what());
        return 3;
    } catch (const std::bad_alloc&) {
        print_error(
            "out of memory: the process may not allocate more (the machine's memory, ulimit -v or "
            "a scheduler's memory limit); render smaller (--size, --crop parts, fewer --layers) "
            "or give it more memory");
        return 1;
    } catch (const std::exception& e) {
        print_error(e.what());
        return 1;
    }
    return 0;
}

}  // namespace
}  // namespace spangle

int main(int argc, char** argv) {
    using namespace spangle;
    install_crash_handlers();
    CLI::App app{"Spangle: a physically based renderer for glittering surfaces"};
    app.set_version_flag("--version", std::string("spangle ") + SPANGLE_VERSION);
    app.require_subcommand(1);
    // In the order --help lists them.
    const std::vector<Command> commands = {add_render_command(app, argc, argv),
                                           add_plugins_command(app),
                                           add_inspect_command(app),
                                           add_merge_command(app),
                                           add_denoise_command(app),
                                           add_flicker_command(app),
                                           add_bench_command(app),
                                           add_convert_command(app),
                                           add_new_command(app)};
    if (refuse_unknown_command(app, argc, argv)) return 2;
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // --help and --version print as CLI11 prints them; a bad command line is one line as
        // every other error ("spangle: error: --threads: Value 0 not in range 1 to 1024"), the
        // help named, exit status 2.
        if (e.get_exit_code() == 0) return app.exit(e);
        print_error(fmt::format("{} (see --help)", e.what()));
        return 2;
    }
    if (refuse_empty_values(app)) return 2;
    return run_chosen(commands);
}
