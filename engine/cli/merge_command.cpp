// `spangle merge PARTS -o FULL.exr`: crop windows (render --crop) assembled, or sample ranges
// (render --spp-range) added, into the whole render, bit for bit (docs/crop_merge.md).

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/output_paths.h"
#include "cli/signals.h"
#include "cli/usage.h"
#include "color/image_merge.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** Options of `spangle merge`. */
struct MergeArgs {
    std::vector<std::string> parts;  ///< the parts' EXR files
    std::string output;              ///< the full frame's EXR
};

/** Checks the output (not a part, an .exr, writable), merges and says what it did. */
int run_merge(const MergeArgs& a) {
    for (const std::string& p : a.parts)
        if (same_file(p, a.output)) usage_error("the output '{}' is one of the parts", a.output);
    prepare_exr_output(a.output);
    install_exit_on_stop_signal();  // nothing polls: a stop signal ends it at once
    const MergeReport rep = merge_exr_parts(a.parts, a.output);
    // A stopped part makes a partial whole (its header says so too): said, not left to be found.
    for (const std::string& p : rep.partial_parts)
        fmt::print(stderr,
                   "warning: '{}' is partial (its render stopped before its last sample: a stop "
                   "signal, or a pass image left by a render that was killed): {} is partial too "
                   "(spangle:partial = 1)\n",
                   p, a.output);
    if (rep.infinite > 0)
        fmt::print(stderr,
                   "warning: {} values of R, G and B in {} are infinite, as the parts hold them: "
                   "values beyond a half float's 65504 (render the parts with --float)\n",
                   rep.infinite, a.output);
    if (rep.nan > 0)
        fmt::print(stderr,
                   "warning: {} values of R, G and B in {} are NaN, as the parts hold them: a "
                   "render writes none, so a part was written or changed by another program\n",
                   rep.nan, a.output);
    if (rep.sample_ranges > 0) {
        fmt::print("added {} sample ranges into {} ({}x{} frame)\n", rep.sample_ranges, a.output,
                   rep.width, rep.height);
        return 0;
    }
    fmt::print("merged {} parts into {} ({}x{}{})\n", rep.parts, a.output, rep.width, rep.height,
               rep.overlap_pixels
                   ? fmt::format(", {} pixels held by more than one part", rep.overlap_pixels)
                   : std::string());
    return 0;
}

}  // namespace

Command add_merge_command(CLI::App& app) {
    auto a = std::make_shared<MergeArgs>();
    CLI::App* sub = app.add_subcommand(
        "merge",
        "assemble crop windows (render --crop) or add sample ranges (render --spp-range) into "
        "the whole render, bit for bit");
    sub->add_option("parts", a->parts, "the parts' EXR files")->required();
    sub->add_option("-o,--output", a->output, "the full frame's EXR")->required();
    return {sub, [a] { return run_merge(*a); }};
}

}  // namespace spangle
