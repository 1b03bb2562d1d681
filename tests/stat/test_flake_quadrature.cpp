// Energy of single footprints of the flake lobe by deterministic quadrature of eval() over the
// hemisphere of wi (not by sampling: a lobe that put energy where sample() never goes would pass a
// sampled furnace). Perfect white mirror flakes (preset "perfect", flake_weight 1): a footprint
// reflects at most what it receives, whatever the algorithm, footprint, view and cone.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "flake_support.h"

namespace spangle::test::flake_quadrature {
namespace {

/** The hemisphere of wi as the unit square, area-preserving: Shirley and Chiu's concentric map to
 *  the disk, lifted with z = 1 - r^2 (solid angle = 2 pi x area in the square). */
Vec3 hemisphere(double u, double v) {
    const double a = 2.0 * u - 1.0, b = 2.0 * v - 1.0;
    if (a == 0.0 && b == 0.0) return {0.0f, 0.0f, 1.0f};
    double r, phi;
    if (std::fabs(a) > std::fabs(b)) {
        r = a;
        phi = 0.25 * kPi * (b / a);
    } else {
        r = b;
        phi = 0.5 * kPi - 0.25 * kPi * (a / b);
    }
    const double x = r * std::cos(phi), y = r * std::sin(phi), r2 = x * x + y * y;
    const double s = std::sqrt(std::max(0.0, 2.0 - r2));
    return {static_cast<float>(x * s), static_cast<float>(y * s), static_cast<float>(1.0 - r2)};
}

/** An albedo by quadrature and its error. */
struct Quadrature {
    double albedo = 0.0;  ///< the integral of f cos(theta_i) over the hemisphere
    double se = 0.0;      ///< standard error of the stratified part (see quadrature())
    double bound = 0.0;   ///< bound on the error of the coarse part
    double error() const { return 4.0 * se + bound; }
    long evals = 0;
    std::size_t refined = 0;  ///< coarse cells integrated by strata
};

/** The integral of f(wo, wi) cos(theta_i) (green channel) of the prepared closure over wi.
 *
 *  The discrete lobe is a sum of cones of half-angle gamma (f cos constant inside each, times G1
 *  with shadowing on) over a lobe that is smooth at the scale of a cone, so the rule is two-level:
 *  - a coarse midpoint grid on the square whose neighbouring nodes are at most gamma apart on the
 *    sphere (checked), so that every cone holds at least one node (a disc of radius gamma holds a
 *    node of any square lattice of spacing up to sqrt(2) gamma);
 *  - every coarse cell whose value differs from a neighbour's by more than `jump` (relative), and
 *    the cells around those (a rim may cross a cell whose node agrees with its neighbours'), is
 *    integrated by stratified sampling, one point jittered in each of sub x sub sub-cells (fixed
 *    seeds): unbiased, with an error only where a rim crosses a sub-cell. Its standard error comes
 *    from pairs of neighbouring sub-cells (the collapsed-strata estimate, which can only
 *    overstate it).
 *  The coarse cells left (relative change below `jump` to every neighbour: no rim, a lobe smooth
 *  across them) take the midpoint rule, with its error bounded from the second differences. */
Quadrature quadrature(const BsdfHarness& m, double gamma_rad, uint64_t seed, int sub = 16,
                      double jump = 0.02) {
    // Coarse spacing: the map stretches a cell by up to 4 (radially at the rim, where dtheta/dr
    // = 2); every pair of neighbouring nodes is checked.
    const int n = std::max(64, static_cast<int>(std::ceil(4.5 / gamma_rad)));
    std::vector<Vec3> wi(static_cast<std::size_t>(n) * n);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            wi[static_cast<std::size_t>(j) * n + i] = hemisphere((i + 0.5) / n, (j + 0.5) / n);
    double spacing = 0.0;
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            const std::size_t c = static_cast<std::size_t>(j) * n + i;
            spacing = std::max(
                {spacing, static_cast<double>(length(wi[c + 1] - wi[c])),
                 static_cast<double>(length(wi[c + static_cast<std::size_t>(n)] - wi[c]))});
        }
    EXPECT_LE(spacing, gamma_rad) << "the coarse grid must put a node in every cone";
    std::vector<Vec3> f;
    std::vector<float> pdf;
    m.eval(wi, f, pdf);
    Quadrature q;
    q.evals = static_cast<long>(wi.size());
    const auto value = [&](int i, int j) {
        return static_cast<double>(f[static_cast<std::size_t>(j) * n + i].y) *
               wi[static_cast<std::size_t>(j) * n + i].z;
    };
    std::vector<uint8_t> mark(wi.size(), 0);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const double a = value(i, j);
            const auto differs = [&](int i2, int j2) {
                if (i2 < 0 || j2 < 0 || i2 >= n || j2 >= n) return false;
                const double b = value(i2, j2);
                return std::fabs(a - b) > jump * (std::fabs(a) + std::fabs(b));
            };
            if (differs(i + 1, j) || differs(i - 1, j) || differs(i, j + 1) || differs(i, j - 1))
                mark[static_cast<std::size_t>(j) * n + i] = 1;
        }
    std::vector<uint8_t> refine(mark);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            if (!mark[static_cast<std::size_t>(j) * n + i]) continue;
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int i2 = i + di, j2 = j + dj;
                    if (i2 >= 0 && j2 >= 0 && i2 < n && j2 < n)
                        refine[static_cast<std::size_t>(j2) * n + i2] = 1;
                }
        }
    // The cells left: the midpoint rule, its error bounded by the second differences (the rule's
    // error on a cell is (d2f/du2 + d2f/dv2) h^2 / 24; taken twice, without cancellation), or by
    // jump / 4 of the value on the square's edge.
    double coarse = 0.0, coarse_error = 0.0;
    std::vector<int> cells;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            if (refine[static_cast<std::size_t>(j) * n + i]) {
                cells.push_back(j * n + i);
                continue;
            }
            const double v = value(i, j);
            coarse += v;
            if (i == 0 || j == 0 || i + 1 == n || j + 1 == n) {
                coarse_error += 0.25 * jump * std::fabs(v);
                continue;
            }
            coarse_error += (std::fabs(value(i + 1, j) + value(i - 1, j) - 2.0 * v) +
                             std::fabs(value(i, j + 1) + value(i, j - 1) - 2.0 * v)) /
                            12.0;
        }
    // The refined cells, stratified, in batches of whole cells (sub x sub points, row-major, so
    // that points 2 k and 2 k + 1 are neighbours in one row of one cell).
    const double cell = 2.0 * kPi / (static_cast<double>(n) * n);
    const double point = cell / (static_cast<double>(sub) * sub);
    double sum = 0.0, var = 0.0;
    constexpr std::size_t kBatch = 1 << 16;
    std::vector<Vec3> batch;
    batch.reserve(kBatch + static_cast<std::size_t>(sub * sub));
    const auto flush = [&]() {
        if (batch.empty()) return;
        std::vector<Vec3> fb;
        std::vector<float> pb;
        m.eval(batch, fb, pb);
        for (std::size_t k = 0; k + 1 < batch.size(); k += 2) {
            const double y0 = static_cast<double>(fb[k].y) * batch[k].z,
                         y1 = static_cast<double>(fb[k + 1].y) * batch[k + 1].z;
            sum += y0 + y1;
            var += (y0 - y1) * (y0 - y1);
        }
        q.evals += static_cast<long>(batch.size());
        batch.clear();
    };
    for (const int c : cells) {
        const int i = c % n, j = c / n;
        for (int b = 0; b < sub; ++b)
            for (int a = 0; a < sub; ++a) {
                const uint64_t h = hash2(seed, static_cast<uint64_t>(c) * 4096 + b * sub + a);
                const double ju = to_unit_double(h), jv = to_unit_double(hash2(h, 1));
                batch.push_back(hemisphere((i + (a + ju) / sub) / n, (j + (b + jv) / sub) / n));
            }
        if (batch.size() >= kBatch) flush();
    }
    flush();
    q.refined = cells.size();
    q.albedo = cell * coarse + point * sum;
    q.se = point * std::sqrt(var);
    q.bound = cell * coarse_error;
    return q;
}

