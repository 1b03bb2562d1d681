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
/** Flake realisations (material seeds) per setting: one realisation's glints under a small light
 *  move the image mean by a percent or two, more than blending does. */
constexpr int kSeeds = 4;

std::string scene_text(double min_flakes, double max_flakes, const char* algorithm, int seed) {
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
params = {{ base_color = 0.0, flake_weight = 1.0, density = 1000000, flake_roughness = 0.3, gamma = 2, min_flakes = {2}, max_flakes = {3}, algorithm = "{5}", seed = {6} }}

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
                       kSize, kSpp, min_flakes, max_flakes, test::asset_dir(), algorithm, seed);
}

struct Run {
    std::vector<double> lum;
    double seconds = 0;
    double lambda_mean = 0, discrete = 0, blended = 0, smooth = 0;
};

Run render_once(double min_flakes, double max_flakes, const char* algorithm, int seed) {
    const std::filesystem::path path =
        std::filesystem::temp_directory_path() / "spangle_accuracy.toml";
    std::ofstream(path) << scene_text(min_flakes, max_flakes, algorithm, seed);
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

/** kSeeds realisations, their images one after the other; the time is the mean per image. */
Run render(double min_flakes, double max_flakes, const char* algorithm) {
    Run all = render_once(min_flakes, max_flakes, algorithm, 0);
    for (int seed = 1; seed < kSeeds; ++seed) {
        const Run r = render_once(min_flakes, max_flakes, algorithm, seed);
        all.lum.insert(all.lum.end(), r.lum.begin(), r.lum.end());
        all.seconds += r.seconds;
    }
    all.seconds /= kSeeds;
    return all;
}

double mean(const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return s / static_cast<double>(v.size());
}

/** Relative RMS difference of 4x4 block means. */
double block_error(const std::vector<double>& a, const std::vector<double>& ref) {
    double num = 0, den = 0;
    const std::size_t pixels = static_cast<std::size_t>(kSize) * kSize;
    for (std::size_t image = 0; image + pixels <= ref.size(); image += pixels)
        for (int by = 0; by < kSize; by += 4)
            for (int bx = 0; bx < kSize; bx += 4) {
                double sa = 0, sr = 0;
                for (int y = by; y < by + 4; ++y)
                    for (int x = bx; x < bx + 4; ++x) {
                        sa += a[image + static_cast<std::size_t>(y * kSize + x)];
                        sr += ref[image + static_cast<std::size_t>(y * kSize + x)];
                    }
                num += (sa - sr) * (sa - sr);
                den += sr * sr;
            }
    return std::sqrt(num / den);
}

/** One table: the all-discrete reference and the blending pairs, for one algorithm. Returns the
 *  reference's time over the default pair's (500, 2000). */
double table(const char* algorithm) {
    const Run ref = render(9e8, 1e9, algorithm);  // the discrete lobe everywhere
    fmt::print("\n## `algorithm = \"{}\"`\n\n", algorithm);
    fmt::print("Mean expected flakes per shading point: {:.0f}.\n\n", ref.lambda_mean);
    fmt::print(
        "| min_flakes | max_flakes | time (s) | speed-up | discrete | blended | smooth | mean "
        "error | structure error |\n");
    fmt::print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    fmt::print("| all discrete | | {:.2f} | 1.00 | {:.2f} | {:.2f} | {:.2f} | 0 | 0 |\n",
               ref.seconds, ref.discrete, ref.blended, ref.smooth);
    const double ref_mean = mean(ref.lum);
    const std::pair<double, double> pairs[] = {{25, 100},   {50, 200},    {125, 500},  {250, 1000},
                                               {500, 2000}, {1000, 4000}, {2000, 8000}};
    double speedup_default = 1.0;
    for (const auto& [lo, hi] : pairs) {
        const Run r = render(lo, hi, algorithm);
        if (lo == 500) speedup_default = ref.seconds / r.seconds;
        fmt::print(
            "| {:.0f} | {:.0f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:+.2f}% | {:.1f}% "
            "|\n",
            lo, hi, r.seconds, ref.seconds / r.seconds, r.discrete, r.blended, r.smooth,
            100.0 * (mean(r.lum) - ref_mean) / ref_mean, 100.0 * block_error(r.lum, ref.lum));
    }
    return speedup_default;
}

}  // namespace
}  // namespace spangle

int main() {
    using namespace spangle;
    fmt::print("# Flake distance blending: accuracy against time\n\n");
    fmt::print(
        "Regenerate with `./build/spangle_accuracy > docs/accuracy.md` (a Release build; the\n"
        "figures below were measured on the 2-core development machine).\n\n");
    fmt::print(
        "A plane of flakes (density 10^6 per uv square, flake roughness 0.3, gamma 2) seen at a\n"
        "grazing angle, {0}x{0} pixels, {1} spp, under the studio environment and a small light:\n"
        "the expected count per footprint grows from tens near the camera to many thousands at\n"
        "the horizon. Each setting renders {2} flake realisations (seeds), so that the mean is "
        "not\n"
        "decided by which glints one realisation happens to catch. The reference keeps the\n"
        "discrete lobe everywhere. Mean error: relative difference of mean luminance. Structure\n"
        "error: relative RMS difference of 4x4-pixel block means (the glitter that blending\n"
        "smooths away). Each algorithm is compared with its own all-discrete render.\n",
        kSize, kSpp, kSeeds);
    const double tree = table("tree");
    const double enumerate = table("enumerate");
    fmt::print(
        "\nReading: the mean error stays small at every setting because the smooth lobe is the\n"
        "discrete lobe's expectation (what remains is mostly which glints the small light\n"
        "catches in {} realisations). With `enumerate` the default blending (500, 2000) is\n"
        "{:.1f}x faster than the discrete lobe everywhere; with `tree`, whose cost does not grow\n"
        "with the flake count, it is {:.1f}x: there the thresholds choose how much glitter\n"
        "survives at a distance rather than buying time. The shipped defaults are\n"
        "min_flakes = 500, max_flakes = 2000.\n",
        kSeeds, enumerate, tree);
    return 0;
}
