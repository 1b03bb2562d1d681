// The flake looks artists ask for, through the plugin ABI and the model's own functions:
// per-flake hue, saturation and value variation, interference (thin-film) flakes. Each: the
// footprint-averaged discrete lobe equals the smooth lobe (its expectation) per channel, energy
// is conserved, a flake keeps its colour from every footprint and view, and the look is there
// (colours do vary, the film's colour does shift with the view).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <map>
#include <utility>

#include "../common/microfacet.h"
#include "core/hash.h"
#include "field.h"
#include "flake_support.h"
#include "thin_film.h"

namespace spangle::test::flake_looks {
namespace {

namespace fl = spangle::flake;

const FlakeParams kHsv = {{"color_table", {1.0}},
                          {"hue_variation", {40.0}},
                          {"saturation_variation", {0.5}},
                          {"value_variation", {0.8}}};
const FlakeParams kFilm = {
    {"film_thickness_min", {200.0}}, {"film_thickness_max", {900.0}}, {"film_ior", {2.0}}};

/** `a` followed by `b`. */
FlakeParams join(FlakeParams a, const FlakeParams& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}
/** The string parameters `a` followed by `b`. */
FlakeStrings join_strings(FlakeStrings a, const FlakeStrings& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

/** The footprint-averaged discrete lobe at wi equals the smooth lobe per channel: within 4
 *  standard errors plus the smooth table's documented accuracy (1%). */
void expect_mean_is_smooth(const FlakeParams& params, Vec3 wo, Vec3 wi, double lambda,
                           int footprints, uint64_t seed) {
    for (const char* algorithm : {"tree", "enumerate"}) {
        auto disc = flake_material(true, params, {{"algorithm", algorithm}});
        auto smooth = flake_material(false, params);
        const Vec3 s = smooth_f(*smooth, wo, {wi})[0];
        double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
        std::vector<Vec3> f;
        std::vector<float> pdf;
        for (int k = 0; k < footprints; ++k) {
            disc->prepare(wo, random_footprint(lambda, seed, static_cast<uint64_t>(k)));
            disc->eval({wi}, f, pdf);
            for (int ch = 0; ch < 3; ++ch) {
                sum[ch] += f[0][ch];
                sum2[ch] += static_cast<double>(f[0][ch]) * f[0][ch];
            }
        }
        for (int ch = 0; ch < 3; ++ch) {
            const double mean = sum[ch] / footprints;
            const double se =
                std::sqrt(std::max(0.0, sum2[ch] / footprints - mean * mean) / footprints);
            EXPECT_GT(s[ch], 0.0f) << algorithm << " channel " << ch;
            EXPECT_NEAR(mean, s[ch], 4.0 * se + 0.01 * s[ch])
                << algorithm << " channel " << ch << ": ratio " << mean / s[ch];
        }
    }
}

TEST(FlakeExpectation, FacetsAverageToTheSmoothLobe) {
    // Facets a thirtieth of the footprint's width (1,200 facet areas per footprint; about a tenth
    // of its facets straddle its edge and count in part), covering half the surface as
    // flake_weight 0.5 says: the footprints average to the smooth lobe at that weight.
    const double facet = std::sqrt(0.5 / (kTestDensity * std::sqrt(3.0) / 2.0));
    const Vec3 wo = dir(0.7f, 0.0f);
    expect_mean_is_smooth({{"flake_size", {facet}}, {"flake_weight", {0.5}}}, wo, mirror(wo), 600.0,
                          1500, 410);
    expect_mean_is_smooth({{"flake_size", {facet}}, {"flake_weight", {0.5}}}, wo, dir(0.75f, 2.9f),
                          600.0, 1500, 411);
}

TEST(FlakeExpectation, ColourVariationAveragesToItsMean) {
    // Varied colours, from the table and from one flake colour: the smooth lobe takes the
    // variants' exact mean, so the footprints average to it.
    const Vec3 wo = dir(0.7f, 0.0f);
    expect_mean_is_smooth(join(kHsv, {{"hue_spread", {40.0}}, {"base_color", {0.6, 0.1, 0.1}}}), wo,
                          mirror(wo), 600.0, 1500, 400);
    expect_mean_is_smooth({{"flake_color", {0.9, 0.5, 0.2}},
                           {"hue_variation", {90.0}},
                           {"saturation_variation", {0.4}},
                           {"value_variation", {0.6}}},
                          wo, mirror(wo), 600.0, 1500, 410);
}

TEST(FlakeExpectation, InterferenceFlakesAverageToTheSmoothLobe) {
    // A range of film thicknesses over aluminium, at the highlight, near normal and at a
    // grazing view: the smooth lobe's Fresnel is the mean of the thickness levels' tables.
    for (float cos_o : {0.9f, 0.3f}) {
        const Vec3 wo = dir(cos_o, 0.0f);
        expect_mean_is_smooth(kFilm, wo, mirror(wo), 600.0, 1500, 420);
    }
}

TEST(FlakeLooks, ThinFilmReducesToTheBareFresnel) {
    // No film (d = 0) or a film of the surrounding index (n = 1): the metal's own Fresnel.
    for (const auto& metal : mf::kMetalPresets)
        for (int c = 0; c < 3; ++c)
            for (double cos_i : {1.0, 0.7, 0.3, 0.05}) {
                const std::complex<double> n(metal.eta[c], metal.k[c]);
                const double bare =
                    mf::fresnel_conductor(static_cast<float>(cos_i), metal.eta[c], metal.k[c]);
                // fresnel_conductor returns a float: equal to its rounding.
                EXPECT_NEAR(fl::airy_reflectance(cos_i, 550.0, 0.0, 1.8, n), bare, 1e-6)
                    << metal.name << " cos " << cos_i;
                EXPECT_NEAR(fl::airy_reflectance(cos_i, 550.0, 480.0, 1.0, n), bare, 1e-6)
                    << metal.name << " cos " << cos_i;
            }
    // Over a dielectric, d = 0: the dielectric's Fresnel.
    EXPECT_NEAR(fl::airy_reflectance(0.6, 500.0, 0.0, 2.2, {1.5, 0.0}),
                mf::fresnel_dielectric(0.6f, 1.5f), 1e-6);
}

TEST(FlakeEnergy, ThinFilmReflectanceNeverExceedsOne) {
    // A lossless film over any substrate reflects at most what it receives, at every angle,
    // wavelength and thickness (the Airy sum's modulus is at most 1 for |r12|, |r23| <= 1).
    const std::complex<double> subs[] = {{0.183, 3.424}, {1.657, 9.224}, {0.155, 4.828},
                                         {1.5, 0.0},     {1.1, 0.0},     {0.0, 1e4}};
    double lowest = 1.0, highest = 0.0;
    for (const auto& n_sub : subs)
        for (double n_film : {1.0, 1.3, 1.5, 2.4, 4.0})
            for (int a = 0; a <= 20; ++a)
                for (int d = 0; d <= 40; ++d)
                    for (double lambda : {400.0, 465.0, 532.0, 630.0, 700.0}) {
                        const double cos_i = a == 0 ? 1e-4 : a / 20.0;
                        const double r =
                            fl::airy_reflectance(cos_i, lambda, 25.0 * d, n_film, n_sub);
                        ASSERT_LE(r, 1.0 + 1e-12) << n_sub << " " << n_film << " " << cos_i;
                        ASSERT_GE(r, 0.0);
                        lowest = std::min(lowest, r);
                        highest = std::max(highest, r);
                    }
    // Interference does happen: some configurations nearly cancel, others reflect fully.
    EXPECT_LT(lowest, 0.02);
    EXPECT_GT(highest, 0.99);
    // Through the ABI: white interference flakes, shadowing off, every footprint of enumerated
    // flakes reflects at most 1 (sampled in proportion to the lobe: up to float rounding).
    auto m = flake_material(true, join(kFilm, {{"shadowing", {0.0}}, {"film_ior", {2.4}}}),
                            {{"algorithm", "enumerate"}});
    for (float cos_o : {1.0f, 0.5f, 0.1f, 1e-3f})
        for (uint64_t k = 0; k < 6; ++k) {
            m->prepare(dir(cos_o, 0.7f), random_footprint(300.0, 430, k));
            EXPECT_LE(albedo(*m, 4000, k), 1.0 + 1e-4) << "cos_o " << cos_o;
        }
}

TEST(FlakeEnergy, AColourTableInAWiderSpaceNeverGainsEnergy) {
    // Found by a user: a table of saturated ACEScg hues in a Rec.709 working space gave white
    // flakes reflecting 1.4-1.7 times the light in red (the colours were clipped below 0, not
    // above 1). Every channel of every footprint reflects at most 1.
    auto m = flake_material(true,
                            {{"color_table", {1.0}},
                             {"table_size", {1.0}},
                             {"shadowing", {0.0}},
                             {"table_l", {0.5}},
                             {"table_s", {1.0}}},
                            {{"algorithm", "enumerate"}, {"table_space", "ACEScg"}});
    double red = 0.0;
    for (uint64_t k = 0; k < 4; ++k) {
        m->prepare(dir(1.0f, 0.0f), random_footprint(300.0, 431, k));
        for (int ch = 0; ch < 3; ++ch) {
            const double a = albedo(*m, 4000, k, ch);
            EXPECT_LE(a, 1.0 + 1e-4) << "channel " << ch << ", footprint " << k;
            if (ch == 0) red = std::max(red, a);
        }
    }
    EXPECT_GT(red, 0.5) << "the flakes are red and bright (the test can fail)";
}

TEST(FlakeLooks, InterferenceColourShiftsWithTheViewAngle) {
    // A pearl pigment (250 nm of TiO2, index 2.4, over mica flakes of index 1.6): the highlight's
    // chromaticity moves as the view tilts from near normal to 70 degrees (measured 0.20 in
    // (r, b) chromaticity); bare aluminium flakes barely change (measured 0.0025).
    const auto chroma_shift = [](const FlakeParams& params, const FlakeStrings& strings) {
        auto smooth = flake_material(false, params, strings);
        double ch[2][2];
        const float cos_o[2] = {0.95f, 0.35f};
        for (int i = 0; i < 2; ++i) {
            const Vec3 wo = dir(cos_o[i], 0.0f);
            const Vec3 f = smooth_f(*smooth, wo, {mirror(wo)})[0];
            const double sum = static_cast<double>(f.x) + f.y + f.z;
            ch[i][0] = f.x / sum;
            ch[i][1] = f.z / sum;
        }
        return std::hypot(ch[0][0] - ch[1][0], ch[0][1] - ch[1][1]);
    };
    const double film = chroma_shift({{"film_thickness_min", {250.0}},
                                      {"film_thickness_max", {250.0}},
                                      {"film_ior", {2.4}},
                                      {"flake_ior", {1.6}}},
                                     {{"fresnel", "dielectric"}});
    const double bare = chroma_shift({}, {});
    EXPECT_GT(film, 0.1) << "the film's colour shifts with the view";
    EXPECT_LT(bare, 0.01) << "aluminium alone is nearly grey at every angle";
}

/** A flake of the test field (seed 0, density kTestDensity) by position, and its mirror
 *  direction from wo. */
struct SeenFlake {
    double u, v;
    Vec3 r;
};
std::vector<SeenFlake> flakes_seen(const BsdfHarness::Point& pt, Vec3 wo) {
    fl::FieldParams fp;
    fp.flakes_per_tile = kTestDensity;
    fp.alpha = 0.15f;
    const fl::Footprint p = fl::make_footprint(pt.u, pt.v, pt.dudx, pt.dvdx, pt.dudy, pt.dvdy, 1.0);
    std::vector<SeenFlake> out;
    bool truncated = false;
    fl::for_each_flake(fp, p, 1u << 20, truncated, [&](const fl::Flake& f) {
        const Vec3 m(f.m.x, f.m.y, f.m.z);
        const Vec3 r = m * (2.0f * dot(wo, m)) - wo;
        if (dot(wo, m) > 0.0f && r.z > 0.05f) out.push_back({f.u, f.v, r});
    });
    return out;
}

/** The chromaticity (r, b over the sum) each flake reflects at the centre of its cone, by the
 *  flake's position, for the flakes whose cone no other flake's cone reaches. */
std::map<std::pair<double, double>, std::pair<double, double>> flake_chroma(
    BsdfHarness& m, const BsdfHarness::Point& pt, Vec3 wo, float gamma) {
    m.prepare(wo, pt);
    const std::vector<SeenFlake> seen = flakes_seen(pt, wo);
    const float apart = 4.0f * std::sin(gamma);  // chord of 2 gamma, with room
    std::map<std::pair<double, double>, std::pair<double, double>> out;
    for (const SeenFlake& a : seen) {
        bool alone = true;
        for (const SeenFlake& b : seen) alone = alone && (&a == &b || length(a.r - b.r) > apart);
        if (!alone) continue;
        std::vector<Vec3> f;
        std::vector<float> pdf;
        m.eval({a.r}, f, pdf);
        const double sum = static_cast<double>(f[0].x) + f[0].y + f[0].z;
        if (sum > 0.0) out[{a.u, a.v}] = {f[0].x / sum, f[0].z / sum};
    }
    return out;
}

/** Each flake seen from footprint a with view wo_a and from the overlapping footprint b with view
 *  wo_b reflects the same chromaticity (its own colour, evaluated alike: equal to float
 *  rounding), and the flakes' chromaticities differ from one another by more than `spread`. */
void expect_flakes_keep_their_colour(const FlakeParams& params, const FlakeStrings& strings,
                                     Vec3 wo_a, Vec3 wo_b, double spread_min) {
    constexpr float kGamma = 0.2f;
    auto m = flake_material(true, join(params, {{"gamma", {kGamma}}, {"flake_roughness", {0.15}}}),
                            join_strings(strings, {{"algorithm", "enumerate"}}));
    const float gamma = kGamma * kPi / 180.0f;
    BsdfHarness::Point a = footprint(40.0, 3.3f, 7.7f), b = a;
    b.u += 0.25f * a.dudx;
    b.v += 0.2f * a.dvdy;
    const auto ca = flake_chroma(*m, a, wo_a, gamma);
    const auto cb = flake_chroma(*m, b, wo_b, gamma);
    int shared = 0;
    double spread = 0.0;
    for (const auto& [pos, c] : ca) {
        spread = std::max({spread, std::fabs(c.first - ca.begin()->second.first),
                           std::fabs(c.second - ca.begin()->second.second)});
        const auto it = cb.find(pos);
        if (it == cb.end()) continue;
        ++shared;
        EXPECT_NEAR(c.first, it->second.first, 1e-5);
        EXPECT_NEAR(c.second, it->second.second, 1e-5);
    }
    EXPECT_GE(shared, 8) << "the footprints share flakes";
    EXPECT_GT(spread, spread_min) << "the flakes' colours vary";
}

TEST(FlakeLooks, AFlakeKeepsItsVariedColourFromEveryFootprintAndView) {
    // Perfect mirror flakes (no Fresnel colour), varied colours: the same from two overlapping
    // footprints and two views (the camera moved between frames).
    expect_flakes_keep_their_colour(kHsv, {{"preset", "perfect"}}, dir(0.8f, 0.2f), dir(0.5f, 1.4f),
                                    0.05);
}

TEST(FlakeLooks, AFlakeKeepsItsFilmFromEveryFootprint) {
    // Interference flakes (100 to 700 nm of TiO2 on mica): a flake's film is its own, so from
    // the same view its colour is the same in both footprints; the films differ between flakes.
    // (Its colour changes with the view by design: the film's interference.)
    expect_flakes_keep_their_colour({{"film_thickness_min", {100.0}},
                                     {"film_thickness_max", {700.0}},
                                     {"film_ior", {2.4}},
                                     {"flake_ior", {1.6}}},
                                    {{"fresnel", "dielectric"}}, dir(0.7f, 0.5f), dir(0.7f, 0.5f),
                                    0.05);
}

// ------------------------------------------------------------------------ two populations

/** A second population of its own density, roughness, cone and colour, weight 0.4. */
const FlakeParams kTwo = {{"flakes2_weight", {0.4}},
                          {"flakes2_density", {kTestDensity}},
                          {"flakes2_color", {1.0, 0.3, 0.1}},
                          {"flakes2_roughness", {0.3}},
                          {"flakes2_gamma", {6.0}}};

TEST(FlakeExpectation, TwoPopulationsAverageToTheirSmoothLobes) {
    // Both populations' footprints average to the weighted sum of their smooth lobes, per
    // channel (the second population's colour makes the channels differ), at the highlight and
    // off it, where the rougher second population dominates.
    const Vec3 wo = dir(0.7f, 0.0f);
    const float tilt = std::atan(0.35f);
    const Vec3 h(0.0f, std::sin(tilt), std::cos(tilt));
    expect_mean_is_smooth(kTwo, wo, mirror(wo), 600.0, 1500, 440);
    expect_mean_is_smooth(kTwo, wo, h * (2.0f * dot(wo, h)) - wo, 600.0, 1500, 450);
}

TEST(FlakeLooks, SecondPopulationIsAFieldOfItsOwn) {
    // Two populations with the same density, roughness and cone: were they one field, the
    // mixture would equal the first population alone at every direction. With a field of its
    // own, the first population's glints are kept at 0.6 of their brightness (weight 0.4 moves
    // to the second population's, elsewhere), and the second population lights directions the
    // first leaves dark.
    const FlakeParams one = {{"gamma", {0.5}}};
    const FlakeParams two = join(one, {{"flakes2_weight", {0.4}},
                                       {"flakes2_density", {kTestDensity}},
                                       {"flakes2_color", {1.0, 1.0, 1.0}},
                                       {"flakes2_roughness", {0.15}},
                                       {"flakes2_gamma", {0.5}}});
    auto m1 = flake_material(true, one, {{"algorithm", "enumerate"}});
    auto m2 = flake_material(true, two, {{"algorithm", "enumerate"}});
    const Vec3 wo = dir(0.8f, 0.3f);
    const BsdfHarness::Point pt = footprint(30.0, 5.5f, 2.5f);
    std::vector<Vec3> at;
    for (const SeenFlake& f : flakes_seen(pt, wo)) at.push_back(f.r);
    for (uint32_t i = 0; i < 4000; ++i)
        at.push_back(dir(sample_1d(5, i, 0, 0), 2.0f * kPi * sample_1d(5, i, 0, 1)));
    std::vector<Vec3> f1, f2;
    std::vector<float> p1, p2;
    m1->prepare(wo, pt);
    m1->eval(at, f1, p1);
    m2->prepare(wo, pt);
    m2->eval(at, f2, p2);
    int kept = 0, first_lit = 0, second_only = 0;
    for (std::size_t i = 0; i < at.size(); ++i) {
        if (f1[i].y > 0.0f) {
            ++first_lit;
            // The first population's lobe times 0.6, unless a second-population glint overlaps.
            kept += std::fabs(f2[i].y - 0.6f * f1[i].y) <= 1e-5f * f1[i].y;
        } else if (f2[i].y > 0.0f) {
            ++second_only;
        }
    }
    ASSERT_GT(first_lit, 10);
    EXPECT_GE(kept, first_lit * 8 / 10) << "the first population's glints, scaled by 0.6";
    EXPECT_GT(second_only, 0) << "glints of the second population's own flakes";
}

TEST(FlakeEnergy, TwoPopulationsNeverGainEnergy) {
    // Perfect white mirror flakes in both populations, shadowing off: the mixture is a convex
    // sum of two lobes that each keep at most their energy (up to float rounding and the
    // estimate's standard error, for both algorithms).
    const FlakeParams params = join({{"shadowing", {0.0}}, {"flakes2_color", {1.0, 1.0, 1.0}}},
                                    {kTwo[0], kTwo[1], kTwo[3]});
    for (const char* algorithm : {"enumerate", "tree"})
        for (double lambda : {20.0, 600.0})
            for (float cos_o : {1.0f, 0.3f, 1e-3f}) {
                auto m =
                    flake_material(true, params, {{"preset", "perfect"}, {"algorithm", algorithm}});
                for (uint64_t k = 0; k < 6; ++k) {
                    m->prepare(dir(cos_o, 0.7f), random_footprint(lambda, 460, k));
                    const auto [mean, se] = m->albedo(4000, k);
                    EXPECT_LE(mean, 1.0 + 4.0 * se + 1e-4)
                        << algorithm << " lambda " << lambda << " cos_o " << cos_o << " +- " << se;
                    // (A footprint of 20 flakes may hold none that reflects wo.)
                    if (lambda >= 600.0) {
                        EXPECT_GT(mean, 0.5) << "mirror flakes keep most of the light";
                    }
                }
            }
}

}  // namespace
}  // namespace spangle::test::flake_looks