struct Case {
    const char* algorithm;  ///< null: the default algorithm with its default sparse_flakes
    double shadowing, gamma_deg, alpha, lambda;
    float cos_o;
};

std::string describe(const Case& c, uint64_t k) {
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  "%s shadowing %g gamma %g alpha %g lambda %g cos_o %g footprint %llu",
                  c.algorithm ? c.algorithm : "default", c.shadowing, c.gamma_deg, c.alpha,
                  c.lambda, static_cast<double>(c.cos_o), static_cast<unsigned long long>(k));
    return buf;
}

/** The worst footprint of a case by quadrature: albedo and error of each of `footprints`. */
struct Worst {
    double albedo = 0.0, error = 0.0, margin = -1e9;  ///< margin: albedo - 1 - error, worst
    uint64_t k = 0;
};
Worst measure(const Case& c, int footprints, uint64_t seed, bool expect) {
    FlakeStrings strings = {{"preset", "perfect"}};
    if (c.algorithm) strings.push_back({"algorithm", c.algorithm});
    auto m = flake_material(
        true,
        {{"shadowing", {c.shadowing}}, {"gamma", {c.gamma_deg}}, {"flake_roughness", {c.alpha}}},
        strings);
    const double gamma = c.gamma_deg * kPi / 180.0;
    Worst w;
    for (uint64_t k = 0; k < static_cast<uint64_t>(footprints); ++k) {
        m->prepare(dir(c.cos_o, 0.7f + 0.9f * static_cast<float>(k)),
                   random_footprint(c.lambda, seed, k));
        // Finer strata where a few cones leave a larger share of the rims' error (cheap there:
        // little is refined).
        Quadrature q = quadrature(*m, gamma, seed + k);
        if (q.error() > 1e-3 && q.refined < 500) q = quadrature(*m, gamma, seed + k, 48);
        const double margin = q.albedo - 1.0 - q.error();
        if (margin > w.margin) w = {q.albedo, q.error(), margin, k};
        if (expect) {
            EXPECT_LE(q.albedo, 1.0 + q.error())
                << describe(c, k) << ": quadrature error " << q.error();
            // The estimate must be able to fail: its error stays far below the excess it guards.
            EXPECT_LT(q.error(), 5e-3) << describe(c, k);
        }
    }
    return w;
}

