// The flake field (../shared/FLAKES.md sections 1 to 3): determinism and nesting of the flakes,
// unbiased counts, exact multinomial splits, the map from the unit square to GGX flake normals,
// and the counting algorithm's view of the same field.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>

#include "chi2.h"
#include "core/hash.h"
#include "counted_lobe.h"
#include "discrete_lobe.h"
#include "field.h"

namespace spangle::test::flake_field {
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

TEST(FlakeField, SplitsHaveMultinomialMoments) {
    // Each child ~ B(n, 1/4): mean n/4, variance 3n/16, covariance of two children -n/16, for the
    // exact split (n = 40, 500 with exact_below 1000) and the normal approximation (n = 1e5).
    for (const auto& [n, exact_below] :
         {std::pair<uint32_t, int>{40, 1000}, {500, 1000}, {100000, 0}}) {
        constexpr int kN = 40000;
        double s0 = 0, s00 = 0, s1 = 0, s01 = 0;
        for (int i = 0; i < kN; ++i) {
            uint32_t c[4];
            flake::split_counts(hash2(17, static_cast<uint64_t>(i)), n, exact_below, c);
            s0 += c[0];
            s00 += static_cast<double>(c[0]) * c[0];
            s1 += c[1];
            s01 += static_cast<double>(c[0]) * c[1];
        }
        const double m0 = s0 / kN, v0 = s00 / kN - m0 * m0, m1 = s1 / kN;
        const double cov = s01 / kN - m0 * m1;
        const double var = 3.0 * n / 16.0;
        // Standard errors: of a mean sqrt(var / N); of a variance about var sqrt(2 / N); of the
        // covariance about sqrt(var^2 / N).
        EXPECT_NEAR(m0, n / 4.0, 4.0 * std::sqrt(var / kN)) << "n " << n;
        EXPECT_NEAR(v0, var, 4.0 * var * std::sqrt(2.0 / kN)) << "n " << n;
        EXPECT_NEAR(cov, -static_cast<double>(n) / 16.0, 4.0 * var / std::sqrt(kN)) << "n " << n;
    }
}

TEST(FlakeField, AddingAFlakeAddsItToOneChild) {
    // Below exact_below a split draws two bits per flake: n + 1 flakes split like n, plus one.
    for (uint64_t key = 0; key < 500; ++key)
        for (uint32_t n = 0; n < 120; n += 7) {
            uint32_t a[4], b[4];
            flake::split_counts(hash2(key, 99), n, 128, a);
            flake::split_counts(hash2(key, 99), n + 1, 128, b);
            int grew = 0;
            for (int c = 0; c < 4; ++c) {
                ASSERT_GE(b[c], a[c]);
                grew += static_cast<int>(b[c] - a[c]);
            }
            ASSERT_EQ(grew, 1);
        }
}

TEST(FlakeField, BinomialMomentsExactAndNormal) {
    // Mean n p and variance n p (1 - p) for both samplers (n = 100 exact, n = 100000 normal).
    for (const auto& [n, exact_below] : {std::pair<uint32_t, int>{100, 1000}, {100000, 0}}) {
        double sum = 0, sum2 = 0;
        constexpr int kN = 40000;
        for (int i = 0; i < kN; ++i) {
            const double k = flake::binomial(
                n, 0.3, to_unit_double(hash2(3, static_cast<uint64_t>(i))), exact_below);
            sum += k;
            sum2 += k * k;
        }
        const double mean = sum / kN, var = sum2 / kN - mean * mean;
        const double want_mean = n * 0.3, want_var = n * 0.3 * 0.7;
        EXPECT_NEAR(mean, want_mean, 4.0 * std::sqrt(want_var / kN)) << "n " << n;
        EXPECT_NEAR(var, want_var, 4.0 * want_var * std::sqrt(2.0 / kN)) << "n " << n;
    }
}

TEST(FlakeField, BinomialNeverDecreasesWithP) {
    // The counting algorithm thins a cell's flakes by the share of it the footprint covers: a
    // footprint that covers more must not see fewer (inversion of the CDF is monotone).
    for (uint32_t n : {3u, 50u, 120u})
        for (int i = 0; i < 300; ++i) {
            const double u = to_unit_double(hash2(5, static_cast<uint64_t>(i)));
            uint32_t prev = 0;
            for (double p = 0.0; p <= 1.0; p += 0.01) {
                const uint32_t k = flake::binomial(n, p, u, 128);
                ASSERT_GE(k, prev) << "n " << n << " p " << p;
                prev = k;
            }
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

TEST(FlakeField, ClassBlockCountsArePoissonAndGrowWithTheMean) {
    // A ranked class's block holds a Poisson count drawn by inverting the block's own uniform:
    // the counts follow the law (chi-square), and for one block the count never falls as the
    // mean grows (a footprint's share of a class nests in the class).
    constexpr int kBlocks = 200000;
    for (double mean : {0.4, 1.7, 3.0}) {
        const flake::PoissonCdf law(mean), more(mean * 1.3 + 0.05);
        std::vector<double> observed(16, 0.0), expected(16, 0.0);
        for (int b = 0; b < kBlocks; ++b) {
            const uint64_t key = hash2(77, static_cast<uint64_t>(b));
            const uint32_t k = law.count(key);
            observed[std::min<uint32_t>(k, 15)] += 1.0;
            ASSERT_LE(k, more.count(key)) << "mean " << mean << " block " << b;
            // The search is the count of cdf entries at most u.
            uint32_t linear = 0;
            for (double c : law.cdf) linear += flake::unit(key) >= c ? 1u : 0u;
            ASSERT_EQ(k, linear) << "mean " << mean << " block " << b;
        }
        double pmf = std::exp(-mean);
        for (int k = 0; k < 16; ++k) {
            expected[k] = kBlocks * pmf;
            pmf *= mean / (k + 1);
        }
        double tail = kBlocks;
        for (int k = 0; k < 15; ++k) tail -= expected[k];
        expected[15] = tail;
        EXPECT_GT(chi2_test(observed, expected).p_value, 0.001) << "mean " << mean;
    }
}

TEST(FlakeField, FootprintClampKeepsCentreAndBoundsTheRatio) {
    // A needle of ratio 100 is widened to the largest ratio; one of 20 (a view at cos 0.05)
    // keeps its shape.
    const Footprint p = flake::make_footprint(0.5, 0.5, 0.1, 0.0, 0.0, 0.001, 1.0);
    const double la = std::hypot(p.ax, p.ay), lb = std::hypot(p.bx, p.by);
    EXPECT_NEAR(std::max(la, lb) / std::min(la, lb), flake::kMaxFootprintRatio, 1e-9);
    EXPECT_GE(flake::kMaxFootprintRatio, 20.0);
    const Footprint q = flake::make_footprint(0.5, 0.5, 0.02, 0.0, 0.0, 0.001, 1.0);
    EXPECT_NEAR(q.area(), 0.02 * 0.001, 1e-15);
    EXPECT_EQ(p.cu, 0.5);
    const Footprint z = flake::make_footprint(0.5, 0.5, 0, 0, 0, 0, 1.0);
    EXPECT_EQ(z.area(), 0.0);
}

TEST(FlakeField, OverlapAreaMatchesMonteCarlo) {
    for (int t = 0; t < 30; ++t) {
        const auto r = [&](int k) {
            return to_unit_double(hash2(31 + k, static_cast<uint64_t>(t)));
        };
        const Footprint p = flake::make_footprint(r(0), r(1), 0.6 * r(2) - 0.3, 0.6 * r(3) - 0.3,
                                                  0.6 * r(4) - 0.3, 0.6 * r(5) - 0.3, 1.0);
        const double x0 = 0.2 * r(6), y0 = 0.2 * r(7), x1 = x0 + 0.5, y1 = y0 + 0.4;
        constexpr int kN = 200000;
        int in = 0;
        for (int i = 0; i < kN; ++i) {
            const double u = x0 + (x1 - x0) * to_unit_double(hash2(41, static_cast<uint64_t>(i)));
            const double v = y0 + (y1 - y0) * to_unit_double(hash2(42, static_cast<uint64_t>(i)));
            in += flake::inside(p, u, v);
        }
        const double cell = (x1 - x0) * (y1 - y0), frac = static_cast<double>(in) / kN;
        EXPECT_NEAR(flake::overlap_area(p, x0, y0, x1, y1) / cell, frac,
                    4.0 * std::sqrt(frac * (1.0 - frac) / kN) + 1e-9)
            << "trial " << t;
    }
}

TEST(FlakeField, StripSpanHoldsEveryPointOfTheFootprintInItsRow) {
    // Loops over rows of class blocks visit only the blocks under StripSpan's range: it must hold
    // every point of P in the row (points missed would be flakes lost), and for a turned needle
    // it must be far narrower than P's bounding box (the reason for it).
    for (int t = 0; t < 300; ++t) {
        const auto r = [&](int k) {
            return to_unit_double(hash2(61 + k, static_cast<uint64_t>(t)));
        };
        // Footprints of every shape up to the needles of the largest axis ratio.
        const double len = 0.3 * r(2), ang = 6.2831853 * r(3), thin = len * std::pow(0.02, r(4));
        const Footprint p =
            flake::make_footprint(r(0), r(1), len * std::cos(ang), len * std::sin(ang),
                                  -thin * std::sin(ang) * r(5), thin * std::cos(ang), 1.0);
        const flake::StripSpan span(p);
        const double hy = p.half_height();
        for (int row = 0; row < 20; ++row) {
            const double y0 = p.cv - 1.2 * hy + 2.4 * hy * to_unit_double(hash2(71, 20 * t + row));
            const double y1 = y0 + 0.3 * hy * to_unit_double(hash2(72, 20 * t + row));
            double x0 = 0.0, x1 = 0.0;
            const bool any = span.at(y0, y1, x0, x1);
            // Points of P: a grid over (s, t), its edges and corners included.
            for (int i = 0; i <= 40; ++i)
                for (int j = 0; j <= 40; ++j) {
                    const double s = i / 40.0 - 0.5, q = j / 40.0 - 0.5;
                    const double u = p.cu + s * p.ax + q * p.bx, v = p.cv + s * p.ay + q * p.by;
                    if (v < y0 || v > y1) continue;
                    ASSERT_TRUE(any) << "trial " << t << " row " << row;
                    ASSERT_GE(u, x0) << "trial " << t << " row " << row;
                    ASSERT_LE(u, x1) << "trial " << t << " row " << row;
                }
            // Never a range beyond P's bounding box (but for the margin against rounding, a
            // millionth of its width).
            if (any) {
                const double margin = 2e-6 * p.half_width();
                EXPECT_GE(x0, p.cu - p.half_width() - margin) << "trial " << t;
                EXPECT_LE(x1, p.cu + p.half_width() + margin) << "trial " << t;
            }
        }
    }
    // Footprints whose edges meet a row's edge to the last bit, where the slabs' arithmetic and
    // the inside test's round differently (found in review): every point the inside test
    // accepts on the row's edges lies in the range. One axis-aligned (its t slab bounds y
    // alone) and one with an edge nearly parallel to x (a slope of 2^58).
    const auto with_inverse = [](double cu, double cv, double ax, double ay, double bx, double by) {
        Footprint p;
        p.cu = cu;
        p.cv = cv;
        p.ax = ax;
        p.ay = ay;
        p.bx = bx;
        p.by = by;
        const double det = ax * by - ay * bx;
        p.i00 = by / det;
        p.i01 = -bx / det;
        p.i10 = -ay / det;
        p.i11 = ax / det;
        return p;
    };
    const Footprint edges[] = {with_inverse(0.5, 0x1p-54, 1.0, 0.0, 0.0, 1.0 - 0x1p-53),
                               with_inverse(0.5, 0.5, 0.0, 0.25, -0.25, 0x1p-60)};
    for (const Footprint& p : edges) {
        const flake::StripSpan span(p);
        for (double block : {0.125, 0.0625, 0.03125})
            for (int by = 0; by < static_cast<int>(1.0 / block); ++by) {
                const double y0 = by * block, y1 = (by + 1) * block;
                double x0 = 0.0, x1 = 0.0;
                const bool any = span.at(y0, y1, x0, x1);
                for (const double y : {y0, std::nextafter(y0, 1.0), std::nextafter(y1, 0.0)})
                    for (int i = 0; i <= 512; ++i) {
                        const double x = p.cu - p.half_width() + 2.0 * p.half_width() * i / 512.0;
                        if (!flake::inside_nonsingular(p, x, y)) continue;
                        ASSERT_TRUE(any) << "row " << y0 << " point " << x << ", " << y;
                        ASSERT_GE(x, x0);
                        ASSERT_LE(x, x1);
                    }
            }
    }
    // A needle at 45 degrees, 32 times as long as it is wide: a thin row through its middle is a
    // small part of its bounding box's width; a row beyond it has no range.
    const Footprint needle = flake::make_footprint(0.5, 0.5, 0.2, 0.2, -0.00625, 0.00625, 1.0);
    const flake::StripSpan span(needle);
    double x0 = 0.0, x1 = 0.0;
    ASSERT_TRUE(span.at(0.495, 0.505, x0, x1));
    EXPECT_LT(x1 - x0, 0.25 * 2.0 * needle.half_width());
    EXPECT_FALSE(span.at(0.75, 0.8, x0, x1));
}

TEST(FlakeNormals, SquareMapRoundTrips) {
    for (float alpha : {0.001f, 0.15f, 1.0f})
        for (int i = 0; i < 20000; ++i) {
            const auto s = static_cast<float>(to_unit_double(hash2(51, static_cast<uint64_t>(i))));
            const auto t = static_cast<float>(to_unit_double(hash2(52, static_cast<uint64_t>(i))));
            const flake::V3 m = flake::flake_normal(alpha, s, t);
            ASSERT_NEAR(std::sqrt(m.x * m.x + m.y * m.y + m.z * m.z), 1.0f, 1e-5f);
            float s2, t2;
            flake::flake_square(alpha, m, s2, t2);
            // Float precision of the stretch: tilted normals of alpha 0.001 lose a few bits.
            ASSERT_NEAR(s2, s, 2e-3f) << "alpha " << alpha;
            ASSERT_NEAR(t2, t, 2e-3f) << "alpha " << alpha;
        }
}

TEST(FlakeNormals, AreTheConcentricMapLiftedAndStretched) {
    // flake_normal() picks the concentric map's sector by selects (no branch) and takes sin and
    // cos from polynomials: against the map written out with the library's sin and cos.
    for (float alpha : {0.001f, 0.15f, 1.0f})
        for (int i = 0; i < 20000; ++i) {
            const auto s = static_cast<float>(to_unit_double(hash2(53, static_cast<uint64_t>(i))));
            const auto t = static_cast<float>(to_unit_double(hash2(54, static_cast<uint64_t>(i))));
            const double a = 2.0 * s - 1.0, b = 2.0 * t - 1.0;
            double x = 0.0, y = 0.0;
            if (std::fabs(a) > std::fabs(b)) {
                const double phi = M_PI / 4.0 * (b / a);
                x = a * std::cos(phi);
                y = a * std::sin(phi);
            } else if (b != 0.0) {
                const double phi = M_PI / 2.0 - M_PI / 4.0 * (a / b);
                x = b * std::cos(phi);
                y = b * std::sin(phi);
            }
            // Near the disk's rim the lift z = sqrt(1 - x^2 - y^2), in float, loses what its
            // cancellation costs: an ulp of x^2 + y^2 (6e-8) against z^2 is a relative error of
            // 3e-8 / z^2 in z and in the stretched normal (|m| = 1); four times that is allowed
            // there, 1e-6 elsewhere.
            const double z2 = 1.0 - (x * x + y * y);
            const double tol = 1e-6 + 1.2e-7 / std::max(z2, 1e-7);
            const double z = std::sqrt(std::max(0.0, z2));
            const double len = std::sqrt(alpha * alpha * (x * x + y * y) + z * z);
            const flake::V3 m = flake::flake_normal(alpha, s, t);
            ASSERT_NEAR(m.x, alpha * x / len, tol) << "alpha " << alpha << " s " << s << " t " << t;
            ASSERT_NEAR(m.y, alpha * y / len, tol) << "alpha " << alpha << " s " << s << " t " << t;
            ASSERT_NEAR(m.z, z / len, tol) << "alpha " << alpha << " s " << s << " t " << t;
        }
}

TEST(FlakeNormals, BatchedCacheEntriesAreEachFlakesOwn) {
    // The reflection cache's entries are made a batch at a time (normals in vector code): each
    // must be what its flake alone gives, bit for bit, in order, with the flakes that face away
    // from wo or reflect it under the horizon left out. Views from head-on to grazing, more
    // flakes than one batch holds, colours, Fresnel tables and scales of their own.
    flake::FresnelTable fresnel[2];
    for (int k = 0; k < flake::FresnelTable::kNodes; ++k) {
        const float x = 1.0f - static_cast<float>(k) / (flake::FresnelTable::kNodes - 1);
        const float x5 = x * x * x * x * x;
        for (int c = 0; c < 3; ++c) {
            const auto fc = static_cast<float>(c);
            fresnel[0].rgb[k][c] = 0.9f - 0.1f * fc + (0.1f + 0.1f * fc) * x5;
            fresnel[1].rgb[k][c] = 0.04f + 0.96f * x5;
        }
    }
    const float colours[3][3] = {{1.0f, 1.0f, 1.0f}, {0.8f, 0.3f, 0.1f}, {0.2f, 0.5f, 0.9f}};
    for (const float alpha : {0.05f, 0.15f, 0.6f})
        for (const float cos_o : {1.0f, 0.7f, 0.2f, 0.01f}) {
            const flake::V3 wo{std::sqrt(1.0f - cos_o * cos_o) * 0.6f,
                               std::sqrt(1.0f - cos_o * cos_o) * 0.8f, cos_o};
            flake::EntryBatch batch;
            std::vector<flake::CacheEntry> out;
            std::vector<flake::CacheEntry> expected;
            for (uint64_t i = 0; i < 300; ++i) {
                float s, t;
                flake::unit2(hash2(55, i), s, t);
                const float* col = colours[i % 3];
                const flake::FresnelTable& fr = fresnel[i % 2];
                const float scale = 0.25f + 0.75f * static_cast<float>(i % 4) / 3.0f;
                batch.add(wo, alpha, s, t, col, &fr, scale, out);
                // The flake alone.
                const flake::V3 m = flake::flake_normal(alpha, s, t);
                const float c = spangle::mf::dot(wo, m);
                const flake::V3 r = spangle::mf::reflect(wo, m);
                if (c <= 0.0f || r.z <= 0.0f) continue;
                const float w = c / m.z;
                float f[3], rgb[3];
                fr.eval(c, f);
                for (int k = 0; k < 3; ++k) rgb[k] = w * col[k] * f[k];
                flake::CacheEntry e;
                e.r = r;
                for (int k = 0; k < 3; ++k) e.rgb[k] = rgb[k] * scale;
                e.lum = std::max(0.0f, flake::luminance(rgb)) * scale;
                e.w = w * scale;
                expected.push_back(e);
            }
            flake::flush_entries(wo, alpha, batch, out);
            EXPECT_EQ(batch.n, 0u);
            ASSERT_EQ(out.size(), expected.size()) << "alpha " << alpha << " cos_o " << cos_o;
            // At grazing many flakes reflect under the horizon: skipped ones occurred.
            if (cos_o < 0.05f) {
                EXPECT_LT(expected.size(), 300u);
            }
            for (std::size_t j = 0; j < out.size(); ++j) {
                const flake::CacheEntry &a = out[j], &b = expected[j];
                ASSERT_EQ(a.r.x, b.r.x) << j;
                ASSERT_EQ(a.r.y, b.r.y) << j;
                ASSERT_EQ(a.r.z, b.r.z) << j;
                for (int k = 0; k < 3; ++k) ASSERT_EQ(a.rgb[k], b.rgb[k]) << j;
                ASSERT_EQ(a.lum, b.lum) << j;
                ASSERT_EQ(a.w, b.w) << j;
            }
        }
}

TEST(FlakeNormals, FollowTheGgxDistribution) {
    // Normals with density D(m) (m.n) have tan^2(theta) with CDF x / (alpha^2 + x); their azimuth
    // is uniform. Chi-square over equal-probability bins of both.
    for (float alpha : {0.05f, 0.3f}) {
        constexpr int kBins = 40, kN = 200000;
        std::vector<double> radial(kBins, 0.0), azimuth(kBins, 0.0);
        for (int i = 0; i < kN; ++i) {
            const auto s = static_cast<float>(to_unit_double(hash2(61, static_cast<uint64_t>(i))));
            const auto t = static_cast<float>(to_unit_double(hash2(62, static_cast<uint64_t>(i))));
            const flake::V3 m = flake::flake_normal(alpha, s, t);
            const double x = (m.x * m.x + m.y * m.y) / (static_cast<double>(m.z) * m.z);
            const double cdf = x / (static_cast<double>(alpha) * alpha + x);
            radial[std::min(kBins - 1, static_cast<int>(cdf * kBins))] += 1.0;
            const double phi = std::atan2(m.y, m.x) / (2.0 * M_PI) + 0.5;
            azimuth[std::min(kBins - 1, static_cast<int>(phi * kBins))] += 1.0;
        }
        const std::vector<double> expected(kBins, static_cast<double>(kN) / kBins);
        EXPECT_GT(chi2_test(radial, expected).p_value, 0.01) << "alpha " << alpha;
        EXPECT_GT(chi2_test(azimuth, expected).p_value, 0.01) << "alpha " << alpha;
    }
}

TEST(FlakeNormals, CacheShareIsTheShareOfFlakesThatEnterTheCache) {
    // Flakes of normals drawn as the field draws them, through flush_entries itself: the share
    // that becomes cache entries (the rest reflect wo under the horizon) against the closed form
    // the sparse flake share divides by, within 4 binomial standard errors; head-on it is
    // 1 / (1 + alpha^2) exactly.
    for (float alpha : {0.1f, 0.3f, 0.6f}) {
        const auto a = static_cast<double>(alpha);
        EXPECT_NEAR(flake::cache_share_exact(alpha, 1.0f), 1.0 / (1.0 + a * a), 1e-12);
        flake::CacheShare table;
        table.init(alpha);
        for (float cos_o : {1.0f, 0.7f, 0.3f, 0.1f, 0.02f}) {
            const flake::V3 wo{std::sqrt(1.0f - cos_o * cos_o), 0.0f, cos_o};
            constexpr int kN = 100000;
            const float white[3] = {1.0f, 1.0f, 1.0f};
            flake::FresnelTable one;
            for (auto& node : one.rgb) node[0] = node[1] = node[2] = 1.0f;
            std::vector<flake::CacheEntry> out;
            flake::EntryBatch batch;
            for (int i = 0; i < kN; ++i) {
                const auto s =
                    static_cast<float>(to_unit_double(hash2(71, static_cast<uint64_t>(i))));
                const auto t =
                    static_cast<float>(to_unit_double(hash2(72, static_cast<uint64_t>(i))));
                batch.add(wo, alpha, s, t, white, &one, 1.0f, out);
            }
            flush_entries(wo, alpha, batch, out);
            const double share = static_cast<double>(out.size()) / kN;
            const double p = flake::cache_share_exact(alpha, cos_o);
            EXPECT_NEAR(share, p, 4.0 * std::sqrt(p * (1.0 - p) / kN) + 1e-6)
                << "alpha " << alpha << " cos_o " << cos_o;
            EXPECT_NEAR(table.at(cos_o), p, 2e-3) << "alpha " << alpha << " cos_o " << cos_o;
        }
        EXPECT_NEAR(flake::cache_share_exact(alpha, 1e-6f), 0.5, 1e-3) << "grazing";
    }
}

TEST(FlakeNormals, SparseAlbedoScalesFewFlakesToTheFarLook) {
    // A footprint of K flakes reflects sum w a / sum w of their albedos a (its own W normalises
    // it), the far look E[w a] / E[w]. Flakes drawn as the field draws them, through
    // flush_entries, grouped K at a time: the mean of the groups' albedos times the table's
    // scale is the far look, within 4 standard errors (of both: the far look's own is wide at
    // grazing views, where w is heavy-tailed) plus the quadrature's 0.5%. Glass flakes
    // of roughness 0.3 and 0.8 (their Fresnel rises where w is small: one flake alone reads 1.3x
    // the far look at cos 0.3) without and with shadowing (G1 at the mirror direction lowers the
    // tilted flakes'); white flakes without shadowing reflect alike at every tilt and are left
    // alone.
    flake::FresnelTable glass, white;
    for (int i = 0; i < flake::FresnelTable::kNodes; ++i) {
        const float c = static_cast<float>(i) / (flake::FresnelTable::kNodes - 1);
        for (int ch = 0; ch < 3; ++ch) {
            glass.rgb[i][ch] = spangle::mf::fresnel_dielectric(c, 1.5f);
            white.rgb[i][ch] = 1.0f;
        }
    }
    constexpr float kAlpha = 0.3f;
    flake::SparseAlbedo flat;
    flat.init(kAlpha, 0.05f, white, false);
    EXPECT_TRUE(flat.flat);
    for (const auto& [alpha, shadowing] :
         {std::pair<float, bool>{0.3f, false}, {0.3f, true}, {0.8f, false}, {0.8f, true}}) {
        flake::SparseAlbedo table;
        table.init(alpha, 0.05f, glass, shadowing);
        EXPECT_FALSE(table.flat);
        for (float cos_o : {0.8f, 0.3f, 0.1f, 0.03f}) {
            const flake::V3 wo{std::sqrt(1.0f - cos_o * cos_o), 0.0f, cos_o};
            const float one[3] = {1.0f, 1.0f, 1.0f};
            std::vector<flake::CacheEntry> out;
            flake::EntryBatch batch;
            constexpr int kN = 240000;
            for (int i = 0; i < kN; ++i) {
                const auto s =
                    static_cast<float>(to_unit_double(hash2(81, static_cast<uint64_t>(i))));
                const auto t =
                    static_cast<float>(to_unit_double(hash2(82, static_cast<uint64_t>(i))));
                batch.add(wo, alpha, s, t, one, &glass, 1.0f, out);
            }
            flush_entries(wo, alpha, batch, out);
            // Each entry's albedo: its rgb over its w (F), times G1 at its mirror direction.
            std::vector<double> w(out.size()), wa(out.size());
            double sum_w = 0.0, sum_wa = 0.0;
            for (std::size_t j = 0; j < out.size(); ++j) {
                const double g = shadowing ? spangle::mf::ggx_g1(out[j].r, alpha, alpha) : 1.0;
                w[j] = out[j].w;
                wa[j] = out[j].rgb[0] * g;
                sum_w += w[j];
                sum_wa += wa[j];
            }
            const double far = sum_wa / sum_w;
            // The far look's own standard error (a ratio estimator; w is heavy-tailed at
            // grazing views).
            double var_far = 0.0;
            for (std::size_t j = 0; j < out.size(); ++j)
                var_far += (wa[j] - far * w[j]) * (wa[j] - far * w[j]);
            const double se_far = std::sqrt(var_far) / sum_w;
            for (uint32_t k : {1u, 2u, 4u, 8u, 40u}) {
                const std::size_t groups = out.size() / k;
                double sum = 0.0, sum2 = 0.0;
                for (std::size_t g = 0; g < groups; ++g) {
                    double gw = 0.0, gwa = 0.0;
                    for (std::size_t j = g * k; j < (g + 1) * k; ++j) {
                        gw += w[j];
                        gwa += wa[j];
                    }
                    sum += gwa / gw;
                    sum2 += (gwa / gw) * (gwa / gw);
                }
                const double mean = sum / static_cast<double>(groups);
                const double se =
                    std::sqrt(std::max(0.0, sum2 / static_cast<double>(groups) - mean * mean) /
                              static_cast<double>(groups));
                float scale[3];
                table.at(cos_o, k, scale);
                const double scaled = mean * static_cast<double>(scale[0]);
                EXPECT_NEAR(
                    scaled, far,
                    4.0 * std::hypot(se * static_cast<double>(scale[0]), se_far) + 0.005 * far)
                    << "alpha " << alpha << " shadowing " << shadowing << " cos_o " << cos_o
                    << " K " << k << ": unscaled " << mean / far << " of the far look, scale "
                    << scale[0];
            }
        }
    }
    // Raised only while the footprint reflects at most what it receives: white flakes with
    // shadowing (G1 lowers the tilted ones, so few flakes read under the far look). A flake
    // reflecting along the normal (G1 1) keeps rgb at most its weight; one reflecting 84 degrees
    // from it is raised, to at most its weight over G1 at its cone's edge nearest the normal.
    constexpr float kGamma = 0.05f;
    flake::SparseAlbedo shadowed;
    shadowed.init(kAlpha, kGamma, white, true);
    float up[3];
    shadowed.at(0.2f, 1, up);
    EXPECT_GT(up[0], 1.0f) << "one shadowed white flake reads under the far look";
    for (float cos_r : {1.0f, 0.1f}) {
        flake::CacheEntry e{};
        e.r = {std::sqrt(1.0f - cos_r * cos_r), 0.0f, cos_r};
        e.w = 0.7f;
        e.rgb[0] = e.rgb[1] = e.rgb[2] = 0.7f;
        shadowed.apply(0.2f, 1, &e, &e + 1);
        const float theta = std::max(0.0f, std::acos(cos_r) - kGamma);
        const float g =
            spangle::mf::ggx_g1(flake::V3{std::sin(theta), 0.0f, std::cos(theta)}, kAlpha, kAlpha);
        EXPECT_LE(e.rgb[0] * g, e.w * (1.0f + 1e-6f)) << "cos_r " << cos_r;
        EXPECT_FLOAT_EQ(e.lum, e.rgb[1]);
        if (cos_r < 1.0f) {
            EXPECT_GT(e.rgb[0], 0.7f) << "a shadowed flake is raised";
        }
    }
}

TEST(FlakeCounting, SmallFootprintsSeeTheEnumeratedFlakes) {
    // Cells under exact_flakes are enumerated: the counting algorithm finds exactly the flakes
    // the enumeration finds, the quad-tree's and the ranked classes', whatever the leaf size
    // (leaves of one or two flakes leave many tree nodes empty: a cell whose node was empty and
    // whose drawn class count was 0 was skipped, and its class flakes went missing).
    for (const auto& [n, leaf] : {std::pair<double, int>{100000.0, 16}, {300.0, 2}, {300.0, 1}}) {
        FieldParams fp = field(n);
        fp.leaf_size = leaf;
        for (int t = 0; t < 100; ++t) {
            // 5 to 15 flakes in the dense field, 0.5 to 10.4 in the sparse one.
            const double side = std::sqrt(n > 1000.0 ? (5.0 + 0.1 * t) / n : (0.5 + 0.1 * t) / n);
            const Footprint p =
                flake::make_footprint(10.0 * to_unit_double(hash2(71, static_cast<uint64_t>(t))),
                                      10.0 * to_unit_double(hash2(72, static_cast<uint64_t>(t))),
                                      side, 0.2 * side, 0.0, side, 1.0);
            std::vector<std::pair<double, double>> counted;
            flake::CountedFootprint cf;
            flake::gather_cells(fp, p, 1000, cf,
                                [&](const Flake& f) { counted.emplace_back(f.u, f.v); });
            std::sort(counted.begin(), counted.end());
            EXPECT_EQ(cf.n_agg, 0u);
            EXPECT_EQ(counted, flakes_in(fp, p)) << "trial " << t << " leaf size " << leaf;
        }
    }
}

TEST(FlakeCounting, CountsAreUnbiased) {
    // Enumerated plus aggregated flakes in random footprints of expected count lambda: mean lambda
    // (the aggregates' binomial thinning is unbiased), variance about lambda. Each footprint in a
    // field of its own: footprints of one field that share a cell share its count, and their
    // mean strays further than independent trials' (seed 11 alone: 3.3 of these standard errors
    // at lambda 20000, seeds 100 to 107 within 1.7).
    for (double lambda : {50.0, 800.0, 20000.0}) {
        constexpr int kTrials = 3000;
        double sum = 0, sum2 = 0;
        const double side = std::sqrt(lambda / 100000.0);
        for (int t = 0; t < kTrials; ++t) {
            const Footprint p =
                flake::make_footprint(50.0 * to_unit_double(hash2(81, static_cast<uint64_t>(t))),
                                      50.0 * to_unit_double(hash2(82, static_cast<uint64_t>(t))),
                                      side, 0.0, 0.0, side, 1.0);
            FieldParams fp = field(100000);
            fp.seed = 1000 + static_cast<uint64_t>(t);
            flake::CountedFootprint cf;
            uint32_t exact = 0;
            flake::gather_cells(fp, p, 64, cf, [&](const Flake&) { ++exact; });
            ASSERT_FALSE(cf.truncated);
            const double k = exact + cf.aggregated;
            sum += k;
            sum2 += k * k;
        }
        const double mean = sum / kTrials, var = sum2 / kTrials - mean * mean;
        EXPECT_NEAR(mean, lambda, 4.0 * std::sqrt(lambda / kTrials)) << "lambda " << lambda;
        // A cell's count and its thinning are both binomial: the variance is lambda to within
        // the correlation of neighbouring cells' counts (under 20% here).
        EXPECT_NEAR(var / lambda, 1.0, 0.2) << "lambda " << lambda;
    }
}

TEST(FlakeCounting, WorkIsBoundedForAnyFootprint) {
    // However large the footprint or the density, a shading point visits at most 4 tiles and
    // 16 cells: the counting algorithm either gathers or declines (the smooth lobe takes over).
    for (double density : {1.0, 1e5, 2147483647.0})
        for (double side : {1e-7, 1e-3, 0.5, 3.0, 1e6}) {
            const FieldParams fp = field(density);
            const Footprint p = flake::make_footprint(0.3, 0.6, side, 0.0, 0.0, side, 1.0);
            flake::CountedFootprint cf;
            uint32_t exact = 0;
            flake::gather_cells(fp, p, 256, cf, [&](const Flake&) { ++exact; });
            EXPECT_LE(cf.n_agg, flake::kMaxAggregates);
            EXPECT_LE(exact, 16u * 256u);
            if (side > 2.0) {
                EXPECT_TRUE(cf.truncated);
            }
        }
}

TEST(FlakeCounting, FootprintsThatAreNotNumbersOrFarAwayAreDeclined) {
    // A NaN centre or extent (a degenerate uv) and uv far beyond any tile index: the tile range
    // is computed without overflow or a float-to-int conversion of NaN, and counting declines
    // (truncated, no cells) so that the smooth lobe takes over instead of a black lobe.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    const FieldParams fp = field(1e4);
    struct Case {
        double u, v, side;
    };
    for (const Case c :
         {Case{nan, 0.5, 1e-3}, Case{0.5, nan, 1e-3}, Case{0.5, 0.5, nan}, Case{0.5, 0.5, inf},
          Case{1e30, -1e30, 1e-3}, Case{-inf, 0.5, 1e-3}, Case{0.5, 0.5, 1e25}}) {
        Footprint p = flake::make_footprint(0.3, 0.6, 1e-3, 0.0, 0.0, 1e-3, 1.0);
        p.cu = c.u;
        p.cv = c.v;
        p.ax = p.by = c.side;
        const flake::TileRange tr = flake::tiles_of(p);
        if (std::isnan(c.u) || std::isnan(c.v) || std::isnan(c.side)) {
            EXPECT_GT(tr.count(), 64u) << c.u << " " << c.v << " " << c.side;
        }
        flake::CountedFootprint cf;
        uint32_t exact = 0;
        flake::gather_cells(fp, p, 256, cf, [&](const Flake&) { ++exact; });
        if (std::isnan(c.u) || std::isnan(c.v) || std::isnan(c.side) || c.side > 2.0) {
            EXPECT_TRUE(cf.truncated) << c.u << " " << c.v << " " << c.side;
            EXPECT_EQ(cf.n_agg, 0u);
            EXPECT_EQ(exact, 0u);
        }
    }
    // A wide range saturates instead of overflowing.
    Footprint wide;
    wide.ax = wide.by = 1e19;
    EXPECT_EQ(flake::tiles_of(wide).count(), UINT64_MAX);
}

}  // namespace
}  // namespace spangle::test::flake_field
