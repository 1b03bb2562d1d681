#pragma once
// The subcommands of `spangle`, one file each. Each registers its options on the CLI11 app,
// bound to arguments it owns, and returns how it runs once the command line is parsed; main.cpp
// registers them in the order --help lists them and runs the one chosen. A new command is a new
// <name>_command.cpp with its add_ function here and one line in main.cpp.
//
//   render   render_command.cpp (one-shot; --frames, --watch and MPI ranks run their own mode)
//   plugins  plugins_command.cpp      inspect  inspect_command.cpp
//   merge    merge_command.cpp        flicker  flicker_command.cpp
//   bench    bench_command.cpp        convert  convert_command.cpp
//   new      new_command.cpp          denoise  denoise_command.cpp

#include <functional>

namespace CLI {
class App;
}

namespace spangle {

/** A subcommand registered on the app. */
struct Command {
    CLI::App* app = nullptr;   ///< the subcommand, owned by the main app
    std::function<int()> run;  ///< runs it once parsed: the exit status, or throws (see main.cpp)
};

/** `spangle render`. argc and argv are main's: MPI may start from them. */
Command add_render_command(CLI::App& app, int& argc, char**& argv);
/** `spangle plugins`: the plugins found and their parameters. */
Command add_plugins_command(CLI::App& app);
/** `spangle inspect`: an image's mean, non-finite pixels and fireflies. */
Command add_inspect_command(CLI::App& app);
/** `spangle merge`: crop windows or sample ranges into the whole render. */
Command add_merge_command(CLI::App& app);
/** `spangle denoise`: a render written with --layers denoised (a merged frame). */
Command add_denoise_command(CLI::App& app);
/** `spangle flicker`: how glints flicker over a rendered sequence. */
Command add_flicker_command(CLI::App& app);
/** `spangle bench`: fixed scenes measured. */
Command add_bench_command(CLI::App& app);
/** `spangle convert`: any scene written as a TOML scene. */
Command add_convert_command(CLI::App& app);
/** `spangle new`: a scene to start from around a model. */
Command add_new_command(CLI::App& app);

}  // namespace spangle