/** The cases of the committed tests: every cone and roughness of the brief, at the footprint
 *  sizes that bound the regimes (a few flakes; cells enumerated; aggregates with every flake a
 *  stand-in; dense aggregates) and views from normal to cos 1e-4, shadowing on and off. The
 *  narrowest cone (a coarse grid of 258^2) on fewer cases; gamma 0.5 (516^2) takes the sweep. */
void expect_every_footprint_keeps_its_energy(const char* algorithm) {
    struct Material {
        double gamma, alpha;
        int footprints;
        std::vector<double> shadowing;
    };
    for (const Material& mat :
         {Material{10.0, 0.15, 2, {0.0, 1.0}}, Material{3.0, 0.15, 1, {0.0, 1.0}},
          Material{10.0, 0.5, 1, {0.0, 1.0}}, Material{1.0, 0.5, 1, {0.0}}})
        for (double shadowing : mat.shadowing)
            for (double lambda : {5.0, 110.0, 1000.0, 1e5})
                for (float cos_o : {1.0f, 0.3f, 0.019f, 1e-4f}) {
                    if (mat.gamma < 3.0 && (lambda != 1000.0 || cos_o == 0.3f)) continue;
                    const Case c{algorithm, shadowing, mat.gamma, mat.alpha, lambda, cos_o};
                    measure(c, mat.footprints, 3100, true);
                }
}

TEST(FlakeEnergy, EnumeratedFootprintsKeepAtMostTheirEnergyByQuadrature) {
    // The reflection cache normalised by its flakes' summed weight: at most 1 exactly (each
    // flake's cone loses its share under the horizon, and G1 <= 1 with shadowing on).
    expect_every_footprint_keeps_its_energy("enumerate");
}

TEST(FlakeEnergy, CountedFootprintsKeepAtMostTheirEnergyByQuadrature) {
    // The counting algorithm's aggregates as stand-in flakes and the smooth lobe, normalised by
    // the weights of what the lobe holds: at most 1 for every footprint, like the enumeration (the
    // allowance of 2.5% to 6% once granted to aggregated footprints is gone).
    expect_every_footprint_keeps_its_energy("tree");
}

