// The discrete flake lobe of both algorithms through the plugin ABI: sample() against pdf()
// (chi-square), the two algorithms against each other, the footprint-averaged lobe against the
// smooth lobe (its expectation) at the highlight and off it, and hard cases.

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "chi2.h"
#include "core/hash.h"
#include "counted_lobe.h"
#include "field.h"
#include "flake_support.h"
#include "smooth_lobe.h"
#include "warp_chi2.h"

namespace spangle::test::flake_lobes {
namespace {

namespace fl = spangle::flake;

float radians(float deg) {
    return deg * kPi / 180.0f;
}

/** The cones of the flakes a prepared closure caches, found independently of the plugin: the
 *  field's flakes in the footprint (all of them for `enumerate`; for `tree`, those of the cells the
 *  counting algorithm enumerates and its aggregates' stand-ins) that face wo and reflect it above
 *  the horizon. */
std::vector<Vec3> cached_cones(bool tree, float alpha, const BsdfHarness::Point& pt, Vec3 wo,
                               uint64_t seed = 0, double density = kTestDensity, double facet = 0.0,
                               float gamma = 0.0f, float sparse_flakes = fl::kSparseFlakes) {
    fl::FieldParams fp;
    fp.seed = seed;
    fp.flakes_per_tile = density;
    fp.alpha = alpha;
    fl::Footprint p = fl::make_footprint(pt.u, pt.v, pt.dudx, pt.dvdx, pt.dudy, pt.dvdy, 1.0);
    // Hexagonal facets of that width (uv units: the harness's uv_area is 1) reach around P.
    const fl::FacetShape hexagon(fl::FacetKind::Hexagon);
    if (facet > 0.0) {
        fp.facet = &hexagon;
        fp.facet_size = facet;
        p.reach = facet * hexagon.radius;
    }
    std::vector<Vec3> cones;
    const auto add = [&](const fl::Flake& f) {
        const Vec3 m(f.m.x, f.m.y, f.m.z);
        if (dot(wo, m) <= 0.0f) return;
        const Vec3 r = m * (2.0f * dot(wo, m)) - wo;
        if (r.z > 0.0f) cones.push_back(r);
    };
    fl::DirectionGrid grid;
    if (tree) grid.init(alpha, gamma);
    // Point flakes lighting their directions sparsely: the tree enumerates the footprint (the
    // discrete lobe is forced: t = 0), all of it or mixed with its count (the cones of both).
    const float enumerated =
        !tree          ? 1.0f
        : facet == 0.0 ? fl::sparse_share(sparse_flakes, grid, wo.z, density * p.area(), 0.0f)
                       : 0.0f;
    if (enumerated < 1.0f) {
        // The cells the plugin enumerates at this view (the default exact_flakes, raised for
        // sparse cells), and the aggregates' stand-ins: their cones depend on their normals only
        // (the colour and film tables, left plain here, scale what they reflect).
        fl::CountedFootprint cf;
        fl::gather_cells(fp, p, fl::exact_limit(256, grid, wo.z), cf, add);
        const fl::ColorTable colors;
        fl::FresnelTable fresnel;
        const fl::FilmTables film;
        std::vector<fl::CacheEntry> stand_ins;
        fl::add_stand_ins(cf, fp, p, 1.0f, fl::kStandIns, grid, colors, fresnel, film,
                          {wo.x, wo.y, wo.z}, stand_ins);
        for (const fl::CacheEntry& e : stand_ins) cones.emplace_back(e.r.x, e.r.y, e.r.z);
    }
    if (enumerated > 0.0f) {
        bool truncated = false;
        fl::for_each_flake(fp, p, 1u << 20, truncated, add);
    }
    return cones;
}

/** Cones on a grid over (x, y) with cells as wide as a cone: how many cones hold a direction. */
class ConeSet {
public:
    ConeSet(const std::vector<Vec3>& cones, float gamma)
        : cones_(cones), threshold_(4.0f * std::sin(0.5f * gamma) * std::sin(0.5f * gamma)) {
        cell_ = std::sqrt(threshold_);
        for (std::size_t i = 0; i < cones_.size(); ++i)
            grid_[key(cell_of(cones_[i].x), cell_of(cones_[i].y))].push_back(i);
    }
    int covering(Vec3 w) const {
        // A cone within chord c of w is within c of it in x and in y: neighbouring cells only.
        int n = 0;
        const int64_t cx = cell_of(w.x), cy = cell_of(w.y);
        for (int64_t dy = -1; dy <= 1; ++dy)
            for (int64_t dx = -1; dx <= 1; ++dx) {
                const auto it = grid_.find(key(cx + dx, cy + dy));
                if (it == grid_.end()) continue;
                for (std::size_t i : it->second) {
                    const Vec3 d = w - cones_[i];
                    n += dot(d, d) <= threshold_;
                }
            }
        return n;
    }
    float threshold() const { return threshold_; }

private:
    int64_t cell_of(float x) const { return static_cast<int64_t>(std::floor((x + 1.0f) / cell_)); }
    static int64_t key(int64_t x, int64_t y) { return x * 1000003 + y; }
    std::vector<Vec3> cones_;
    float threshold_, cell_;
    std::unordered_map<int64_t, std::vector<std::size_t>> grid_;
};

struct LobeCase {
    const char* algorithm;
    double lambda;
    float gamma_deg, alpha, cos_o;
    FlakeParams extra = {};  ///< further parameters (the looks: colour variation, film)
};

/** Chi-square of sample() against pdf() for the discrete lobe of one footprint, in the warped
 *  domain of warp_chi2.h. The pdf is a mixture of the cached flakes' cones and (tree, when the
 *  footprint has aggregates) the smooth lobe's proposal, so the expected counts are integrated by
 *  a quadrature of each: points inside every cone (rings dense at the rim, weights divided by how
 *  many cones cover a point so that overlaps count once) and a stratified grid of the smooth
 *  proposal's own samples (weight 1 / (n q)) for the directions outside all cones. */
void lobe_chi2(const LobeCase& c, uint64_t seed) {
    SCOPED_TRACE(testing::Message() << c.algorithm << " lambda " << c.lambda << " gamma "
                                    << c.gamma_deg << " cos_o " << c.cos_o);
    const bool tree = std::string(c.algorithm) == "tree";
    FlakeParams params = {{"gamma", {c.gamma_deg}}, {"flake_roughness", {c.alpha}}};
    params.insert(params.end(), c.extra.begin(), c.extra.end());
    auto m = flake_material(true, params, {{"algorithm", c.algorithm}});
    const Vec3 wo = dir(c.cos_o, 0.3f);
    const BsdfHarness::Point pt = random_footprint(c.lambda, seed, 0);
    m->prepare(wo, pt);
    const float gamma = radians(c.gamma_deg);
    const auto value = [&](const char* name) {
        for (const auto& [key, v] : c.extra)
            if (key == name) return v[0];
        return 0.0;
    };
    // (flake_material() turns the named tree's sparse enumeration off unless a case sets it:
    // value() is 0 for a parameter the case does not set.)
    const auto sparse = static_cast<float>(value("sparse_flakes"));
    std::vector<Vec3> list =
        cached_cones(tree, c.alpha, pt, wo, 0, kTestDensity, value("flake_size"), gamma, sparse);
    // A second population (of the same cone): its own field's flakes, by the plugin's seed salt.
    if (value("flakes2_weight") > 0.0)
        for (const Vec3& r :
             cached_cones(tree, static_cast<float>(value("flakes2_roughness")), pt, wo,
                          fl::mix(0, 0x5ec0d), value("flakes2_density"), 0.0, gamma, sparse))
            list.push_back(r);
    const ConeSet cones(list, gamma);

    std::vector<Vec3> q;
    std::vector<double> weight;
    // Cones: rings at u = 1 - (1 - t)^2 of the cap's area (t uniform: dense at the rim, where a
    // bin boundary may cut off a thin sliver), sectors equal in angle.
    // Points per cone: eval() costs a pass over every cone per point, so points x cones is held
    // to about 4e8; up to 32768 per cone when there are few.
    const double n_cones = std::max<double>(1.0, static_cast<double>(list.size()));
    const int per_cone = static_cast<int>(std::clamp(4e8 / (n_cones * n_cones), 32.0, 32768.0));
    const int rings = std::max(4, static_cast<int>(std::sqrt(per_cone / 2.0)));
    const int sectors = 2 * rings;
    const double cap = 2.0 * M_PI * (1.0 - std::cos(gamma));
    for (const Vec3& r : list) {
        Vec3 s, t;
        make_basis(r, s, t);
        for (int i = 0; i < rings; ++i) {
            const double tt = (i + 0.5) / rings, u = 1.0 - (1.0 - tt) * (1.0 - tt);
            const double cz = 1.0 - u * (1.0 - std::cos(gamma));
            const double sn = std::sqrt(std::max(0.0, 1.0 - cz * cz));
            for (int j = 0; j < sectors; ++j) {
                const double ph = (j + 0.5) * 2.0 * M_PI / sectors;
                const Vec3 w = normalize(s * static_cast<float>(sn * std::cos(ph)) +
                                         t * static_cast<float>(sn * std::sin(ph)) +
                                         r * static_cast<float>(cz));
                if (w.z <= 0.0f) continue;
                q.push_back(w);
                weight.push_back(cap * 2.0 * (1.0 - tt) / (rings * sectors) /
                                 std::max(1, cones.covering(w)));
            }
        }
    }
    // Outside the cones: the smooth proposal's stratified samples (coarser for `enumerate`, whose
    // pdf there should be zero).
    fl::FresnelTable flat;
    for (auto& node : flat.rgb) node[0] = node[1] = node[2] = 1.0f;
    fl::SmoothLobe smooth;
    smooth.init(c.alpha, gamma, &flat);
    const fl::V3 fwo{wo.x, wo.y, wo.z};
    const int kGrid = tree ? 512 : 128;
    for (int a = 0; a < kGrid; ++a)
        for (int b = 0; b < kGrid; ++b) {
            fl::V3 w;
            if (!fl::sample_smooth(smooth, fwo, static_cast<float>((a + 0.5) / kGrid),
                                   static_cast<float>((b + 0.5) / kGrid), w))
                continue;
            const Vec3 wi(w.x, w.y, w.z);
            if (cones.covering(wi) > 0) continue;
            float f[3], pdf;
            fl::eval_smooth(smooth, fwo, smooth.valid_fraction(wo.z), w, f, pdf);
            if (!(pdf > 0.0f)) continue;
            q.push_back(wi);
            weight.push_back(1.0 / (static_cast<double>(kGrid) * kGrid * pdf));
        }
    std::vector<Vec3> f;
    std::vector<float> pdf;
    m->eval(q, f, pdf);

    float ax, ay;
    smooth.proposal_alpha(c.cos_o, ax, ay);
    const Warp warp{wo, ax, ax, 0.0f};
    constexpr int kBins = kWarpBins;
    const auto bin_of = [&](Vec3 w) {
        int lobe;
        double u1, u2;
        if (!warp.to_u(w, lobe, u1, u2)) return static_cast<std::size_t>(kBins * kBins);
        const int b1 = std::min(kBins - 1, static_cast<int>(u1 * kBins));
        const int b2 = std::min(kBins - 1, static_cast<int>(u2 * kBins));
        return static_cast<std::size_t>(b1 * kBins + b2);
    };
    constexpr uint32_t kN = 100000;
    std::vector<double> expected(kBins * kBins + 1, 0.0), observed(kBins * kBins + 1, 0.0);
    double total = 0.0;
    for (std::size_t k = 0; k < q.size(); ++k) {
        expected[bin_of(q[k])] += kN * pdf[k] * weight[k];
        total += pdf[k] * weight[k];
    }
    EXPECT_LE(total, 1.01) << "the pdf integrates to at most one";
    EXPECT_GT(total, 0.5);
    expected.back() += std::max(0.0, kN * (1.0 - total));
    for (const auto& s : m->sample(kN, seed + 7)) {
        if (s.flags == 0) {
            observed.back() += 1.0;
            continue;
        }
        observed[bin_of(s.wi)] += 1.0;
    }
    const Chi2Result r = chi2_test(observed, expected);
    EXPECT_GT(r.p_value, 0.001) << list.size() << " cached flakes: chi2 " << r.statistic << " dof "
                                << r.dof;
}

TEST(FlakeLobe, SamplingMatchesPdfFewFlakes) {
    lobe_chi2({"enumerate", 5, 3.0f, 0.2f, 0.8f}, 1);
    lobe_chi2({"tree", 5, 3.0f, 0.2f, 0.8f}, 1);
    lobe_chi2({"enumerate", 8, 10.0f, 0.15f, 0.3f}, 2);
}
TEST(FlakeLobe, SamplingMatchesPdfManyFlakes) {
    lobe_chi2({"enumerate", 50, 3.0f, 0.15f, 0.7f}, 3);
    lobe_chi2({"tree", 50, 3.0f, 0.15f, 0.7f}, 3);
    lobe_chi2({"enumerate", 5000, 2.0f, 0.15f, 0.7f}, 4);
}
TEST(FlakeLobe, SamplingMatchesPdfWithAggregates) {
    // Counted aggregates (tree, footprints of a few thousand flakes): the pdf mixes the cached
    // cones with the smooth proposal; and 700 flakes of these, which light their directions
    // sparsely, as the tree takes them by default (`sparse_flakes`: enumerated).
    lobe_chi2({"tree", 5000, 3.0f, 0.15f, 0.7f}, 5);
    lobe_chi2({"tree", 700, 3.0f, 0.15f, 0.7f}, 6);
    lobe_chi2({"tree", 700, 3.0f, 0.15f, 0.7f, {{"sparse_flakes", {fl::kSparseFlakes}}}}, 8);
    lobe_chi2({"tree", 5000, 10.0f, 0.3f, 0.1f}, 7);
    // Faded half way from the count to the enumeration (sparse_share: wider cones, a few hundred
    // flakes), the two lobes mixed. (At a few thousand flakes of gamma 3, where the count's own
    // bound fades, this quadrature of the expected counts is too coarse: `enumerate` fails there
    // alike, and both pass with ten times the points.)
    lobe_chi2({"tree",
               half_faded_lambda(0.15f, 10.0f, 0.7f),
               10.0f,
               0.15f,
               0.7f,
               {{"sparse_flakes", {fl::kSparseFlakes}}}},
              9);
}

TEST(FlakeLobe, SamplingMatchesPdfWithColourVariationAndFilm) {
    // The looks change what each flake reflects, hence how likely sampling picks it (by
    // luminance): varied colours from the table and interference films over the flakes, with
    // enumerated flakes and with the tree's aggregates (whose virtual flakes vary alike).
    const FlakeParams hsv = {{"color_table", {1.0}},
                             {"hue_variation", {40.0}},
                             {"saturation_variation", {0.5}},
                             {"value_variation", {0.8}}};
    const FlakeParams film = {
        {"film_thickness_min", {200.0}}, {"film_thickness_max", {900.0}}, {"film_ior", {2.0}}};
    FlakeParams both = hsv;
    both.insert(both.end(), film.begin(), film.end());
    lobe_chi2({"enumerate", 50, 3.0f, 0.15f, 0.5f, both}, 22);
    lobe_chi2({"tree", 700, 3.0f, 0.15f, 0.7f, both}, 23);
    FlakeParams sparse = both;
    sparse.push_back({"sparse_flakes", {fl::kSparseFlakes}});
    lobe_chi2({"tree", 700, 3.0f, 0.15f, 0.7f, sparse}, 24);
}

TEST(FlakeLobe, SamplingMatchesPdfWithTwoPopulations) {
    // The mixture of two populations' discrete lobes (each its own cache and field) is sampled
    // as its pdf says: the second population is picked by its share of the luminance.
    const FlakeParams two = {{"flakes2_weight", {0.4}},
                             {"flakes2_density", {0.5 * kTestDensity}},
                             {"flakes2_color", {1.0, 0.3, 0.1}},
                             {"flakes2_roughness", {0.3}},
                             {"flakes2_gamma", {3.0}}};
    lobe_chi2({"enumerate", 40, 3.0f, 0.15f, 0.7f, two}, 31);
    lobe_chi2({"tree", 40, 3.0f, 0.15f, 0.5f, two}, 32);
    // Both populations under the default rule, wide cones: the first half faded from its count
    // to its enumeration (sparse_share), the second (half as dense, rougher) its own share.
    FlakeParams faded = {
        {"flakes2_weight", {0.4}},          {"flakes2_density", {0.5 * kTestDensity}},
        {"flakes2_color", {1.0, 0.3, 0.1}}, {"flakes2_roughness", {0.3}},
        {"flakes2_gamma", {10.0}},          {"sparse_flakes", {fl::kSparseFlakes}}};
    lobe_chi2({"tree", half_faded_lambda(0.15f, 10.0f, 0.5f), 10.0f, 0.15f, 0.5f, faded}, 33);
}

TEST(FlakeLobe, SamplingMatchesPdfWithFacets) {
    // Facets (flake_size) weigh each flake by its share inside the footprint: the cache is
    // sampled by those weights. Facets as wide as the footprint (lambda 3) and a tenth of it.
    const double side3 = std::sqrt(3.0 / kTestDensity), side60 = std::sqrt(60.0 / kTestDensity);
    lobe_chi2({"enumerate", 3, 4.0f, 0.3f, 0.6f, {{"flake_size", {side3}}}}, 41);
    lobe_chi2({"tree", 3, 4.0f, 0.3f, 0.4f, {{"flake_size", {side3}}}}, 42);
    lobe_chi2({"enumerate", 60, 3.0f, 0.15f, 0.7f, {{"flake_size", {0.1 * side60}}}}, 43);
}

TEST(FlakeLobe, UvThatIsNotFiniteGivesTheSmoothLobe) {
    // A mesh with NaN or infinite uvs: no cell holds the point, so the lobe is the smooth one
    // (before, the counting algorithm converted the NaN centre to a block index: undefined
    // behaviour, which the sanitizer build reports).
    const Vec3 wo = dir(0.7f, 0.3f);
    std::vector<Vec3> wis;
    for (int a = -4; a <= 4; ++a)
        for (int b = -4; b <= 4; ++b)
            wis.push_back(normalize(Vec3(-wo.x + 0.1f * static_cast<float>(a),
                                         -wo.y + 0.1f * static_cast<float>(b), wo.z)));
    for (const char* algorithm : {"tree", "enumerate"}) {
        auto m = flake_material(true, {}, {{"algorithm", algorithm}});
        const std::vector<Vec3> smooth = smooth_f(*m, wo, wis);
        for (const float u :
             {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
            m->prepare(wo, footprint(1000.0, u, 0.5f));
            std::vector<Vec3> f;
            std::vector<float> pdf;
            m->eval(wis, f, pdf);
            for (std::size_t j = 0; j < wis.size(); ++j) {
                ASSERT_TRUE(std::isfinite(f[j].y) && std::isfinite(pdf[j]))
                    << algorithm << " " << u;
                EXPECT_NEAR(f[j].y, smooth[j].y, 1e-5f * (1.0f + smooth[j].y))
                    << algorithm << " " << u;
            }
        }
    }
}

TEST(FlakeLobe, AUvLayoutOnATriangleWithoutUvsGivesTheSmoothLobe) {
    // density_space "uv" (or "world") where the mesh has no usable uvs (SPANGLE_SHADING_NO_UV):
    // the host's stand-in uvs, (0, 0), (1, 0), (0, 1) on every triangle, would give every
    // triangle the same flakes, so the lobe is the smooth one, as the host's warning says.
    // "auto" and "object" place flakes by object-space position there instead: glints.
    const Vec3 wo = dir(0.7f, 0.3f);
    std::vector<Vec3> wis;
    for (int a = -6; a <= 6; ++a)
        for (int b = -6; b <= 6; ++b)
            wis.push_back(normalize(Vec3(-wo.x + 0.04f * static_cast<float>(a),
                                         -wo.y + 0.04f * static_cast<float>(b), wo.z)));
    BsdfHarness::Point pt = footprint(300.0, 0.3f, 0.2f);
    pt.no_uv = true;
    pt.p_obj = Vec3(0.3f, 0.2f, 0.0f);
    pt.dpdx_obj = Vec3(pt.dudx, 0.0f, 0.0f);
    pt.dpdy_obj = Vec3(0.0f, pt.dvdy, 0.0f);
    for (const char* space : {"uv", "world", "auto"}) {
        auto m = flake_material(true, {}, {{"density_space", space}});
        const std::vector<Vec3> smooth = smooth_f(*m, wo, wis);
        m->prepare(wo, pt);
        std::vector<Vec3> f;
        std::vector<float> pdf;
        m->eval(wis, f, pdf);
        double off = 0.0, total = 0.0;
        for (std::size_t j = 0; j < wis.size(); ++j) {
            off += std::fabs(static_cast<double>(f[j].y - smooth[j].y));
            total += static_cast<double>(smooth[j].y);
        }
        if (std::string(space) == "auto")
            EXPECT_GT(off, 0.1 * total) << "object-space flakes make glints";
        else
            EXPECT_LT(off, 1e-5 * total) << space;
    }
}

TEST(FlakeLobe, TreeSeesTheEnumeratedFlakesInSmallFootprints) {
    // Up to a few dozen flakes per footprint every cell is enumerated: the same glints, exactly.
    auto tree = flake_material(true, {}, {{"algorithm", "tree"}});
    auto enumerate = flake_material(true, {}, {{"algorithm", "enumerate"}});
    std::vector<Vec3> wis;
    for (uint32_t i = 0; i < 400; ++i)
        wis.push_back(dir(sample_1d(3, i, 0, 0), 2.0f * kPi * sample_1d(3, i, 0, 1)));
    for (double lambda : {5.0, 50.0})
        for (uint64_t k = 0; k < 20; ++k) {
            const Vec3 wo = dir(0.2f + 0.04f * static_cast<float>(k), 0.1f * static_cast<float>(k));
            const BsdfHarness::Point pt = random_footprint(lambda, 11, k);
            tree->prepare(wo, pt);
            enumerate->prepare(wo, pt);
            // Near the peak too: directions of the flakes' own mirror reflections.
            std::vector<Vec3> at = wis;
            for (const Vec3& r : cached_cones(false, 0.15f, pt, wo)) at.push_back(r);
            std::vector<Vec3> ft, fe;
            std::vector<float> pt_, pe;
            tree->eval(at, ft, pt_);
            enumerate->eval(at, fe, pe);
            for (std::size_t i = 0; i < at.size(); ++i) {
                // The same flakes, summed in another order: equal to float rounding.
                ASSERT_NEAR(ft[i].y, fe[i].y, 1e-5f * fe[i].y)
                    << "lambda " << lambda << " footprint " << k;
                ASSERT_NEAR(pt_[i], pe[i], 1e-5f * pe[i])
                    << "lambda " << lambda << " footprint " << k;
            }
        }
}

// ------------------------------------------------------------------------------- expectations

/** Mean and standard error of f.y at wi over random footprints of expected count lambda. */
struct Mean {
    double mean = 0.0, se = 0.0;
};
Mean footprint_mean(BsdfHarness& m, Vec3 wo, Vec3 wi, double lambda, int footprints,
                    uint64_t seed) {
    double sum = 0.0, sum2 = 0.0;
    std::vector<Vec3> f;
    std::vector<float> pdf;
    for (int k = 0; k < footprints; ++k) {
        m.prepare(wo, random_footprint(lambda, seed, static_cast<uint64_t>(k)));
        m.eval({wi}, f, pdf);
        sum += f[0].y;
        sum2 += static_cast<double>(f[0].y) * f[0].y;
    }
    Mean r;
    r.mean = sum / footprints;
    r.se = std::sqrt(std::max(0.0, sum2 / footprints - r.mean * r.mean) / footprints);
    return r;
}

/** The smooth lobe's density of mirror directions at wi (G1 D / (4 cos_o), no blur): a guide
 *  for how many flakes light wi in a footprint. */
double mirror_density(Vec3 wo, Vec3 wi, float alpha) {
    const Vec3 h = normalize(wo + wi);
    const double t2 = (h.x * h.x + h.y * h.y) / (static_cast<double>(h.z) * h.z);
    const double a2 = static_cast<double>(alpha) * alpha;
    const double d = 1.0 / (M_PI * a2 * std::pow(h.z, 4.0) * std::pow(1.0 + t2 / a2, 2.0));
    return d / (4.0 * wo.z);
}

/** The footprint-averaged discrete lobe equals the smooth lobe at the highlight's peak (the
 *  mirror direction) and off it (a half vector tilted across the plane of incidence by 1.2
 *  alpha in slope), for one algorithm. Footprints are sized so that about `lit` flakes light wi
 *  (at least 20 flakes per footprint). The bound is 4 standard errors plus the smooth table's
 *  documented accuracy (1%). */
void expectation_case(const char* algorithm, float gamma_deg, float cos_o, int footprints,
                      double lit, double max_lambda, uint64_t seed) {
    constexpr float kAlpha = 0.15f;
    const FlakeParams params = {{"gamma", {gamma_deg}}, {"flake_roughness", {kAlpha}}};
    auto disc = flake_material(true, params, {{"algorithm", algorithm}});
    auto smooth = flake_material(false, params);
    const Vec3 wo = dir(cos_o, 0.0f);
    const float tilt = std::atan(1.2f * kAlpha);
    const Vec3 h_off(0.0f, std::sin(tilt), std::cos(tilt));
    const Vec3 off = h_off * (2.0f * dot(wo, h_off)) - wo;
    const float sigma = 4.0f * kPi * std::pow(std::sin(0.5f * radians(gamma_deg)), 2.0f);
    for (const auto& [name, wi] :
         {std::pair<const char*, Vec3>{"peak", mirror(wo)}, {"off", off}}) {
        const double lambda =
            std::clamp(lit / (mirror_density(wo, wi, kAlpha) * sigma), 500.0, max_lambda);
        const Mean d = footprint_mean(*disc, wo, wi, lambda, footprints, seed);
        const double s = smooth_f(*smooth, wo, {wi})[0].y;
        EXPECT_NEAR(d.mean, s, 4.0 * d.se + 0.01 * s)
            << algorithm << " gamma " << gamma_deg << " cos_o " << cos_o << " " << name
            << " lambda " << lambda << ": ratio " << d.mean / s << " +- " << d.se / s;
    }
}

TEST(FlakeExpectation, TreeMatchesTheSmoothLobe) {
    // Every cone size of the issue, views from normal to grazing; the counting algorithm is cheap
    // enough for many footprints.
    for (float gamma : {1.0f, 3.0f, 10.0f, 30.0f})
        for (float cos_o : {1.0f, 0.5f, 0.2f, 0.05f})
            expectation_case("tree", gamma, cos_o, 3000, 12.0, 1e6, 100);
}

TEST(FlakeExpectation, EnumerationMatchesTheSmoothLobe) {
    // The reference algorithm, on fewer footprints of at most 4000 flakes.
    for (float gamma : {1.0f, 10.0f})
        for (float cos_o : {1.0f, 0.2f, 0.05f})
            expectation_case("enumerate", gamma, cos_o, 1200, 8.0, 4000.0, 200);
    for (float gamma : {3.0f, 30.0f})
        expectation_case("enumerate", gamma, 0.5f, 1200, 8.0, 4000.0, 300);
}

TEST(FlakeExpectation, FootprintsOfFewFlakesAverageToTheSmoothLimit) {
    // A footprint holding no flake that reflects wo above the horizon shows the base alone, one
    // holding any the flake share w / (1 - e^-found) (at most 1), found the expected count of
    // flakes that do (cache_share): averaged over footprints the flakes reflect what the smooth
    // limit reflects down to lambda 0.5, where most footprints hold no flake (they kept the
    // share w always and averaged (1 - e^-lambda) of it: 0.39 at lambda 0.5; and with found =
    // lambda, rough flakes (0.6) at cos 0.2 averaged 0.60 of it at lambda 0.5, 0.85 at 3). A
    // footprint of few flakes reflects their albedos' mean weighted among themselves, the far
    // look their mean weighted by w over all flakes; the material's SparseAlbedo scale makes the
    // two agree where albedo depends on tilt: glass flakes at cos 0.3 (their Fresnel rises where
    // w is small: they read 1.29 / 1.31 / 1.21 of the far look unscaled) and Schlick flakes (f0
    // 0.9) with shadowing at cos 0.2 (G1 lowers the small-w ones: 0.91 / 0.93 / 0.955), and
    // white flakes with shadowing at cos 0.1, raised only as far as they reflect at most what
    // they receive (roughness 0.3: 0.90 before, now 0.94 / 0.96 / 0.98). The last
    // case has the tree count every cell (exact_flakes 1): counted cells whose stand-ins are
    // their flakes (it read 0.64 there, the enumeration 0.89).
    // The flakes' albedo per footprint is estimated from samples of its lobe (unbiased); the
    // bound is 4 standard errors over footprints plus the smooth table's documented 1%.
    struct Case {
        double weight;  // above 1 - e^-found (0.6 at lambda 0.5) the footprints that hold
                        // a flake are all flake and the rest show the far look at the share
                        // left over (it read 0.64 of the far look at lambda 0.5)
        double roughness, gamma, shadowing, exact_flakes;
        Vec3 wo;
        const char* fresnel;
        double facet = 0.0;  // flake_size (0: point flakes)
    };
    for (const Case& cs : {Case{0.3, 0.15, 3.0, 1.0, 256.0, dir(0.8f, 0.3f), "conductor"},
                           Case{0.2, 0.6, 3.0, 0.0, 256.0, dir(0.2f, 0.3f), "conductor"},
                           Case{0.2, 0.3, 3.0, 0.0, 256.0, dir(0.3f, 0.3f), "dielectric"},
                           Case{0.2, 0.3, 3.0, 1.0, 256.0, dir(0.2f, 0.3f), "schlick"},
                           Case{0.2, 0.3, 3.0, 1.0, 256.0, dir(0.1f, 0.3f), "perfect"},
                           Case{0.2, 0.8, 3.0, 1.0, 256.0, dir(0.1f, 0.3f), "perfect"},
                           Case{0.2, 0.3, 45.0, 0.0, 1.0, dir(0.2f, 0.3f), "conductor"},
                           Case{0.6, 0.15, 3.0, 1.0, 256.0, dir(0.8f, 0.3f), "conductor"},
                           Case{0.2, 0.6, 3.0, 0.0, 256.0, dir(0.2f, 0.3f), "perfect", 1e-9},
                           Case{0.2, 0.3, 3.0, 1.0, 256.0, dir(0.1f, 0.3f), "perfect", 1e-9}}) {
        FlakeParams params = {{"flake_weight", {cs.weight}},
                              {"flake_roughness", {cs.roughness}},
                              {"gamma", {cs.gamma}},
                              {"shadowing", {cs.shadowing}},
                              {"exact_flakes", {cs.exact_flakes}}};
        if (cs.facet > 0.0) params.push_back({"flake_size", {cs.facet}});
        // "perfect": conductor flakes of the preset that reflects everything.
        const bool perfect = std::string(cs.fresnel) == "perfect";
        FlakeStrings strings = {{"fresnel", perfect ? "conductor" : cs.fresnel}};
        if (perfect) strings.push_back({"preset", "perfect"});
        auto smooth = flake_material(false, params, strings);
        BsdfHarness::Point far;
        far.has_differentials = false;
        smooth->prepare(cs.wo, far);
        const double limit = smooth->albedo(200000, 5).mean;
        // Metal and Schlick flakes (f0 0.9) reflect most of what reaches them, glass ones a few
        // percent.
        const bool glass = std::string(cs.fresnel) == "dielectric";
        ASSERT_GT(limit, (glass ? 0.01 : 0.5) * cs.weight) << cs.fresnel;
        for (double lambda : {0.5, 1.0, 3.0}) {
            double mean[2], se[2];
            for (int alg = 0; alg < 2; ++alg) {
                FlakeStrings with = strings;
                with.push_back({"algorithm", alg == 0 ? "tree" : "enumerate"});
                auto disc = flake_material(true, params, with);
                constexpr int kFootprints = 4000;
                double sum = 0.0, sum2 = 0.0;
                for (int k = 0; k < kFootprints; ++k) {
                    disc->prepare(cs.wo, random_footprint(lambda, 400, static_cast<uint64_t>(k)));
                    const double a = disc->albedo(64, static_cast<uint64_t>(k)).mean;
                    sum += a;
                    sum2 += a * a;
                }
                mean[alg] = sum / kFootprints;
                se[alg] = std::sqrt(std::max(0.0, sum2 / kFootprints - mean[alg] * mean[alg]) /
                                    kFootprints);
            }
            const std::string what = fmt::format(
                "{} roughness {} shadowing {} cos_o {} exact_flakes {} flake_size {} lambda {}",
                cs.fresnel, cs.roughness, cs.shadowing, cs.wo.z, cs.exact_flakes, cs.facet, lambda);
            if (cs.exact_flakes > 1.0) {
                for (int alg = 0; alg < 2; ++alg)
                    EXPECT_NEAR(mean[alg], limit, 4.0 * se[alg] + 0.01 * limit)
                        << (alg == 0 ? "tree " : "enumerate ") << what << ": ratio "
                        << mean[alg] / limit << " +- " << se[alg] / limit;
            } else {
                // Against the enumeration on the same footprints (a 45-degree cone loses the
                // part of it under the horizon, more for the flakes of small weight, so neither
                // is the limit there).
                EXPECT_NEAR(mean[0], mean[1], 4.0 * std::hypot(se[0], se[1]))
                    << "tree against enumerate, " << what << ": " << mean[0] << " and " << mean[1];
            }
        }
    }
}

TEST(FlakeExpectation, ADenseSecondPopulationKeepsTheSparseFirstOnesShare) {
    // Sparse flakes beside a second population a thousand times denser (its footprints nominal):
    // averaged over footprints the material reflects its smooth limit. The second population's
    // nominal share reset the first one's to nominal too, losing its empty footprints (they
    // showed flakes that were not there, the base not at all): 0.76 of the far look at lambda
    // 0.6 (a user's render). Bound: 4 standard errors plus the smooth table's 1%.
    const FlakeParams params = {{"flake_weight", {0.3}},
                                {"flake_roughness", {0.3}},
                                {"gamma", {3.0}},
                                {"shadowing", {0.0}},
                                {"base_color", {0.5}},
                                {"flakes2_weight", {0.05}},
                                {"flakes2_density", {kTestDensity * 1000.0}}};
    const Vec3 wo = dir(0.8f, 0.3f);
    auto smooth = flake_material(false, params);
    BsdfHarness::Point far;
    far.has_differentials = false;
    smooth->prepare(wo, far);
    const double limit = smooth->albedo(200000, 5).mean;
    auto disc = flake_material(true, params);
    for (double lambda : {0.5, 2.0}) {
        constexpr int kFootprints = 4000;
        double sum = 0.0, sum2 = 0.0;
        for (int k = 0; k < kFootprints; ++k) {
            disc->prepare(wo, random_footprint(lambda, 410, static_cast<uint64_t>(k)));
            const double a = disc->albedo(64, static_cast<uint64_t>(k)).mean;
            sum += a;
            sum2 += a * a;
        }
        const double mean = sum / kFootprints;
        const double se = std::sqrt(std::max(0.0, sum2 / kFootprints - mean * mean) / kFootprints);
        EXPECT_NEAR(mean, limit, 4.0 * se + 0.01 * limit)
            << "lambda " << lambda << ": ratio " << mean / limit << " +- " << se / limit;
    }
}

TEST(FlakeExpectation, ColourTableAveragesToItsMean) {
    // Flakes coloured from the table: the average over footprints is the table's mean colour.
    const FlakeParams params = {{"color_table", {1.0}},
                                {"hue_spread", {40.0}},
                                {"base_color", {0.6, 0.1, 0.1}},
                                {"gamma", {3.0}}};
    for (const char* algorithm : {"tree", "enumerate"}) {
        auto disc = flake_material(true, params, {{"algorithm", algorithm}});
        auto smooth = flake_material(false, params);
        const Vec3 wo = dir(0.7f, 0.0f), wi = mirror(wo);
        const Vec3 s = smooth_f(*smooth, wo, {wi})[0];
        Vec3 sum(0.0f), sum2(0.0f);
        constexpr int kFootprints = 2000;
        std::vector<Vec3> f;
        std::vector<float> pdf;
        for (int k = 0; k < kFootprints; ++k) {
            disc->prepare(wo, random_footprint(600.0, 400, static_cast<uint64_t>(k)));
            disc->eval({wi}, f, pdf);
            sum += f[0];
            sum2 += f[0] * f[0];
        }
        for (int ch = 0; ch < 3; ++ch) {
            const double mean = sum[ch] / kFootprints;
            const double se =
                std::sqrt(std::max(0.0, sum2[ch] / kFootprints - mean * mean) / kFootprints);
            EXPECT_NEAR(mean, s[ch], 4.0 * se + 0.01 * s[ch]) << algorithm << " channel " << ch;
        }
    }
}

/** Per-bin albedo contributions (f cos / pdf of the closure's own samples, binned in the warped
 *  domain, 8 x 8 bins) averaged over footprints, with their standard errors. */
struct Histogram {
    std::vector<double> mean, se;
};
Histogram energy_histogram(BsdfHarness& m, Vec3 wo, double lambda, const Warp& warp, int footprints,
                           uint32_t samples, uint64_t seed) {
    constexpr int kB = 8;
    std::vector<double> sum(kB * kB, 0.0), sum2(kB * kB, 0.0), one(kB * kB);
    for (int k = 0; k < footprints; ++k) {
        m.prepare(wo, random_footprint(lambda, seed, static_cast<uint64_t>(k)));
        std::fill(one.begin(), one.end(), 0.0);
        for (const auto& s : m.sample(samples, seed + static_cast<uint64_t>(k))) {
            int lobe;
            double u1, u2;
            if (s.flags == 0 || !(s.pdf > 0.0f) || !warp.to_u(s.wi, lobe, u1, u2)) continue;
            const int b = std::min(kB - 1, static_cast<int>(u1 * kB)) * kB +
                          std::min(kB - 1, static_cast<int>(u2 * kB));
            one[static_cast<std::size_t>(b)] +=
                s.f.y * s.wi.z / s.pdf / static_cast<double>(samples);
        }
        for (std::size_t b = 0; b < one.size(); ++b) {
            sum[b] += one[b];
            sum2[b] += one[b] * one[b];
        }
    }
    Histogram h;
    for (std::size_t b = 0; b < sum.size(); ++b) {
        const double mean = sum[b] / footprints;
        h.mean.push_back(mean);
        h.se.push_back(std::sqrt(std::max(0.0, sum2[b] / footprints - mean * mean) / footprints));
    }
    return h;
}

TEST(FlakeExpectation, AlgorithmsAgreeOnWhereTheEnergyGoes) {
    // Footprints of 5000 flakes, where the counting algorithm aggregates: the footprint-averaged
    // energy each algorithm sends into each bin of directions agrees (a two-sample test: the sum
    // of squared z-scores over the bins is chi-square distributed).
    const Vec3 wo = dir(0.6f, 0.0f);
    const Warp warp{wo, 0.2f, 0.2f, 0.0f};
    const Histogram t = energy_histogram(*flake_material(true, {}, {{"algorithm", "tree"}}), wo,
                                         5000.0, warp, 300, 256, 500);
    const Histogram e = energy_histogram(*flake_material(true, {}, {{"algorithm", "enumerate"}}),
                                         wo, 5000.0, warp, 300, 256, 500);
    double stat = 0.0;
    int dof = 0;
    for (std::size_t b = 0; b < t.mean.size(); ++b) {
        const double var = t.se[b] * t.se[b] + e.se[b] * e.se[b];
        if (!(var > 0.0) || std::max(t.mean[b], e.mean[b]) < 1e-4) continue;
        stat += (t.mean[b] - e.mean[b]) * (t.mean[b] - e.mean[b]) / var;
        ++dof;
    }
    ASSERT_GT(dof, 20);
    EXPECT_GT(gamma_q(0.5 * dof, 0.5 * stat), 0.001) << "chi2 " << stat << " dof " << dof;
}

}  // namespace
}  // namespace spangle::test::flake_lobes
