// Glints are points: a flake lies at one place, so two footprints side by side (as two
// neighbouring pixels see the surface) hold different flakes and show different glints. Measured
// through the plugin ABI on rows of adjacent, non-overlapping footprints: how often a direction
// lit in one footprint is lit in the next, against how often it is lit at all, and how many
// footprints in a row one glint spans, for the counting algorithm against the enumeration.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/hash.h"
#include "flake_support.h"

namespace spangle::test::flake_glints {
namespace {

struct GlintRuns {
    double lit = 0.0;          ///< share of (footprint, direction) pairs with a glint
    double correlation = 0.0;  ///< of f between two neighbours, the same direction (mean over them)
    double run = 0.0;          ///< mean length of a run of neighbours brighter than twice the mean
    double cv = 0.0;           ///< spread of f over footprints / its mean (mean over directions)
};

/** Rows of footprints of `lambda` flakes each, `step` times their width apart along u (1: side
 *  by side; 0.5: each overlapping half of the last), `aspect` times as long in v as wide in u
 *  (a receding surface's footprints: narrow across, long in depth); wo at cos_o, and a fan of
 *  directions around the mirror direction (within the flake lobe's width). */
GlintRuns glint_runs(const char* algorithm, double lambda, float cos_o, float alpha, float gamma,
                     double step = 1.0, double aspect = 1.0) {
    auto m = flake_material(true, {{"flake_roughness", {alpha}}, {"gamma", {gamma}}},
                            {{"algorithm", algorithm}});
    const Vec3 wo = dir(cos_o, 0.3f);
    const Vec3 r = mirror(wo);
    std::vector<Vec3> wis;
    for (int a = -3; a <= 3; ++a)
        for (int b = -3; b <= 3; ++b) {
            const Vec3 d = normalize(Vec3(r.x + 0.3f * static_cast<float>(a) * alpha,
                                          r.y + 0.3f * static_cast<float>(b) * alpha, r.z));
            if (d.z > 0.05f) wis.push_back(d);
        }
    const double side = std::sqrt(lambda / kTestDensity);
    const double width = side / std::sqrt(aspect), length = side * std::sqrt(aspect);
    constexpr int kRows = 80, kPerRow = 16;
    const std::size_t nd = wis.size();
    // f of every footprint (row by row) in every direction.
    std::vector<std::vector<float>> rows(kRows * kPerRow);
    std::vector<Vec3> f;
    std::vector<float> pdf;
    for (int row = 0; row < kRows; ++row) {
        const double u0 = to_unit_double(hash2(91, 2 * row)) * 50.0 + 0.1;
        const double v0 = to_unit_double(hash2(91, 2 * row + 1)) * 50.0 + 0.1;
        for (int i = 0; i < kPerRow; ++i) {
            BsdfHarness::Point pt;
            pt.u = static_cast<float>(u0 + width * step * i);
            pt.v = static_cast<float>(v0);
            pt.dudx = static_cast<float>(width);
            pt.dvdy = static_cast<float>(length);
            m->prepare(wo, pt);
            m->eval(wis, f, pdf);
            auto& out = rows[static_cast<std::size_t>(row * kPerRow + i)];
            for (const Vec3& x : f) out.push_back(x.y);
        }
    }
    double lit = 0.0, cells = 0.0, corr = 0.0, runs = 0.0, run_cells = 0.0, cvsum = 0.0;
    for (std::size_t j = 0; j < nd; ++j) {
        double mean = 0.0;
        for (const auto& v : rows) mean += v[j];
        mean /= static_cast<double>(rows.size());
        double cxy = 0.0, cxx = 0.0, cyy = 0.0, mx = 0.0, my = 0.0, n = 0.0;
        for (int row = 0; row < kRows; ++row)
            for (int i = 0; i + 1 < kPerRow; ++i) {
                const double x = rows[static_cast<std::size_t>(row * kPerRow + i)][j];
                const double y = rows[static_cast<std::size_t>(row * kPerRow + i + 1)][j];
                mx += x;
                my += y;
                cxy += x * y;
                cxx += x * x;
                cyy += y * y;
                n += 1.0;
            }
        mx /= n;
        my /= n;
        const double var_x = cxx / n - mx * mx, var_y = cyy / n - my * my;
        cvsum += mx > 0 ? std::sqrt(std::max(var_x, 0.0)) / mx : 0.0;
        corr += var_x > 0.0 && var_y > 0.0 ? (cxy / n - mx * my) / std::sqrt(var_x * var_y) : 0.0;
        for (int row = 0; row < kRows; ++row) {
            int run = 0;
            for (int i = 0; i < kPerRow; ++i) {
                const bool bright =
                    rows[static_cast<std::size_t>(row * kPerRow + i)][j] > 2.0 * mean;
                lit += bright ? 1.0 : 0.0;
                cells += 1.0;
                if (bright) ++run;
                if (run > 0 && (!bright || i + 1 == kPerRow)) {
                    runs += 1.0;
                    run_cells += run;
                    run = 0;
                }
            }
        }
    }
    GlintRuns g;
    g.lit = lit / cells;
    g.correlation = corr / static_cast<double>(nd);
    g.run = runs > 0.0 ? run_cells / runs : 0.0;
    g.cv = cvsum / static_cast<double>(nd);
    return g;
}

TEST(FlakeGlints, NeighbouringFootprintsShowTheirOwnGlints) {
    // Where the counting algorithm aggregates a cell, every footprint in the cell used to see the
    // cell's first k stand-ins: neighbours lit the same directions (sparse cells: a correlation
    // of 0.22 to 0.35, fewer and longer glints: blotches and dashes in a render) or the same
    // modulation of the lobe (dense cells: 0.17 to 0.25). Sparse cells are now enumerated up to
    // 4096 flakes, and an aggregate's stand-ins have places of their own in the cell (a
    // footprint has those it covers). The enumeration's neighbours are independent: a correlation
    // of 0 up to sampling noise (about 0.01 here), glints one footprint long. And the counted lobe
    // varies from footprint to footprint as much as the flakes' own, sqrt(lambda) x CV flat as
    // theirs (a cone wide against the flake lobe, gamma 6 at alpha 0.1, used to vary 4-10x less:
    // its direction tree had 4 leaves; the default material beyond lambda 3000, 0.55 times as much:
    // the modulation's tent spans more than a cone).
    struct Case {
        double lambda;
        float cos_o, alpha, gamma;
        bool sparse;  ///< few flakes per cone: single glints (else a nearly smooth lobe)
    };
    for (const Case& c :
         {Case{600, 0.8f, 0.25f, 2.5f, true}, Case{1500, 0.8f, 0.25f, 2.5f, true},
          Case{300, 0.9f, 0.15f, 3.0f, true}, Case{1500, 0.9f, 0.15f, 3.0f, false},
          Case{1800, 0.5f, 0.1f, 6.0f, false}, Case{8000, 0.5f, 0.1f, 6.0f, false},
          Case{3000, 0.8f, 0.15f, 3.0f, false}, Case{10000, 0.8f, 0.15f, 3.0f, false}}) {
        const GlintRuns e = glint_runs("enumerate", c.lambda, c.cos_o, c.alpha, c.gamma);
        const GlintRuns t = glint_runs("tree", c.lambda, c.cos_o, c.alpha, c.gamma);
        EXPECT_LT(std::fabs(e.correlation), 0.05) << "enumerate, lambda " << c.lambda;
        EXPECT_LT(t.correlation, 0.05) << "tree, lambda " << c.lambda;
        EXPECT_NEAR(t.cv, e.cv, 0.25 * e.cv) << "tree, lambda " << c.lambda;
        if (c.sparse) {
            // Enough glints to measure (pairs brighter than twice the mean: 0.1% to a few %),
            // as many under both algorithms, as short.
            ASSERT_GT(e.lit, 0.001) << c.lambda;
            EXPECT_NEAR(t.lit, e.lit, 0.25 * e.lit) << c.lambda;
            EXPECT_LT(t.run, 1.1 * e.run) << "tree, lambda " << c.lambda;
        }
    }
}

TEST(FlakeGlints, GrazingFootprintsSideBySideShowTheirOwnGlints) {
    // A receding surface at grazing views: pixels' footprints 16 and 24 times as long in depth as
    // they are wide across (cos 0.06 and 0.04), side by side across. They hold different flakes,
    // so their glints are as independent as those of square footprints: a correlation of 0 up to
    // noise, glints one footprint long. The footprint's axis ratio was clamped to 4 (its narrow
    // side widened): each footprint covered 4 to 6 of its neighbours, so a flake lit a run of
    // pixels across the surface (horizontal dashes at grazing; correlation 0.75 here) and
    // lambda was as many times too large. Now clamped at 32.
    for (double aspect : {16.0, 24.0})
        for (const char* algorithm : {"enumerate", "tree"})
            for (double lambda : {600.0, 3000.0}) {
                const GlintRuns g = glint_runs(algorithm, lambda, 0.8f, 0.25f, 2.5f, 1.0, aspect);
                EXPECT_LT(std::fabs(g.correlation), 0.05)
                    << algorithm << " lambda " << lambda << " aspect " << aspect;
                if (lambda < 1000.0) {
                    ASSERT_GT(g.lit, 0.001) << algorithm << " lambda " << lambda;
                    EXPECT_LT(g.run, 1.2)
                        << algorithm << " lambda " << lambda << " aspect " << aspect;
                }
            }
}

TEST(FlakeGlints, OverlappingFootprintsShareGlintsAsFlakesDo) {
    // Footprints that overlap hold many of the same flakes: the samples of one pixel, a pixel and
    // its neighbour across a receding surface (footprints long in depth, narrow across and wider
    // than the pixels are apart). Their lobes are correlated as much as the flakes they share,
    // and a render's glints are as large as real ones. The counting algorithm's stand-ins were
    // keyed by where a footprint lay in its cell, on a grid of half the footprint's longer side:
    // neighbours closer than that saw the very same stand-ins (horizontal dashes at grazing:
    // correlation near 1) and the samples of one pixel up to four independent sets (a pixel
    // smoother than one of real flakes). Stand-ins now have places of their own and footprints
    // share those they both cover. Aggregated footprints (lambda 3000 to 20000, dense cones).
    struct Case {
        double lambda;
        float cos_o;
        double step, aspect;
    };
    // Lambda 600 and 1000: aggregates whose k is at times below the number of stand-ins the
    // footprint finds (it then keeps the k of smallest hash, so that overlapping footprints keep
    // the same ones; keeping the first k in block order gave the same figures here).
    for (const Case& c :
         {Case{600, 0.8f, 0.5, 1.0}, Case{1000, 0.8f, 0.25, 1.0}, Case{3000, 0.8f, 0.5, 1.0},
          Case{20000, 0.8f, 0.25, 1.0}, Case{3000, 0.3f, 0.5, 4.0}, Case{20000, 0.3f, 0.25, 4.0}}) {
        const GlintRuns e =
            glint_runs("enumerate", c.lambda, c.cos_o, 0.15f, 3.0f, c.step, c.aspect);
        const GlintRuns t = glint_runs("tree", c.lambda, c.cos_o, 0.15f, 3.0f, c.step, c.aspect);
        // Half and three quarters of each footprint shared: the enumeration's lobes are
        // correlated by about as much (0.49 to 0.50 and 0.75). The counting algorithm's agree
        // within 0.01 here (keyed by place they were 0.03, 0.39, 0.66 and 0.78 at lambda 3000 and
        // 20000); 0.05 is well
        // above the sampling spread of a correlation over 1200 pairs (about 0.02 for one
        // direction, less for the mean over the fan).
        EXPECT_GT(e.correlation, 0.3) << "enumerate, lambda " << c.lambda;
        EXPECT_NEAR(t.correlation, e.correlation, 0.05)
            << "lambda " << c.lambda << " cos_o " << c.cos_o << " aspect " << c.aspect;
        EXPECT_NEAR(t.cv, e.cv, 0.25 * e.cv) << "tree, lambda " << c.lambda;
    }
}

TEST(FlakeGlints, NestedFootprintsLightNestedDirections) {
    // A footprint holds the flakes of every footprint inside it, so every direction its half-size
    // copy (same centre, a quarter of the area) lights, it lights too: glints do not appear and
    // vanish as the camera dollies. The enumeration nests exactly; the counting algorithm's
    // aggregates, counted per cell at each footprint's own level, did not (14-26% of the
    // directions at lambda 200-2000); with sparse cells enumerated, under 1% here.
    for (const char* algorithm : {"enumerate", "tree"})
        for (double lambda : {200.0, 600.0}) {
            auto m = flake_material(true, {}, {{"algorithm", algorithm}});
            const Vec3 wo = dir(0.8f, 0.3f);
            const std::vector<Vec3> wis = fan(mirror(wo), 0.05f, 6, 0.05f);
            double lit_small = 0.0, not_big = 0.0;
            std::vector<Vec3> fs, fb;
            std::vector<float> pdf;
            for (uint64_t k = 0; k < 200; ++k) {
                const BsdfHarness::Point big = random_footprint(lambda, 77, k);
                BsdfHarness::Point small = big;
                small.dudx *= 0.5f;
                small.dvdy *= 0.5f;
                m->prepare(wo, small);
                m->eval(wis, fs, pdf);
                m->prepare(wo, big);
                m->eval(wis, fb, pdf);
                for (std::size_t j = 0; j < wis.size(); ++j)
                    if (fs[j].y > 0.0f) {
                        lit_small += 1.0;
                        not_big += fb[j].y > 0.0f ? 0.0 : 1.0;
                    }
            }
            ASSERT_GT(lit_small, 1000.0) << algorithm << " lambda " << lambda;
            const double share = not_big / lit_small;
            if (std::string(algorithm) == "enumerate")
                EXPECT_EQ(not_big, 0.0) << "lambda " << lambda;
            else
                EXPECT_LT(share, 0.01) << "tree, lambda " << lambda;
        }
}

}  // namespace
}  // namespace spangle::test::flake_glints
