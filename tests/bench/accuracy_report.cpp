// What the flake material's distance blending costs and saves: a tilted plane of flakes, whose
// expected flake count per pixel footprint grows from tens near the camera to thousands at the
// horizon, rendered with the discrete lobe everywhere (the reference) and with several
// (min_flakes, max_flakes) pairs. For each: render time and the error against the reference.
//
//     ./build/spangle_accuracy > docs/accuracy.md
//
// Error measures: the relative difference of mean luminance (blending must not change the
// average: the smooth lobe is the discrete one's expectation), and the relative RMS difference of
// 4x4-pixel block means (how much of the glitter's structure survives). Block means are used
// because per-pixel glints are what blending is allowed to smooth away at large counts.

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include "render/frame.h"
#include "test_support.h"

namespace spangle {
namespace {

constexpr int kSize = 160;
constexpr int kSpp = 16;

std::string scene_text(double min_flakes, double max_flakes) {
    return fmt::format(R"(
[render]
width = {0}
height = {0}
spp = {1}
max_depth = 1
filter = "box"
working_space = "lin_rec709"

[environment]
map = "{4}/env/studio.exr"
color_space = "lin_rec709"

[camera]
position = [0, 0.25, 1.5]
look_at = [0, 0.05, -4]
fov = 50

[[material]]
name = "glitter"
plugin = "flake"
params = {{ base_color = 0.0, flake_weight = 1.0, density = 1000000, flake_roughness = 0.3, gamma = 2, min_flakes = {2}, max_flakes = {3} }}

[[object]]
mesh = "{4}/meshes/plane.ply"
material = "glitter"
scale = 40

[[light]]
type = "sphere"
center = [0.3, 1.2, 1.8]
radius = 0.05
intensity = 2000
)",
                       kSize, kSpp, min_flakes, max_flakes, test::asset_dir());
}

struct Run {
    std::vector<double> lum;
    double seconds = 0;
    double lambda_mean = 0, discrete = 0, blended = 0, smooth = 0;
};

Run render_once(double min_flakes, double max_flakes) {
    const std::filesystem::path path =
        std::filesystem::temp_directory_path() / "spangle_accuracy.toml";
    std::ofstream(path) << scene_text(min_flakes, max_flakes);
    FrameRequest req;
    req.scene = path.string();
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    const FrameResult r = render_frame(req);
    Run out;
    out.seconds = r.stats.seconds;
    out.lum.resize(r.image.size() / 3);
    for (std::size_t i = 0; i < out.lum.size(); ++i)
        out.lum[i] =
            0.2126 * r.image[3 * i] + 0.7152 * r.image[3 * i + 1] + 0.0722 * r.image[3 * i + 2];
    for (const auto& [name, values] : r.material_stats)
        for (const auto& [key, value] : values) {
            if (key == "mean expected flakes per footprint (lambda)") out.lambda_mean = value;
            if (key == "fraction discrete") out.discrete = value;
            if (key == "fraction blended") out.blended = value;
            if (key == "fraction smooth") out.smooth = value;
        }
    return out;
}

/** The best time of two runs (the images are identical: rendering is deterministic). */
Run render(double min_flakes, double max_flakes) {
    Run a = render_once(min_flakes, max_flakes);
    const Run b = render_once(min_flakes, max_flakes);
    a.seconds = std::min(a.seconds, b.seconds);
    return a;
}

double mean(const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return s / static_cast<double>(v.size());
}

/** Relative RMS difference of 4x4 block means. */
double block_error(const std::vector<double>& a, const std::vector<double>& ref) {
    double num = 0, den = 0;
    for (int by = 0; by < kSize; by += 4)
        for (int bx = 0; bx < kSize; bx += 4) {
            double sa = 0, sr = 0;
            for (int y = by; y < by + 4; ++y)
                for (int x = bx; x < bx + 4; ++x) {
                    sa += a[static_cast<std::size_t>(y * kSize + x)];
                    sr += ref[static_cast<std::size_t>(y * kSize + x)];
                }
            num += (sa - sr) * (sa - sr);
            den += sr * sr;
        }
    return std::sqrt(num / den);
}

}  // namespace
}  // namespace spangle

int main() {
    using namespace spangle;
    const Run ref = render(9e6, 1e7);  // the discrete lobe everywhere (the schema allows up to 1e7)
    fmt::print("# Flake distance blending: accuracy against time\n\n");
    fmt::print(
        "Regenerate with `./build/spangle_accuracy > docs/accuracy.md` (a Release build; the\n"
        "figures below were measured on the 2-core development machine).\n\n");
    fmt::print(
        "A plane of flakes (density 10^6 per uv square, flake roughness 0.3, gamma 2) seen at a\n"
        "grazing angle, {0}x{0} pixels, {1} spp, under the studio environment and a small light,\n"
        "so that the image's mean is not decided by a handful of glints: the expected count per\n"
        "footprint grows from tens near the camera to many thousands at the horizon (mean over\n"
        "shading points {2:.0f}). The reference keeps the discrete lobe everywhere. Mean error:\n"
        "relative difference of the image's mean luminance. Structure error: relative RMS\n"
        "difference of 4x4-pixel block means (the glitter that blending smooths away).\n\n",
        kSize, kSpp, ref.lambda_mean);
    fmt::print(
        "| min_flakes | max_flakes | time (s) | speed-up | discrete | blended | smooth | mean "
        "error | structure error |\n");
    fmt::print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    fmt::print("| all discrete | | {:.2f} | 1.00 | {:.2f} | {:.2f} | {:.2f} | 0 | 0 |\n",
               ref.seconds, ref.discrete, ref.blended, ref.smooth);
    const double ref_mean = mean(ref.lum);
    const std::pair<double, double> pairs[] = {{25, 100},   {50, 200},    {125, 500},  {250, 1000},
                                               {500, 2000}, {1000, 4000}, {2000, 8000}};
    for (const auto& [lo, hi] : pairs) {
        const Run r = render(lo, hi);
        fmt::print(
            "| {:.0f} | {:.0f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:+.2f}% | {:.1f}% "
            "|\n",
            lo, hi, r.seconds, ref.seconds / r.seconds, r.discrete, r.blended, r.smooth,
            100.0 * (mean(r.lum) - ref_mean) / ref_mean, 100.0 * block_error(r.lum, ref.lum));
    }
    fmt::print(
        "\nReading: the mean error stays small at every setting because the smooth lobe is the\n"
        "discrete lobe's expectation; what lower thresholds trade for time is glitter structure\n"
        "at a distance. The shipped defaults are min_flakes = 500, max_flakes = 2000.\n");
    return 0;
}
