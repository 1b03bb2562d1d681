#pragma once
// Helpers shared by the flake model's tests: the material through the real ABI (BsdfHarness) with
// flake-friendly defaults, footprints of a given expected count, and directions.

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "../common/microfacet.h"
#include "bsdf_harness.h"
#include "core/hash.h"
#include "counted_lobe.h"

namespace spangle::test {

using FlakeParams = std::vector<std::pair<std::string, std::vector<double>>>;
using FlakeStrings = std::vector<std::pair<std::string, std::string>>;

/** Density of the test materials, flakes per uv unit square. */
constexpr double kTestDensity = 1e5;

/** A flake material, flakes only (no base), density kTestDensity. With `discrete` the discrete
 *  lobe is kept for every footprint (the smooth lobe is reached by preparing without
 *  differentials). Named `algorithm = "tree"`, the counting algorithm itself: its enumeration of
 *  footprints that light their directions sparsely (`sparse_flakes`) is off unless `extra` sets
 *  it, so that tests of the counting keep counting (test_flake_sparse.cpp tests that rule; the
 *  default algorithm, not named, has it on). */
inline std::unique_ptr<BsdfHarness> flake_material(bool discrete, FlakeParams extra = {},
                                                   FlakeStrings strings = {}) {
    FlakeParams p = {{"flake_weight", {1.0}}, {"base_color", {0.0}}, {"density", {kTestDensity}}};
    if (discrete) {
        p.push_back({"min_flakes", {5e8}});
        p.push_back({"max_flakes", {1e9}});
    }
    const bool named_tree = std::any_of(strings.begin(), strings.end(), [](const auto& s) {
        return s.first == "algorithm" && s.second == "tree";
    });
    const bool sets_sparse = std::any_of(extra.begin(), extra.end(),
                                         [](const auto& e) { return e.first == "sparse_flakes"; });
    if (named_tree && !sets_sparse) p.push_back({"sparse_flakes", {0.0}});
    for (auto& e : extra) p.push_back(e);
    return std::make_unique<BsdfHarness>("flake", "flake", p, strings);
}

/** Unit direction with the given cosine and azimuth. */
inline Vec3 dir(float cos_t, float phi) {
    const float s = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
    return {s * std::cos(phi), s * std::sin(phi), cos_t};
}

/** dir() as the plugins' own vector type, for tests that call the flake model's parts directly. */
inline mf::V3 fdir(float cos_t, float phi) {
    const Vec3 d = dir(cos_t, phi);
    return {d.x, d.y, d.z};
}

/** The mirror direction of wo about the normal. */
inline Vec3 mirror(Vec3 wo) {
    return {-wo.x, -wo.y, wo.z};
}

/** A fan of directions around r: r offset by (step a, step b) for a, b in [-half, half],
 *  normalised, those above min_z. */
inline std::vector<Vec3> fan(Vec3 r, float step, int half, float min_z) {
    std::vector<Vec3> out;
    for (int a = -half; a <= half; ++a)
        for (int b = -half; b <= half; ++b) {
            const Vec3 d = normalize(
                Vec3(r.x + step * static_cast<float>(a), r.y + step * static_cast<float>(b), r.z));
            if (d.z > min_z) out.push_back(d);
        }
    return out;
}

/** The correlation over footprints of f in the same direction between two sets of the same
 *  footprints' f (x[k][j], y[k][j]: footprint k, direction j), the mean over the directions (a
 *  direction that varies in neither counts 0). */
inline double mean_correlation(const std::vector<std::vector<float>>& x,
                               const std::vector<std::vector<float>>& y) {
    const std::size_t nd = x.empty() ? 0 : x[0].size();
    const double n = static_cast<double>(x.size());
    double corr = 0.0;
    for (std::size_t j = 0; j < nd; ++j) {
        double mx = 0, my = 0, cxy = 0, cxx = 0, cyy = 0;
        for (std::size_t k = 0; k < x.size(); ++k) {
            const double a = x[k][j], b = y[k][j];
            mx += a;
            my += b;
            cxy += a * b;
            cxx += a * a;
            cyy += b * b;
        }
        mx /= n;
        my /= n;
        const double vx = cxx / n - mx * mx, vy = cyy / n - my * my;
        corr += vx > 0 && vy > 0 ? (cxy / n - mx * my) / std::sqrt(vx * vy) : 0.0;
    }
    return nd > 0 ? corr / static_cast<double>(nd) : 0.0;
}

/** A square footprint of expected count lambda (density kTestDensity) centred at (u, v). */
inline BsdfHarness::Point footprint(double lambda, float u, float v) {
    BsdfHarness::Point pt;
    const double side = std::sqrt(lambda / kTestDensity);
    pt.u = u;
    pt.v = v;
    pt.dudx = static_cast<float>(side);
    pt.dvdy = static_cast<float>(side);
    return pt;
}

/** The k-th of a series of random footprint centres (fixed seed `seed`), spread over 100 tiles
 *  so that footprints are independent realisations. */
inline BsdfHarness::Point random_footprint(double lambda, uint64_t seed, uint64_t k) {
    return footprint(lambda, static_cast<float>(to_unit_double(hash2(seed, 2 * k)) * 100.0),
                     static_cast<float>(to_unit_double(hash2(seed, 2 * k + 1)) * 100.0));
}

/** The smooth lobe's f at each wi (prepared without differentials). */
inline std::vector<Vec3> smooth_f(BsdfHarness& m, Vec3 wo, const std::vector<Vec3>& wis) {
    BsdfHarness::Point sp;
    sp.has_differentials = false;
    m.prepare(wo, sp);
    std::vector<Vec3> f;
    std::vector<float> pdf;
    m.eval(wis, f, pdf);
    return f;
}

/** Directional albedo of the prepared closure: mean of f cos / pdf over n samples. */
inline double albedo(const BsdfHarness& m, uint32_t n, uint64_t seed, int channel = 1) {
    return m.albedo(n, seed, channel).mean;
}

/** The footprint size (expected flakes) at which the default tree's discrete lobe, seen from
 *  cos_o (t = 0), is half enumerated and half counted (flake::sparse_share() at 1/2), for flakes
 *  of roughness alpha and a cone of gamma_deg degrees: found by bisection on the plugin's own
 *  table. */
inline double half_faded_lambda(float alpha, float gamma_deg, float cos_o) {
    namespace fl = spangle::flake;
    fl::DirectionGrid grid;
    grid.init(alpha, gamma_deg * 3.14159265358979f / 180.0f);
    double lo = 1.0, hi = fl::kSparseEnumerate;  // share 1 at lo, 0 at hi
    for (int i = 0; i < 40; ++i) {
        const double mid = std::sqrt(lo * hi);
        (fl::sparse_share(fl::kSparseFlakes, grid, cos_o, mid, 0.0f) > 0.5f ? lo : hi) = mid;
    }
    return lo;
}

}  // namespace spangle::test
