// Flake facets (flake_size): the share of a facet inside a footprint, its nesting and mean, the
// point-flake limit, and the material around a facet through the plugin ABI (a footprint inside
// one facet is that flat mirror, one between facets is the base; energy; sampling against pdf is
// in test_flake_lobes.cpp, the footprint average against the smooth lobe in
// test_flake_looks.cpp).

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "core/hash.h"
#include "discrete_lobe.h"
#include "facet.h"
#include "field.h"
#include "flake_support.h"

namespace spangle::test::flake_facets {
namespace {

namespace fl = spangle::flake;

/** An axis-aligned square footprint of side `side` centred at (u, v). */
fl::Footprint square(double u, double v, double side) {
    return fl::make_footprint(u, v, side, 0.0, 0.0, side, 1.0);
}

TEST(FlakeFacets, CoverageIsTheShareOfTheOutlineInside) {
    // Exact cases by symmetry, for any turn of the facet (the turn comes from the flake's hash):
    // the disc (a 32-gon) and the square are unchanged by quarter turns and every regular polygon
    // by a half turn, so an edge through the centre halves each of them and a corner quarters the
    // disc and the square.
    const fl::Footprint p = square(0.5, 0.5, 0.2);
    for (fl::FacetKind kind :
         {fl::FacetKind::Hexagon, fl::FacetKind::Square, fl::FacetKind::Round}) {
        const fl::FacetShape shape(kind);
        for (uint64_t id = 1; id < 40; ++id) {
            const uint64_t h = hash2(17, id);
            EXPECT_EQ(fl::facet_coverage(p, shape, 0.01, 0.5, 0.5, h), 1.0f);
            EXPECT_EQ(fl::facet_coverage(p, shape, 0.01, 0.75, 0.5, h), 0.0f);
            EXPECT_NEAR(fl::facet_coverage(p, shape, 0.01, 0.4, 0.52, h), 0.5f, 1e-5f);
            EXPECT_NEAR(fl::facet_coverage(p, shape, 0.01, 0.55, 0.6, h), 0.5f, 1e-5f);
            if (kind != fl::FacetKind::Hexagon) {
                EXPECT_NEAR(fl::facet_coverage(p, shape, 0.01, 0.4, 0.4, h), 0.25f, 1e-5f);
                EXPECT_NEAR(fl::facet_coverage(p, shape, 0.01, 0.6, 0.6, h), 0.25f, 1e-5f);
            }
        }
        // Areas at unit width: flat to flat for the hexagon, side for the square, diameter for
        // the disc (its 32-gon within 0.7% of pi / 4).
        const double expected = kind == fl::FacetKind::Hexagon  ? std::sqrt(3.0) / 2.0
                                : kind == fl::FacetKind::Square ? 1.0
                                                                : M_PI / 4.0;
        EXPECT_NEAR(shape.area, expected, kind == fl::FacetKind::Round ? 0.007 : 1e-12);
    }
    // A singular footprint covers nothing.
    const fl::Footprint flat = fl::make_footprint(0.5, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0);
    EXPECT_EQ(fl::facet_coverage(flat, fl::FacetShape(fl::FacetKind::Hexagon), 0.01, 0.5, 0.5, 3),
              0.0f);
}

/** A sheared footprint of expected count lambda (density kTestDensity) at (u, v), scaled. */
fl::Footprint sheared(double lambda, double u, double v, double scale) {
    const double side = std::sqrt(lambda / kTestDensity / 1.06);  // det [a b] = 1.06 side^2
    return fl::make_footprint(u, v, side, 0.3 * side, -0.2 * side, side, scale);
}

/** The facets reaching into P (sheared footprint of expected count lambda at (u, v)), by id. */
std::map<uint64_t, float> facets_in(const fl::FacetShape& shape, double facet, double lambda,
                                    double u, double v, double scale) {
    fl::FieldParams fp;
    fp.flakes_per_tile = kTestDensity;
    fp.alpha = 0.3f;
    fp.facet = &shape;
    fp.facet_size = facet;
    fl::Footprint p = sheared(lambda, u, v, scale);
    p.reach = facet * shape.radius;
    std::map<uint64_t, float> out;
    bool truncated = false;
    fl::for_each_flake(fp, p, 1u << 20, truncated,
                       [&](const fl::Flake& f) { out[f.id] = f.cover; });
    EXPECT_FALSE(truncated);
    return out;
}

/** Visits the facets reaching into the footprint of harness point pt (axis-aligned, dudx by
 *  dvdy) in the field a facet material of density kTestDensity and roughness 0.3 lays out;
 *  returns whether the visit was cut short. */
template <class Visit>
bool for_each_facet(const fl::FacetShape& shape, double facet, const BsdfHarness::Point& pt,
                    Visit&& visit) {
    fl::FieldParams fp;
    fp.flakes_per_tile = kTestDensity;
    fp.alpha = 0.3f;
    fp.facet = &shape;
    fp.facet_size = facet;
    fl::Footprint p = fl::make_footprint(pt.u, pt.v, pt.dudx, 0.0, 0.0, pt.dvdy, 1.0);
    p.reach = facet * shape.radius;
    bool truncated = false;
    fl::for_each_flake(fp, p, 1000, truncated, visit);
    return truncated;
}

TEST(FlakeFacets, SharesAreNestedAndAverageToTheExpectedCount) {
    // A footprint inside another sees each facet at most as much; over random footprints the
    // shares add up to lambda on average (a facet's area is counted once wherever it falls), for
    // facets from a tenth of the footprint's width to three times it.
    const fl::FacetShape shape(fl::FacetKind::Hexagon);
    const double lambda = 20.0, side = std::sqrt(lambda / kTestDensity);
    EXPECT_NEAR(sheared(lambda, 0.5, 0.5, 1.0).area() * kTestDensity, lambda, 1e-9);
    for (double rel : {0.1, 1.0, 3.0}) {
        double sum = 0.0, sum2 = 0.0;
        constexpr int kFootprints = 1500;
        for (int k = 0; k < kFootprints; ++k) {
            const double u = to_unit_double(hash2(5, 2 * k)) * 50.0;
            const double v = to_unit_double(hash2(5, 2 * k + 1)) * 50.0;
            const auto whole = facets_in(shape, rel * side, lambda, u, v, 1.0);
            const auto half = facets_in(shape, rel * side, lambda, u, v, 0.5);
            for (const auto& [id, c] : half) {
                const auto it = whole.find(id);
                ASSERT_NE(it, whole.end()) << "rel " << rel << " footprint " << k;
                EXPECT_GE(it->second, c - 1e-6f) << "rel " << rel << " footprint " << k;
            }
            double s = 0.0;
            for (const auto& [id, c] : whole) s += c;
            sum += s;
            sum2 += s * s;
        }
        const double mean = sum / kFootprints;
        const double se = std::sqrt((sum2 / kFootprints - mean * mean) / kFootprints);
        EXPECT_NEAR(mean, lambda, 4.0 * se) << "facets " << rel << " x the footprint";
    }
}

TEST(FlakeFacets, TinyFacetsAreThePointFlakes) {
    // As the facets shrink against the footprint the lobe becomes the point flakes' lobe: with
    // facets a millionth of the footprint's width every flake counts wholly or not at all (but
    // those within that distance of P's edge), so the flake lobe is the point model's: the same
    // pdf, and f the same to rounding, the footprint's flake share too (w / P(any flake reflects
    // wo above the horizon)). It was the facets' count against lambda, which averaged 0.62 of the
    // far look at lambda 0.5 where rough flakes face a low sun: the facets that reflect under the
    // horizon hid the base and reflected nothing.
    auto points = flake_material(true, {{"gamma", {4.0}}, {"flake_roughness", {0.3}}},
                                 {{"algorithm", "enumerate"}});
    auto facets =
        flake_material(true, {{"gamma", {4.0}}, {"flake_roughness", {0.3}}, {"flake_size", {1e-9}}},
                       {{"algorithm", "enumerate"}});
    std::vector<Vec3> wis;
    for (uint32_t i = 0; i < 300; ++i)
        wis.push_back(dir(sample_1d(9, i, 0, 0), 2.0f * kPi * sample_1d(9, i, 0, 1)));
    int lit = 0;
    for (uint64_t k = 0; k < 30; ++k) {
        const Vec3 wo = dir(0.3f + 0.02f * static_cast<float>(k), 0.2f * static_cast<float>(k));
        const BsdfHarness::Point pt = random_footprint(40.0, 21, k);
        points->prepare(wo, pt);
        facets->prepare(wo, pt);
        std::vector<Vec3> fp, ff;
        std::vector<float> pp, pf;
        points->eval(wis, fp, pp);
        facets->eval(wis, ff, pf);
        float share = -1.0f;
        for (std::size_t i = 0; i < wis.size(); ++i) {
            EXPECT_EQ(pp[i], pf[i]) << "footprint " << k << " direction " << i;
            if (fp[i].y <= 0.0f) {
                EXPECT_EQ(ff[i].y, 0.0f);
                continue;
            }
            ++lit;
            if (share < 0.0f) share = ff[i].y / fp[i].y;
            EXPECT_NEAR(ff[i].y / fp[i].y, share, 1e-5f) << "footprint " << k;
        }
        if (share >= 0.0f) {
            EXPECT_NEAR(share, 1.0f, 1e-5f) << "footprint " << k;
        }
    }
    EXPECT_GT(lit, 50);  // the directions do meet glints
}

/** The first flake (by id order) whose facet covers the footprint of side `side` at its centre
 *  wholly, searching around (u, v); returns its centre. */
bool facet_centre(const fl::FacetShape& shape, double facet, double u, double v, double& cu,
                  double& cv) {
    const auto around = facets_in(shape, facet, 400.0, u, v, 1.0);
    fl::FieldParams fp;
    fp.flakes_per_tile = kTestDensity;
    fp.alpha = 0.3f;
    const double side = std::sqrt(400.0 / kTestDensity);
    fl::Footprint p = fl::make_footprint(u, v, side, 0.3 * side, -0.2 * side, side, 1.0);
    bool truncated = false, found = false;
    fl::for_each_flake(fp, p, 1u << 20, truncated, [&](const fl::Flake& f) {
        if (!found && around.count(f.id)) {
            cu = f.u;
            cv = f.v;
            found = true;
        }
    });
    return found;
}

TEST(FlakeFacets, AFootprintInsideAFacetSeesThatMirrorAndOneBetweenThemTheBase) {
    // Facets covering a fifth of the surface (flake_weight 0.2), footprints a hundredth of a
    // facet wide: a macro view.
    const double density = kTestDensity;
    const double facet = std::sqrt(0.2 / (density * std::sqrt(3.0) / 2.0));
    const fl::FacetShape shape(fl::FacetKind::Hexagon);
    auto m = flake_material(true,
                            {{"gamma", {4.0}},
                             {"flake_roughness", {0.3}},
                             {"flake_size", {facet}},
                             {"flake_weight", {0.2}},
                             {"base_color", {0.5, 0.5, 0.5}},
                             {"shadowing", {0.0}}},
                            {{"preset", "perfect"}, {"algorithm", "enumerate"}});
    const Vec3 wo = dir(0.8f, 0.4f);
    int on = 0, alone = 0, between = 0;
    for (uint64_t k = 0; k < 40; ++k) {
        double cu = 0.0, cv = 0.0;
        const double u0 = to_unit_double(hash2(8, 2 * k)) * 40.0;
        const double v0 = to_unit_double(hash2(8, 2 * k + 1)) * 40.0;
        ASSERT_TRUE(facet_centre(shape, facet, u0, v0, cu, cv));
        // Two tiny footprints near the centre of the facet: the same flat mirror, all of the
        // light in one cone (albedo 1 but for the cone's share under the horizon; at cos 0.8 and
        // a roughness of 0.3 a cone may dip under it, hence >= 0.9 rather than 1). A facet that
        // reflects wo into the surface shows the far look instead (its smooth lobe), as one.
        BsdfHarness::Point pt;
        pt.u = static_cast<float>(cu);
        pt.v = static_cast<float>(cv);
        pt.dudx = pt.dvdy = static_cast<float>(facet * 0.01);

        m->prepare(wo, pt);
        const auto a = m->albedo(4000, k);
        const double albedo = a.mean;
        std::vector<Vec3> wis, f0, f;
        std::vector<float> pdf;
        for (const auto& s : m->sample(64, 3 * k))
            if (s.flags != 0) wis.push_back(s.wi);
        if (wis.empty()) continue;  // the facet faces away from wo
        m->eval(wis, f0, pdf);
        pt.u += static_cast<float>(facet * 0.05);
        m->prepare(wo, pt);
        m->eval(wis, f, pdf);
        // Where the neighbouring footprint lies on this facet alone (facets may overlap: a fifth
        // of the surface is covered), it reflects each sampled direction as brightly: one mirror.
        const double lambda_pt = kTestDensity * facet * facet * 1e-4;
        if (facets_in(shape, facet, lambda_pt, cu, cv, 1.0).size() == 1 &&
            facets_in(shape, facet, lambda_pt, pt.u, pt.v, 1.0).size() == 1) {
            ++alone;
            for (std::size_t i = 0; i < wis.size(); ++i)
                EXPECT_NEAR(f[i].y, f0[i].y, 1e-3f * f0[i].y + 1e-6f);
        }
        // (Exact for a cone; the far look's estimate has a spread of its own.)
        EXPECT_LE(albedo, 1.0 + 4.0 * a.se + 1e-3);
        // The facet may overlap another; alone it reflects all it receives but its cone's share
        // under the horizon.
        if (albedo > 0.0) {
            EXPECT_GT(albedo, 0.5);
            ++on;
        }
    }
    EXPECT_GT(on, 20);
    EXPECT_GT(alone, 15);
    // Between facets: the base alone, f = base / pi, in every direction.
    for (uint64_t k = 0; k < 200 && between < 10; ++k) {
        BsdfHarness::Point pt;
        pt.u = static_cast<float>(to_unit_double(hash2(9, 2 * k)) * 40.0);
        pt.v = static_cast<float>(to_unit_double(hash2(9, 2 * k + 1)) * 40.0);
        pt.dudx = pt.dvdy = static_cast<float>(facet * 0.01);
        bool any = false;
        for_each_facet(shape, facet, pt, [&](const fl::Flake&) { any = true; });
        if (any) continue;
        ++between;
        m->prepare(wo, pt);
        std::vector<Vec3> f;
        std::vector<float> pdf;
        m->eval({dir(0.9f, 1.0f), mirror(wo), dir(0.2f, 2.0f)}, f, pdf);
        for (const Vec3& x : f) EXPECT_NEAR(x.y, 0.5f / kPi, 1e-5f);
    }
    EXPECT_EQ(between, 10);
}

TEST(FlakeFacets, AFootprintAcrossFacetsReflectsItsShareThroughThoseThatReflect) {
    // Facets wider than the footprint (its area 0.65 of a facet's), covering about 0.3 of the
    // surface as flake_weight says, perfect white mirrors seen at cos 0.7 in a cone of 1 degree.
    // A footprint's share is flake_weight times its facets' shares against lambda (at most 1),
    // reflected through the facets that reflect the view above the horizon (as the far look
    // spreads the share of the flakes that do not over those that do); a footprint whose facets
    // all reflect the view into the surface is those dark mirrors. (Scaling the lobe by the
    // facets that reflect alone made a receding plane of facets about a pixel wide 0.61 of its
    // far look at grazing views; showing the far look on the others made grey hexagons.)
    const double density = kTestDensity, weight = 0.3;
    const double facet = std::sqrt(weight / (density * std::sqrt(3.0) / 2.0));
    const double side = 0.75 * facet;
    const fl::FacetShape shape(fl::FacetKind::Hexagon);
    const FlakeParams params = {{"gamma", {1.0}},
                                {"flake_roughness", {0.3}},
                                {"flake_size", {facet}},
                                {"flake_weight", {weight}},
                                {"shadowing", {0.0}}};
    auto m = flake_material(true, params, {{"preset", "perfect"}, {"algorithm", "enumerate"}});
    const Vec3 wo = dir(0.7f, 0.4f);
    const double lambda = density * side * side;
    int mixed = 0, away = 0, lit = 0;
    for (uint64_t k = 0; k < 1000 && (mixed < 12 || away < 8); ++k) {
        BsdfHarness::Point pt;
        pt.u = static_cast<float>(to_unit_double(hash2(12, 2 * k)) * 40.0);
        pt.v = static_cast<float>(to_unit_double(hash2(12, 2 * k + 1)) * 40.0);
        pt.dudx = pt.dvdy = static_cast<float>(side);
        // The footprint's facets, their shares and whether each reflects wo above the horizon.
        double all = 0.0, in = 0.0;
        bool near_horizon = false;
        const bool truncated = for_each_facet(shape, facet, pt, [&](const fl::Flake& f) {
            const float c = f.m.x * wo.x + f.m.y * wo.y + f.m.z * wo.z;
            all += f.cover;
            const float rz = 2.0f * c * f.m.z - wo.z;
            if (c > 0.0f && rz > 0.0f) in += f.cover;
            near_horizon |= c > 0.0f && std::fabs(rz) < 0.05f;
        });
        ASSERT_FALSE(truncated);
        // (A cone that reaches under the horizon reflects less: such footprints are left out.)
        if (!(all > 0.0) || near_horizon) continue;
        ++lit;
        if (in > 0.0 && all > in + 0.05) ++mixed;
        if (!(in > 0.0)) ++away;
        m->prepare(wo, pt);
        const auto a = m->albedo(4000, k);
        const double expected = in > 0.0 ? std::min(1.0, weight * all / lambda) : 0.0;
        EXPECT_NEAR(a.mean, expected, 4.0 * a.se + 0.01)
            << "footprint " << k << ": shares " << in << " of " << all << " reflect";
    }
    EXPECT_GE(mixed, 12);  // across a facet that reflects and one that does not
    EXPECT_GE(away, 8);    // on facets that face away alone
    EXPECT_GT(lit, mixed + away);
}

TEST(FlakeFacets, FootprintsAverageToTheirRuleAtEveryFacetSize) {
    // Over many footprints, facets covering a tenth of the surface (density = flake_weight /
    // facet area), rough flakes (0.6) at cos 0.2, where only about 0.55 of the flakes reflect
    // the view above the horizon: what hides the base averages flake_weight at every facet size
    // (base alone: white, flakes black). The flakes (perfect white flakes, black base) reflect
    // the far look where facets are much smaller than the footprint (r, a facet's area over
    // the footprint's: 1/256); where they are larger, footprints inside a facet that faces away
    // are dark mirrors, so the flakes reflect between cache_share and all of the far look (r 4,
    // and r 1/8, the middle of the blend between the rules). Where facets are larger than the
    // footprint, their overlaps (random places) cover (1 - e^-w) / w of w: 0.95 at w 0.1.
    // Bound: 4 standard errors plus 2%.
    constexpr double kWeight = 0.1;
    const float alpha = 0.6f;
    const Vec3 wo = dir(0.2f, 0.3f);
    const double facet = std::sqrt(kWeight / (kTestDensity * std::sqrt(3.0) / 2.0));
    const double share = fl::cache_share_exact(alpha, wo.z);
    ASSERT_LT(share, 0.6);  // many flakes face away
    const FlakeParams common = {{"flake_weight", {kWeight}},
                                {"flake_roughness", {alpha}},
                                {"gamma", {3.0}},
                                {"shadowing", {0.0}},
                                {"flake_size", {facet}}};
    FlakeParams hide_params = common;
    hide_params.push_back({"flake_color", {0.0, 0.0, 0.0}});
    hide_params.push_back({"base_color", {1.0, 1.0, 1.0}});
    auto hides = flake_material(true, hide_params, {{"algorithm", "enumerate"}});
    auto lobes = flake_material(true, common, {{"preset", "perfect"}, {"algorithm", "enumerate"}});
    auto smooth = flake_material(false, common, {{"preset", "perfect"}});
    BsdfHarness::Point far;
    far.has_differentials = false;
    smooth->prepare(wo, far);
    const double limit = smooth->albedo(200000, 5).mean;
    struct Case {
        double r, beta;
    };
    for (const Case& c : {Case{1.0 / 256.0, 0.0}, Case{1.0 / 8.0, 0.5}, Case{4.0, 1.0}}) {
        const double lambda = kWeight / c.r;
        const int footprints = c.r > 1.0 ? 64000 : 3000;
        double sum[2] = {0, 0}, sum2[2] = {0, 0};
        for (int k = 0; k < footprints; ++k) {
            const BsdfHarness::Point pt = random_footprint(lambda, 430, static_cast<uint64_t>(k));
            hides->prepare(wo, pt);
            lobes->prepare(wo, pt);
            const double a[2] = {1.0 - hides->albedo(16, static_cast<uint64_t>(k)).mean,
                                 lobes->albedo(16, static_cast<uint64_t>(k)).mean};
            for (int i = 0; i < 2; ++i) {
                sum[i] += a[i];
                sum2[i] += a[i] * a[i];
            }
        }
        double mean[2], se[2];
        for (int i = 0; i < 2; ++i) {
            mean[i] = sum[i] / footprints;
            se[i] = std::sqrt(std::max(0.0, sum2[i] / footprints - mean[i] * mean[i]) / footprints);
        }
        const double overlap = c.r >= 1.0 ? -std::expm1(-kWeight) / kWeight : 1.0;
        const double hidden = kWeight * ((1.0 - c.beta) + c.beta * overlap);
        EXPECT_NEAR(mean[0], hidden, 4.0 * se[0] + 0.02 * hidden)
            << "base hidden, r " << c.r << ": " << mean[0] / kWeight << " of flake_weight";
        const std::string what =
            fmt::format("flakes, r {}: {} of the far look", c.r, mean[1] / limit);
        if (c.beta == 0.0) {
            EXPECT_NEAR(mean[1], limit, 4.0 * se[1] + 0.02 * limit) << what;
        } else {
            const double low = limit * ((1.0 - c.beta) + c.beta * share * overlap);
            const double high = limit * ((1.0 - c.beta) + c.beta * overlap);
            EXPECT_GE(mean[1], low - 4.0 * se[1] - 0.02 * low) << what;
            EXPECT_LE(mean[1], high + 4.0 * se[1] + 0.02 * high) << what;
        }
    }
}

TEST(FlakeFacets, NoFootprintGainsEnergy) {
    // Perfect white mirror facets, shadowing off, from footprints a tenth of a facet to many
    // facets wide, down to grazing views: each footprint's lobe is normalised by its facets'
    // shares and the far look (which facets facing away show) reflects at most what it
    // receives, so the footprint does too. The cache is sampled in proportion to its lobe (an
    // estimate with float rounding's variance only); the far look's estimate has a spread of
    // its own (4 standard errors of 4000 samples).
    const double facet = std::sqrt(0.5 / (kTestDensity * std::sqrt(3.0) / 2.0));
    for (double lambda : {0.05, 2.0, 60.0})
        for (float cos_o : {1.0f, 0.3f, 1e-3f}) {
            auto m = flake_material(true,
                                    {{"shadowing", {0.0}},
                                     {"gamma", {3.0}},
                                     {"flake_size", {facet}},
                                     {"flake_weight", {0.5}}},
                                    {{"preset", "perfect"}, {"algorithm", "enumerate"}});
            for (uint64_t k = 0; k < 40; ++k) {
                m->prepare(dir(cos_o, 0.7f), random_footprint(lambda, 33, k));
                const auto a = m->albedo(4000, k);
                EXPECT_LE(a.mean, 1.0 + 4.0 * a.se + 1e-4)
                    << "lambda " << lambda << " cos_o " << cos_o << " se " << a.se;
            }
        }
}

TEST(FlakeFacets, FacetsWiderThanHalfATileAreEnumeratedByTheTreeToo) {
    // Facets 0.5 to 1 uv wide (a few flakes per uv tile, as `density = flake_weight / facet
    // area` gives for large glitter): a tiny footprint near a tile's edge reaches into more than
    // the tree's 2 x 2 tiles. The tree enumerates those few flakes as `enumerate` does (it gave
    // up there and showed the smooth lobe, in bands along every tile edge): the same lobe, bit
    // for bit, from every footprint.
    for (double width : {0.5, 0.9, 1.0}) {
        const double density = 0.9 / (width * width * std::sqrt(3.0) / 2.0);
        const FlakeParams params = {{"gamma", {4.0}},        {"flake_roughness", {0.3}},
                                    {"flake_size", {width}}, {"flake_weight", {0.9}},
                                    {"density", {density}},  {"base_color", {0.1, 0.1, 0.1}},
                                    {"min_flakes", {5e8}},   {"max_flakes", {1e9}}};
        auto tree = flake_material(false, params, {{"algorithm", "tree"}});
        auto all = flake_material(false, params, {{"algorithm", "enumerate"}});
        int lit = 0;
        for (uint64_t k = 0; k < 60; ++k) {
            BsdfHarness::Point pt;
            // Near a tile's corner for half of them, anywhere for the rest.
            const double jitter = k % 2 == 0 ? 0.05 : 1.0;
            pt.u = static_cast<float>(3.0 + jitter * (to_unit_double(hash2(21, 2 * k)) - 0.5));
            pt.v = static_cast<float>(7.0 + jitter * (to_unit_double(hash2(21, 2 * k + 1)) - 0.5));
            pt.dudx = pt.dvdy = 1e-3f;
            const Vec3 wo = dir(0.3f + 0.6f * static_cast<float>(to_unit_double(hash2(22, k))),
                                static_cast<float>(k));
            all->prepare(wo, pt);
            tree->prepare(wo, pt);
            std::vector<Vec3> wis;
            for (const auto& s : all->sample(32, k))
                if (s.flags != 0) wis.push_back(s.wi);
            wis.push_back(mirror(wo));
            std::vector<Vec3> f_all, f_tree;
            std::vector<float> pdf_all, pdf_tree;
            all->eval(wis, f_all, pdf_all);
            tree->eval(wis, f_tree, pdf_tree);
            bool any = false;
            for (std::size_t i = 0; i < wis.size(); ++i) {
                EXPECT_EQ(f_tree[i].y, f_all[i].y) << "width " << width << " footprint " << k;
                EXPECT_EQ(pdf_tree[i], pdf_all[i]) << "width " << width << " footprint " << k;
                any = any || f_all[i].y > 0.2f;  // brighter than the base: a facet's cone
            }
            lit += any ? 1 : 0;
        }
        // Not a vacuous comparison: some footprints see a facet's cone.
        EXPECT_GT(lit, 5) << "width " << width;
    }
}

TEST(FlakeFacets, OverlappingFacetsWiderThanTheFootprintShowNoSquares) {
    // Glitter made larger without lowering its density: facets a hundred footprints wide,
    // hundreds to thousands of them over every point (`density` x facet area). The tree's cells
    // follow the facets' reach, so each held hundreds of flakes and was counted, the footprint
    // holding a few of its flakes (a count drawn per cell) or none: the cover went up and down a
    // cell at a time, and a sphere showed squares of base and of mirror. With few facets to find
    // (under 2 x the tree's limit) the tree now enumerates them as `enumerate` does, bit for bit
    // (the old tree showed the bare base, 0.159, where the enumeration's facets covered it:
    // 0.002); with many, each counted cell adds its expected share to the cover, and the base
    // shows (1 - flake_weight) of itself everywhere, as thousands of overlapping facets do.
    struct Case {
        double density;  ///< flakes per uv square (facets 0.05 wide, footprints 5e-4)
        double weight;   ///< flake_weight
        bool same;       ///< few facets: the tree is the enumeration, bit for bit
    };
    for (const Case& c : {Case{1.4e5, 1.0, true}, Case{1e5, 1.0, true}, Case{2e6, 0.5, false}}) {
        const FlakeParams params = {
            {"gamma", {2.0}},         {"flake_roughness", {0.05}},  {"flake_size", {0.05}},
            {"density", {c.density}}, {"flake_weight", {c.weight}}, {"base_color", {0.5, 0.5, 0.5}},
            {"min_flakes", {5e8}},    {"max_flakes", {1e9}}};
        auto tree = flake_material(false, params, {{"algorithm", "tree"}});
        auto all = flake_material(false, params, {{"algorithm", "enumerate"}});
        const Vec3 wo = dir(0.8f, 0.4f);
        // A direction far from every flake's cone (flake normals within a few times 0.05 of
        // the normal): the base's light, base (1 - share) / pi.
        const std::vector<Vec3> away = {dir(0.15f, 3.5f)};
        double sum = 0.0, sum2 = 0.0;
        int n = 0, covered = 0;
        for (uint64_t k = 0; k < 120; ++k) {
            BsdfHarness::Point pt;
            // Along a row across many cells.
            pt.u = static_cast<float>(2.0 + 0.004 * static_cast<double>(k));
            pt.v = static_cast<float>(5.3 + 0.1 * to_unit_double(hash2(31, k)));
            pt.dudx = pt.dvdy = 5e-4f;
            std::vector<Vec3> ft, fa;
            std::vector<float> pdf_t, pdf_a;
            tree->prepare(wo, pt);
            tree->eval(away, ft, pdf_t);
            if (c.same) {
                all->prepare(wo, pt);
                all->eval(away, fa, pdf_a);
                EXPECT_EQ(ft[0].y, fa[0].y) << "density " << c.density << " footprint " << k;
                EXPECT_EQ(pdf_t[0], pdf_a[0]) << "density " << c.density << " footprint " << k;
                covered += fa[0].y < 0.1f ? 1 : 0;
            }
            sum += ft[0].y;
            sum2 += static_cast<double>(ft[0].y) * ft[0].y;
            ++n;
        }
        if (c.same) {
            EXPECT_GT(covered, 100) << "density " << c.density << ": facets over the base";
            continue;
        }
        // Thousands of facets over every point (4330 on average): the share is flake_weight
        // within their count's spread (1.5%), the base's light 0.5 (1 - 0.5) / pi.
        const double mean = sum / n, sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
        const double expected = 0.5 * (1.0 - c.weight) / kPi;
        EXPECT_NEAR(mean, expected, 0.05 * expected) << "the base's mean light";
        EXPECT_LT(sd, 0.05 * expected) << "the base's spread over footprints";
    }
}

}  // namespace
}  // namespace spangle::test::flake_facets