TEST(FlakeEnergy, FadedFootprintsKeepAtMostTheirEnergyByQuadrature) {
    // The default tree mixes a footprint's enumerated and counted lobes where it fades from one
    // to the other (sparse_share), each normalised by its own weight: at most 1 too. Each case at
    // the lambda where the share is 1/2, found on the plugin's own table: the bound on flakes per
    // direction for the wide cone at alpha 0.15 (lambda 360 to 1 000), the bound on the count
    // (about 2 900) for the others.
    namespace fl = spangle::flake;
    int cases = 0;
    for (const auto& [gamma, alpha] :
         {std::pair{10.0, 0.15}, std::pair{3.0, 0.15}, std::pair{10.0, 0.5}})
        for (float cos_o : {1.0f, 0.3f, 0.019f}) {
            const double lambda =
                half_faded_lambda(static_cast<float>(alpha), static_cast<float>(gamma), cos_o);
            fl::DirectionGrid grid;
            grid.init(static_cast<float>(alpha), static_cast<float>(gamma * kPi / 180.0));
            ASSERT_NEAR(fl::sparse_share(fl::kSparseFlakes, grid, cos_o, lambda, 0.0f), 0.5f,
                        0.01f);
            for (double shadowing : {0.0, 1.0}) {
                // (Wide cones in every case; the costlier others, of thousands of flakes, at one
                // view (gamma 3) or two, with shadowing head-on and without at grazing: 15 s in
                // all.)
                const bool wide = gamma == 10.0 && alpha == 0.15;
                if (!wide && (cos_o == 0.3f || (shadowing == 1.0) != (cos_o == 1.0f) ||
                              (gamma == 3.0 && cos_o == 1.0f)))
                    continue;
                const Case c{nullptr, shadowing, gamma, alpha, lambda, cos_o};
                measure(c, 1, 3300, true);
                ++cases;
            }
        }
    EXPECT_EQ(cases, 9);
}

/** A list of numbers from the environment (comma-separated), or `fallback`. */
std::vector<double> env_list(const char* name, std::vector<double> fallback) {
    const char* v = std::getenv(name);
    if (!v || !*v) return fallback;
    std::vector<double> out;
    for (const char* p = v; *p;) {
        char* end = nullptr;
        out.push_back(std::strtod(p, &end));
        p = *end == ',' ? end + 1 : end;
        if (end == p && *p) break;
    }
    return out;
}

/** Sweeps the cases of the brief and prints each case's worst footprint: SPANGLE_FLAKE_SWEEP
 *  (enumerate or tree), SPANGLE_SWEEP_{GAMMA,ALPHA,SHADOWING,LAMBDA,COS} (comma-separated lists)
 *  and SPANGLE_SWEEP_N (footprints per case) narrow it. A measurement tool, not a check: run it by
 *  name. */
TEST(FlakeQuadrature, DISABLED_Sweep) {
    const char* which = std::getenv("SPANGLE_FLAKE_SWEEP");
    const std::string algorithm = which ? which : "tree";
    const int footprints = static_cast<int>(env_list("SPANGLE_SWEEP_N", {4})[0]);
    Worst worst;
    std::string worst_case;
    for (double gamma : env_list("SPANGLE_SWEEP_GAMMA", {10.0, 3.0, 0.5}))
        for (double alpha : env_list("SPANGLE_SWEEP_ALPHA", {0.15, 0.5}))
            for (double shadowing : env_list("SPANGLE_SWEEP_SHADOWING", {0.0, 1.0}))
                for (double lambda : env_list("SPANGLE_SWEEP_LAMBDA", {5, 83, 300, 1000, 1e4, 1e5}))
                    for (double cos_o : env_list("SPANGLE_SWEEP_COS", {1.0, 0.3, 0.019, 1e-4})) {
                        const Case c{algorithm.c_str(),        shadowing, gamma, alpha, lambda,
                                     static_cast<float>(cos_o)};
                        const Worst w = measure(c, footprints, 2500, false);
                        std::printf("%-70s worst %.5f +- %.5f\n", describe(c, w.k).c_str(),
                                    w.albedo, w.error);
                        std::fflush(stdout);
                        if (w.margin > worst.margin) {
                            worst = w;
                            worst_case = describe(c, w.k);
                        }
                    }
    std::printf("WORST %s: %.5f +- %.5f\n", worst_case.c_str(), worst.albedo, worst.error);
}

}  // namespace
}  // namespace spangle::test::flake_quadrature
