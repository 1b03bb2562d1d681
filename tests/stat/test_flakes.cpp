// The flake model's tests (../shared/FLAKES.md section 7): the flake field's determinism, nesting
// and unbiased counts; chi-square of sample() against pdf(); convergence of the discrete lobe to
// its smooth expectation; white furnace; the hard cases of the stability suite.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "bsdf_harness.h"
#include "chi2.h"
#include "core/hash.h"
#include "field.h"

namespace spangle::test {
namespace {

using flake::FieldParams;
using flake::Flake;
using flake::Footprint;

std::vector<std::pair<double, double>> flakes_in(const FieldParams& fp, const Footprint& p,
                                                 uint32_t cap = 1000000) {
    std::vector<std::pair<double, double>> out;
    bool truncated = false;
    flake::for_each_flake(fp, p, cap, truncated,
                          [&](const Flake& f) { out.emplace_back(f.u, f.v); });
    EXPECT_FALSE(truncated);
    std::sort(out.begin(), out.end());
    return out;
}

FieldParams field(double n) {
    FieldParams fp;
    fp.seed = 11;
    fp.flakes_per_tile = n;
    return fp;
}

TEST(FlakeField, ChildCountsSumToParent) {
    for (uint32_t n : {0u, 1u, 5u, 16u, 127u, 128u, 1000u, 123456u, 2147483647u})
        for (uint64_t key = 0; key < 200; ++key) {
            uint32_t c[4];
            flake::split_counts(hash2(key, n), n, 128, c);
            ASSERT_EQ(static_cast<uint64_t>(c[0]) + c[1] + c[2] + c[3], n) << "n " << n;
        }
}

TEST(FlakeField, BinomialMomentsExactAndNormal) {
    // Mean n p and variance n p (1 - p) for both samplers (n = 100 exact, n = 100000 normal).
    for (const auto& [n, exact_below] : {std::pair<uint32_t, int>{100, 1000}, {100000, 0}}) {
        double sum = 0, sum2 = 0;
        constexpr int kN = 40000;
        for (int i = 0; i < kN; ++i) {
            const double k = flake::binomial(
                n, 0.25, to_unit_double(hash2(3, static_cast<uint64_t>(i))), exact_below);
            sum += k;
            sum2 += k * k;
        }
        const double mean = sum / kN, var = sum2 / kN - mean * mean;
        const double want_mean = n * 0.25, want_var = n * 0.25 * 0.75;
        // Standard error of the mean sqrt(var / N); of the variance about var sqrt(2 / N).
        EXPECT_NEAR(mean, want_mean, 4.0 * std::sqrt(want_var / kN)) << "n " << n;
        EXPECT_NEAR(var, want_var, 4.0 * want_var * std::sqrt(2.0 / kN)) << "n " << n;
    }
}

TEST(FlakeField, SetIsAPureFunctionOfTheFootprint) {
    const FieldParams fp = field(100000);
    const Footprint p = flake::make_footprint(0.3, 0.7, 0.01, 0.002, -0.003, 0.012, 1.0);
    const auto a = flakes_in(fp, p), b = flakes_in(fp, p);
    EXPECT_GT(a.size(), 5u);
    EXPECT_EQ(a, b);
    FieldParams other = fp;
    other.seed = 12;
    EXPECT_NE(flakes_in(other, p), a) << "another seed is another realisation";
}

TEST(FlakeField, NestedFootprintsGiveSubsets) {
    const FieldParams fp = field(500000);
    for (int trial = 0; trial < 20; ++trial) {
        const double cu = 0.05 + 0.9 * to_unit_double(hash2(7, static_cast<uint64_t>(trial)));
        const double cv = 0.05 + 0.9 * to_unit_double(hash2(8, static_cast<uint64_t>(trial)));
        const Footprint big = flake::make_footprint(cu, cv, 0.02, 0.004, -0.006, 0.018, 1.0);
        const Footprint small = flake::make_footprint(cu, cv, 0.02, 0.004, -0.006, 0.018, 0.5);
        const auto outer = flakes_in(fp, big), inner = flakes_in(fp, small);
        EXPECT_TRUE(std::includes(outer.begin(), outer.end(), inner.begin(), inner.end()))
            << "trial " << trial;
        EXPECT_LT(inner.size(), outer.size());
    }
}

TEST(FlakeField, CountsAreUnbiasedWithBinomialVariance) {
    // Random footprints of fixed area A inside a tile of N flakes hold Binomial(N, A) flakes.
    for (const auto& [n, scale, depth] : {std::tuple<double, double, int>{200000, 0.004, 12},
                                          {2147483647.0, 0.0002, 24},
                                          {2000, 0.05, 10}}) {
        FieldParams fp = field(n);
        fp.max_depth = depth;
        constexpr int kTrials = 3000;
        double sum = 0, sum2 = 0, area = 0;
        for (int t = 0; t < kTrials; ++t) {
            const double cu = 0.1 + 0.8 * to_unit_double(hash2(21, static_cast<uint64_t>(t)));
            const double cv = 0.1 + 0.8 * to_unit_double(hash2(22, static_cast<uint64_t>(t)));
            const Footprint p =
                flake::make_footprint(cu, cv, scale, 0.3 * scale, -0.2 * scale, 0.9 * scale, 1.0);
            area = p.area();
            bool truncated = false;
            const double k =
                flake::for_each_flake(fp, p, 100000000, truncated, [](const Flake&) {});
            sum += k;
            sum2 += k * k;
        }
        const double lambda = n * area;
        const double mean = sum / kTrials, var = sum2 / kTrials - mean * mean;
        const double want_var = lambda * (1.0 - area);
        EXPECT_NEAR(mean, lambda, 4.0 * std::sqrt(want_var / kTrials)) << "N " << n;
        // The sample variance of a Poisson-like count has standard error ~ var sqrt(2 / trials)
        // (plus a kurtosis term 1 / lambda that is small here).
        EXPECT_NEAR(var, want_var,
                    5.0 * want_var * std::sqrt(2.0 / kTrials + 1.0 / (kTrials * lambda)))
            << "N " << n;
    }
}

TEST(FlakeField, FootprintClampKeepsCentreAndBoundsTheRatio) {
    const Footprint p = flake::make_footprint(0.5, 0.5, 0.1, 0.0, 0.0, 0.001, 1.0);
    const double la = std::hypot(p.ax, p.ay), lb = std::hypot(p.bx, p.by);
    EXPECT_NEAR(std::max(la, lb) / std::min(la, lb), 4.0, 1e-9);
    EXPECT_EQ(p.cu, 0.5);
    const Footprint z = flake::make_footprint(0.5, 0.5, 0, 0, 0, 0, 1.0);
    EXPECT_EQ(z.area(), 0.0);
}

// ------------------------------------------------------------------------------------ the material

using Params = std::vector<std::pair<std::string, std::vector<double>>>;
using Strings = std::vector<std::pair<std::string, std::string>>;

/** A flake material: flakes only; with `discrete` the discrete lobe is kept for every footprint
 *  (the smooth lobe is reached by preparing without differentials). */
std::unique_ptr<BsdfHarness> flake_material(bool discrete, Params extra = {},
                                            Strings strings = {}) {
    Params p = {{"flake_weight", {1.0}}, {"base_color", {0.0}}};
    if (discrete) {
        p.push_back({"min_flakes", {1e6}});
        p.push_back({"max_flakes", {1e7}});
    }
    for (auto& e : extra) p.push_back(e);
    return std::make_unique<BsdfHarness>("flake", "flake", p, strings);
}

Vec3 dir(float cos_t, float phi) {
    const float s = std::sqrt(1.0f - cos_t * cos_t);
    return {s * std::cos(phi), s * std::sin(phi), cos_t};
}

/** A footprint of expected count lambda (density 1e5 per uv square) at (u, v). */
BsdfHarness::Point point_with_lambda(double lambda, float u, float v) {
    BsdfHarness::Point pt;
    const double side = std::sqrt(lambda / 1e5);
    pt.u = u;
    pt.v = v;
    pt.dudx = static_cast<float>(side);
    pt.dvdy = static_cast<float>(side);
    return pt;
}

/** Chi-square of sample() against pdf() for the discrete lobe of one footprint. Expected counts
 *  integrate pdf() over each sphere bin by quadrature inside every flake's cone (the lobe lives
 *  only there), divided by how many cones cover a point so overlaps count once. */
void chi2_discrete(double lambda, float gamma_deg) {
    auto m = flake_material(
        true, {{"density", {1e5}}, {"gamma", {gamma_deg}}, {"flake_roughness", {0.2}}},
        {{"algorithm", "enumerate"}});
    const Vec3 wo = dir(0.8f, 0.3f);
    const BsdfHarness::Point pt = point_with_lambda(lambda, 0.43f, 0.57f);
    m->prepare(wo, pt);
    // The oracle: the same flakes, facing wo, reflecting above the horizon.
    FieldParams fp = field(1e5);
    fp.seed = 0;
    fp.alpha = 0.2f;
    const Footprint p = flake::make_footprint(pt.u, pt.v, pt.dudx, pt.dvdx, pt.dudy, pt.dvdy, 1.0);
    std::vector<Vec3> cones;
    bool truncated = false;
    flake::for_each_flake(fp, p, 100000, truncated, [&](const Flake& f) {
        const Vec3 mm(f.m.x, f.m.y, f.m.z);
        if (dot(wo, mm) <= 0.0f) return;
        const Vec3 r = mm * (2.0f * dot(wo, mm)) - wo;
        if (r.z > 0.0f) cones.push_back(r);
    });
    ASSERT_GT(cones.size(), 0u);
    const float gamma = gamma_deg * kPi / 180.0f;
    const float thr = 4.0f * std::sin(0.5f * gamma) * std::sin(0.5f * gamma);
    constexpr int kZ = 24, kPhi = 48;
    const auto bin_of = [&](Vec3 w) {
        const int bz = std::min(kZ - 1, static_cast<int>(w.z * kZ));
        double phi = std::atan2(static_cast<double>(w.y), static_cast<double>(w.x));
        if (phi < 0) phi += 2 * M_PI;
        const int bp = std::min(kPhi - 1, static_cast<int>(phi / (2 * M_PI) * kPhi));
        return static_cast<std::size_t>(bz * kPhi + bp);
    };
    // Quadrature per cone: rings in u = (1 - cos psi) / (1 - cos gamma) at u = 1 - (1 - t)^2 for
    // t uniform (weight 2 (1 - t) dt: dense at the rim, where a bin boundary may cut off a thin
    // sliver that a coarse rule would leave without points), sectors equal in angle.
    constexpr int kRings = 64, kSectors = 128;
    std::vector<Vec3> q;
    std::vector<double> weight;
    const double cap = 2.0 * M_PI * (1.0 - std::cos(gamma));
    for (const Vec3& r : cones) {
        Vec3 s, t;
        make_basis(r, s, t);
        for (int i = 0; i < kRings; ++i) {
            const double tt = (i + 0.5) / kRings, u = 1.0 - (1.0 - tt) * (1.0 - tt);
            const double c = 1.0 - u * (1.0 - std::cos(gamma));
            const double sn = std::sqrt(std::max(0.0, 1.0 - c * c));
            for (int j = 0; j < kSectors; ++j) {
                const double ph = (j + 0.5) * 2.0 * M_PI / kSectors;
                const Vec3 w = normalize(s * static_cast<float>(sn * std::cos(ph)) +
                                         t * static_cast<float>(sn * std::sin(ph)) +
                                         r * static_cast<float>(c));
                if (w.z <= 0.0f) continue;
                int mult = 0;
                for (const Vec3& o : cones) mult += dot(w - o, w - o) <= thr;
                q.push_back(w);
                weight.push_back(cap * 2.0 * (1.0 - tt) / (kRings * kSectors) / std::max(1, mult));
            }
        }
    }
    std::vector<Vec3> f;
    std::vector<float> pdf;
    m->eval(q, f, pdf);
    constexpr uint32_t kN = 200000;
    std::vector<double> expected(kZ * kPhi + 1, 0.0), observed(kZ * kPhi + 1, 0.0);
    double total = 0.0;
    for (std::size_t k = 0; k < q.size(); ++k) {
        expected[bin_of(q[k])] += kN * pdf[k] * weight[k];
        total += pdf[k] * weight[k];
    }
    EXPECT_NEAR(total, 1.0, 0.02)
        << "the discrete pdf integrates to one over the cones above the horizon";
    expected.back() = std::max(0.0, kN * (1.0 - total));
    for (const auto& s : m->sample(kN, 31)) {
        if (s.flags == 0) {
            observed.back() += 1.0;
            continue;
        }
        // Every sampled direction lies in some flake's cone (where the pdf is not zero).
        float nearest = 4.0f;
        for (const Vec3& o : cones) nearest = std::min(nearest, dot(s.wi - o, s.wi - o));
        ASSERT_LE(nearest, thr * 1.0001f) << "a sample outside every cone";
        observed[bin_of(s.wi)] += 1.0;
    }
    const Chi2Result r = chi2_test(observed, expected);
    EXPECT_GT(r.p_value, 0.01) << "lambda " << lambda << " flakes " << cones.size() << ": chi2 "
                               << r.statistic << " dof " << r.dof;
}

TEST(FlakeLobe, ChiSquareFewFlakes) {
    chi2_discrete(8.0, 3.0f);
}
TEST(FlakeLobe, ChiSquareManyFlakes) {
    chi2_discrete(400.0, 2.0f);
}

/** Mean over random footprints of the discrete lobe vs the smooth lobe, at (wo, wi). */
void expectation_matches(bool table, float cos_o = 0.7f) {
    Params common = {{"density", {1e5}}, {"gamma", {1.0}}, {"flake_roughness", {0.35}}};
    Strings strings;
    if (table) {
        common.push_back({"color_table", {1.0}});
        common.push_back({"hue_spread", {40.0}});
        common.push_back({"base_color", {0.6, 0.1, 0.1}});
    }
    auto disc = flake_material(true, common, strings);
    auto smooth = flake_material(false, common, strings);
    const Vec3 wo = dir(cos_o, 0.0f);
    const std::vector<Vec3> wis = {dir(cos_o, kPi), dir(0.9f, 2.5f), dir(0.5f, 3.5f)};
    std::vector<Vec3> fs;
    std::vector<float> ps;
    BsdfHarness::Point sp;
    sp.has_differentials = false;
    smooth->prepare(wo, sp);
    smooth->eval(wis, fs, ps);
    constexpr int kFootprints = 6000;
    for (std::size_t k = 0; k < wis.size(); ++k) {
        Vec3 sum(0.0f), sum2(0.0f);
        for (int t = 0; t < kFootprints; ++t) {
            disc->prepare(
                wo,
                point_with_lambda(
                    600.0,
                    static_cast<float>(to_unit_double(hash2(51, static_cast<uint64_t>(t)))) * 50.0f,
                    static_cast<float>(to_unit_double(hash2(52, static_cast<uint64_t>(t)))) *
                        50.0f));
            std::vector<Vec3> f;
            std::vector<float> p;
            disc->eval({wis[k]}, f, p);
            sum += f[0];
            sum2 += f[0] * f[0];
        }
        for (int ch = 0; ch < 3; ++ch) {
            const double mean = sum[ch] / kFootprints;
            const double se =
                std::sqrt(std::max(0.0, sum2[ch] / kFootprints - mean * mean) / kFootprints);
            // 4 standard errors, plus 2% for the ratio estimator's O(1/lambda) bias (lambda 600)
            // and the 1 degree cone's smoothing of the lobe.
            EXPECT_NEAR(mean, fs[k][ch], 4.0 * se + 0.02 * fs[k][ch])
                << "wi " << k << " channel " << ch << " table " << table;
        }
    }
}

TEST(FlakeLobe, DiscreteMeanConvergesToTheSmoothLobe) {
    expectation_matches(false);
}
TEST(FlakeLobe, DiscreteMeanConvergesWithTheColourTable) {
    expectation_matches(true);
}
TEST(FlakeLobe, DiscreteMeanConvergesAtGrazingAngles) {
    expectation_matches(false, 0.3f);
    expectation_matches(false, 0.1f);
}

/** Albedo estimate: mean of f cos / pdf over sample(), averaged over footprints. */
double material_albedo(BsdfHarness& m, Vec3 wo, bool discrete) {
    double sum = 0.0;
    int n = 0;
    for (int t = 0; t < 40; ++t) {
        BsdfHarness::Point pt = point_with_lambda(
            discrete ? 30.0 : 1e6, static_cast<float>(t) * 0.37f, static_cast<float>(t) * 0.61f);
        m.prepare(wo, pt);
        for (const auto& s : m.sample(2000, static_cast<uint64_t>(t))) {
            if (s.flags != 0 && s.pdf > 0.0f) sum += static_cast<double>(s.f.y) * s.wi.z / s.pdf;
            ++n;
        }
    }
    return sum / n;
}

TEST(FlakeFurnace, WholeMaterialNeverGainsEnergy) {
    for (bool coat : {false, true})
        for (bool discrete : {true, false})
            for (float c : {1.0f, 0.6f, 0.2f}) {
                Params p = {{"flake_weight", {0.5}},   {"base_color", {1.0}},
                            {"density", {1e5}},        {"coat", {coat ? 1.0 : 0.0}},
                            {"coat_roughness", {0.1}}, {"shadowing", {0.0}}};
                BsdfHarness m("flake", "flake", p, {{"preset", "perfect"}});
                const double e = material_albedo(m, dir(c, 0.4f), discrete);
                // 80000 samples of a weight bounded by about 2: standard error below 0.01.
                EXPECT_LE(e, 1.0 + 0.03)
                    << "coat " << coat << " discrete " << discrete << " cos " << c;
                EXPECT_GT(e, 0.5) << "white base and perfect mirror flakes keep most of the energy";
            }
}

TEST(FlakeStability, HardCasesStayFiniteAndConsistent) {
    struct Hard {
        const char* name;
        Params params;
        Vec3 wo;
        BsdfHarness::Point pt;
    };
    const auto pt = [](float u, float v, float d, bool diff = true) {
        BsdfHarness::Point p;
        p.u = u;
        p.v = v;
        p.dudx = p.dvdy = d;
        p.dvdx = 0.3f * d;
        p.has_differentials = diff;
        return p;
    };
    const std::vector<Hard> cases = {
        {"grazing", {}, dir(1e-4f, 0.3f), pt(0.3f, 0.3f, 0.002f)},
        {"zero area", {}, dir(0.7f, 0.3f), pt(0.3f, 0.3f, 0.0f)},
        {"huge footprint", {}, dir(0.7f, 0.3f), pt(0.3f, 0.3f, 1e6f)},
        {"uv far outside", {}, dir(0.7f, 0.3f), pt(-1.0e7f, 3.0e6f, 0.002f)},
        {"one flake", {{"density", {1.0}}}, dir(0.7f, 0.3f), pt(0.3f, 0.3f, 0.5f)},
        {"2^31-1 flakes",
         {{"density", {2147483647.0}}, {"max_depth", {24.0}}},
         dir(0.7f, 0.3f),
         pt(0.3f, 0.3f, 1e-5f)},
        {"tiny gamma", {{"gamma", {0.01}}}, dir(0.7f, 0.3f), pt(0.3f, 0.3f, 0.002f)},
        {"large gamma", {{"gamma", {45.0}}}, dir(0.7f, 0.3f), pt(0.3f, 0.3f, 0.002f)},
        {"roughness near 0",
         {{"flake_roughness", {0.001}}},
         dir(0.7f, 0.3f),
         pt(0.3f, 0.3f, 0.002f)},
        {"roughness 1", {{"flake_roughness", {1.0}}}, dir(0.7f, 0.3f), pt(0.3f, 0.3f, 0.002f)},
        {"no differentials", {}, dir(0.7f, 0.3f), pt(0.3f, 0.3f, 0.0f, false)},
        {"coat, grazing", {{"coat", {1.0}}}, dir(1e-3f, 0.3f), pt(0.3f, 0.3f, 0.002f)},
    };
    for (const Hard& h : cases) {
        Params p = h.params;
        p.push_back({"min_flakes", {50.0}});
        p.push_back({"max_flakes", {400.0}});
        BsdfHarness m("flake", "flake", p);
        m.prepare(h.wo, h.pt);
        const auto samples = m.sample(3000, 5);
        std::vector<Vec3> wi;
        for (const auto& s : samples) {
            ASSERT_TRUE(std::isfinite(s.pdf) && is_finite(s.f) && is_finite(s.wi)) << h.name;
            ASSERT_GE(s.pdf, 0.0f) << h.name;
            ASSERT_GE(std::min({s.f.x, s.f.y, s.f.z}), 0.0f) << h.name;
            if (s.flags != 0) wi.push_back(s.wi);
        }
        std::vector<Vec3> f;
        std::vector<float> pdf;
        m.eval(wi, f, pdf);
        for (std::size_t i = 0; i < wi.size(); ++i) {
            if (max_component(f[i]) > 0.0f) {
                ASSERT_GT(pdf[i], 0.0f) << h.name << ": f > 0 where pdf is 0";
            }
        }
        std::vector<Vec3> random;
        for (uint32_t i = 0; i < 500; ++i)
            random.push_back(
                dir(2.0f * sample_1d(6, i, 0, 0) - 1.0f, 2.0f * kPi * sample_1d(6, i, 0, 1)));
        m.eval(random, f, pdf);
        for (std::size_t i = 0; i < random.size(); ++i) {
            ASSERT_TRUE(is_finite(f[i]) && std::isfinite(pdf[i])) << h.name;
            ASSERT_GE(pdf[i], 0.0f) << h.name;
            ASSERT_GE(std::min({f[i].x, f[i].y, f[i].z}), 0.0f) << h.name;
        }
    }
}

}  // namespace
}  // namespace spangle::test
