// `spangle flicker FRAMES...`: how glints flicker in a sequence rendered with --frames --layers
// (color/flicker.h measures; this prints the figures).

#include <fmt/format.h>
#include <cmath>
#include <cstdlib>

#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "color/flicker.h"
#include "core/error.h"

namespace spangle {
namespace {

/** Options of `spangle flicker`. */
struct FlickerArgs {
    std::vector<std::string> frames;  ///< the frames' EXRs, in order
    double threshold = 0.0;           ///< glint-mask threshold; 0 = 4 x the glints' mean
};

/** Measures the sequence and prints its figures. */
int run_flicker(const FlickerArgs& a) {
    const FlickerReport r = measure_flicker(a.frames, a.threshold);
    // No pixel of one frame lands on a pixel of the next (frames of different scenes or
    // cameras, or no glints layer's points in view): every figure would read as perfect.
    if (!(r.pixels > 0.0))
        throw_error(
            "no pixel of a frame could be followed into the next one, so nothing was compared: "
            "are these frames of one sequence, rendered with --frames --layers?");
    // No glint anywhere: the figures below would read as "every glint flickers".
    if (!(r.mask_fraction > 0.0))
        throw_error(
            "no glint in these frames (their glints layers hold nothing above the threshold "
            "{:.4g}): "
            "nothing to measure; render a flake material with --layers",
            r.threshold);
    if (r.nonfinite_glints > 0)
        fmt::print(stderr,
                   "spangle: warning: {} glint pixels of the frames are not finite (NaN, or "
                   "infinity: brighter than a half float's 65504, rendered without --float) and "
                   "are left out of every figure below, which then understate the glints\n",
                   r.nonfinite_glints);
    // Steps between frames' times within 1% of each other (the times are printed with
    // enough digits to keep equal steps equal).
    if (r.step_max > 1.01 * r.step_min && r.step_max > r.step_min + 1e-9)
        fmt::print(stderr,
                   "spangle: warning: the frames are not evenly spaced in time (steps from {:.4g} "
                   "s to {:.4g} s): is a frame missing? A pair across the gap compares frames "
                   "further apart, and flickers more\n",
                   r.step_min, r.step_max);
    if (r.blurred > 0)
        fmt::print(
            "{} of the {} frames were rendered with motion blur: their glints are streaks, so "
            "the figures below say little of flicker (compare frames rendered without a "
            "shutter)\n",
            r.blurred, a.frames.size());
    if (r.reordered)
        fmt::print(
            "frames taken in the order of their spangle:time, not as given (a shell's glob puts "
            "frame -003 after -001)\n");
    fmt::print(
        "frames: {} ({} pairs), pixels compared: {:.0f} (points carried by {})\n"
        "glint mask threshold: {:.4g}, mask coverage: {:.4f}\n"
        "mask flicker (mean |mask_k - mask_k+1| of reprojected pixels): {:.4f}\n"
        "glint persistence (glint pixels still glints in the next frame): {:.4f}\n"
        "relative glint difference (mean |g_k - g_k+1| / mean g): {:.4f}\n",
        a.frames.size(), r.pairs, r.pixels,
        r.by_rest      ? "their objects, a deforming one's by their rest position"
        : r.by_objects ? "their objects"
                       : "world position",
        r.threshold, r.mask_fraction, r.mask_flicker, r.mask_persistence, r.relative_difference);
    return 0;
}

}  // namespace

Command add_flicker_command(CLI::App& app) {
    auto a = std::make_shared<FlickerArgs>();
    CLI::App* sub = app.add_subcommand(
        "flicker", "measure how glints flicker in a sequence rendered with --frames --layers");
    sub->add_option("frames", a->frames, "the frames' EXRs, in order")->required();
    sub->add_option("--threshold", a->threshold,
                    "glint-mask threshold (glints layer luminance; default 4 x its mean)")
        ->check(CLI::Validator(
            [](std::string& text) -> std::string {
                // Range() let 0 and nan through, which then meant the default without a word.
                const double v = std::strtod(text.c_str(), nullptr);
                return std::isfinite(v) && v > 0.0
                           ? std::string()
                           : "must be a positive number (leave it out for 4 x the glints' mean)";
            },
            "POSITIVE"));
    return {sub, [a] { return run_flicker(*a); }};
}

}  // namespace spangle
