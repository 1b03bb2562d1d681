// `spangle inspect IMAGE`: the image's size, mean luminance, non-finite and negative pixels, and
// fireflies (pixels above 10x the median of their 3x3 neighbourhood).

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "color/image_io.h"
#include "core/error.h"
#include "render/image_metrics.h"

namespace spangle {
namespace {

/** Measures and prints the image at `path`. */
int run_inspect(const std::string& path) {
    ImageHeader spec;
    const std::vector<float> all = read_image(path, 3, spec);
    if (spec.channels < 3) throw_error("'{}' has {} channels; expected RGB", path, spec.channels);
    const std::vector<float>& rgb = all;
    const ImageMetrics m = measure_image(rgb, spec.width, spec.height);
    fmt::print("{}: {}x{}\n", path, spec.width, spec.height);
    fmt::print("mean luminance: {:.6g}\nnon-finite pixels: {}\nnegative pixels: {}\n",
               m.mean_luminance, m.nonfinite, m.negative);
    fmt::print("fireflies (> 10x the 3x3 median): {} ({:.4f}% of pixels)\n", m.fireflies,
               100.0 * m.firefly_fraction);
    return 0;
}

}  // namespace

Command add_inspect_command(CLI::App& app) {
    auto path = std::make_shared<std::string>();
    CLI::App* sub =
        app.add_subcommand("inspect", "measure an image: mean, non-finite pixels, fireflies");
    sub->add_option("image", *path, "EXR (or any image OpenImageIO reads, through its module)")
        ->required();
    return {sub, [path] { return run_inspect(*path); }};
}

}  // namespace spangle
