#include "accuracy_plane.h"

#include <fmt/format.h>

#include <cmath>
#include <iterator>
#include <utility>
#include <vector>

#include "accuracy_render.h"
#include "test_support.h"

namespace spangle::accuracy {
namespace {

/** Size, samples, flake realisations and threshold pairs of one run. */
struct PlanePlan {
    int size, spp, seeds;
    std::vector<std::pair<double, double>> pairs;  ///< (min_flakes, max_flakes)
};

/** The plane's scene: flakes of one realisation (`seed`) with the given thresholds. */
std::string plane_scene(const PlanePlan& pp, double min_flakes, double max_flakes,
                        const char* algorithm, int seed) {
    return fmt::format(R"([render]
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
                       pp.size, pp.spp, min_flakes, max_flakes, test::asset_dir(), algorithm, seed);
}

/** What one threshold pair gave over all realisations. */
struct PlaneRun {
    std::vector<double> lum;  ///< Rec.709 luminance of every seed's image, one after the other
    double seconds = 0;       ///< mean render time per image
    double lambda = 0, discrete = 0, blended = 0, smooth = 0;
};

/** Renders every realisation; the lobe fractions are those of the first. */
PlaneRun plane_render(Renderer& r, const PlanePlan& pp, double lo, double hi,
                      const char* algorithm) {
    PlaneRun run;
    for (int seed = 0; seed < pp.seeds; ++seed) {
        r.load(plane_scene(pp, lo, hi, algorithm, seed));
        const Pass last = r.render_passes(static_cast<uint32_t>(pp.spp), Strategy::Mis).back();
        run.seconds += last.seconds / pp.seeds;
        for (std::size_t i = 0; i < last.image.pixels(); ++i) {
            const float* c = &last.image.rgb[3 * i];
            run.lum.push_back(0.2126 * static_cast<double>(c[0]) +
                              0.7152 * static_cast<double>(c[1]) +
                              0.0722 * static_cast<double>(c[2]));
        }
        if (seed > 0) continue;
        const auto st = r.material_stats();
        const auto get = [&](const char* k) { return st.count(k) ? st.at(k) : 0.0; };
        run.lambda = get("mean expected flakes per footprint (lambda)");
        run.discrete = get("fraction discrete");
        run.blended = get("fraction blended");
        run.smooth = get("fraction smooth");
    }
    return run;
}

/** Arithmetic mean of a non-empty vector. */
double mean(const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return s / static_cast<double>(v.size());
}

/** Relative RMS difference of 4x4 block means. */
double block_error(const PlanePlan& pp, const std::vector<double>& a,
                   const std::vector<double>& ref) {
    double num = 0, den = 0;
    const auto n = static_cast<std::size_t>(pp.size);
    for (std::size_t image = 0; image + n * n <= ref.size(); image += n * n)
        for (std::size_t by = 0; by + 4 <= n; by += 4)
            for (std::size_t bx = 0; bx + 4 <= n; bx += 4) {
                double sa = 0, sr = 0;
                for (std::size_t y = by; y < by + 4; ++y)
                    for (std::size_t x = bx; x < bx + 4; ++x) {
                        sa += a[image + y * n + x];
                        sr += ref[image + y * n + x];
                    }
                num += (sa - sr) * (sa - sr);
                den += sr * sr;
            }
    return std::sqrt(num / den);
}

}  // namespace

void plane_section(std::string& md, bool quick, const std::string& work_dir, int threads) {
    const PlanePlan pp = quick ? PlanePlan{32, 2, 1, {{125, 500}, {500, 2000}}}
                               : PlanePlan{160,
                                           16,
                                           4,
                                           {{25, 100},
                                            {50, 200},
                                            {125, 500},
                                            {250, 1000},
                                            {500, 2000},
                                            {1000, 4000},
                                            {2000, 8000}}};
    auto out = std::back_inserter(md);
    fmt::format_to(
        out,
        "\n## Distance blending alone: a receding plane\n\n"
        "A plane of flakes (density 10^6 per uv square, flake roughness 0.3, gamma 2) seen at a "
        "grazing angle, {0}x{0} pixels, {1} spp, one bounce, under the studio environment and a "
        "small light: the expected count of flakes per footprint grows with the distance (its "
        "mean over the shading points is given per algorithm). Each setting renders {2} flake "
        "realisation(s) (material seeds), "
        "so that the mean is not decided by which glints one realisation happens to catch; the "
        "time is the mean per image, measured as above. The reference of each algorithm is its "
        "own render with the discrete lobe everywhere. Mean error: relative difference of mean "
        "luminance. Structure error: relative RMS difference of 4x4-pixel block means (the "
        "glitter that blending smooths away). Discrete, blended, smooth: the shares of the "
        "shading points on each lobe (`--stats`). A footprint that holds no flake reflecting the "
        "view, where flake_weight is above its chance of holding one, shows the smooth lobe at "
        "the share the flakes lack (plugins/flake/README.md, flake_weight above 1 - e^-f) and "
        "counts as smooth: the all-discrete row's smooth share is those footprints.\n",
        pp.size, pp.spp, pp.seeds);
    Renderer r(work_dir + "/plane-work.toml", threads);
    for (const char* algorithm : {"tree", "enumerate"}) {
        fmt::print(stderr, "  plane: {}\n", algorithm);
        const PlaneRun ref = plane_render(r, pp, 9e8, 1e9, algorithm);
        fmt::format_to(out, "\n### `algorithm = \"{}\"`\n\n", algorithm);
        fmt::format_to(out, "Mean expected flakes per shading point: {:.0f}.\n\n", ref.lambda);
        md +=
            "| min_flakes | max_flakes | time (s) | speed-up | discrete | blended | smooth | "
            "mean error | structure error |\n";
        md += "|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        fmt::format_to(out,
                       "| all discrete | | {:.2f} | 1.00 | {:.2f} | {:.2f} | {:.2f} | 0 | 0 |\n",
                       ref.seconds, ref.discrete, ref.blended, ref.smooth);
        const double ref_mean = mean(ref.lum);
        for (const auto& [lo, hi] : pp.pairs) {
            const PlaneRun run = plane_render(r, pp, lo, hi, algorithm);
            fmt::format_to(out,
                           "| {:.0f} | {:.0f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | "
                           "{:+.2f}% | {:.1f}% |\n",
                           lo, hi, run.seconds, ref.seconds / run.seconds, run.discrete,
                           run.blended, run.smooth, 100.0 * (mean(run.lum) - ref_mean) / ref_mean,
                           100.0 * block_error(pp, run.lum, ref.lum));
        }
    }
}

}  // namespace spangle::accuracy
