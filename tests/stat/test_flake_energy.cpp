// Energy of the flake material: no footprint, view angle or layering reflects more than it
// receives (white furnace), down to cos(theta_o) = 1e-6.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "coat.h"
#include "core/hash.h"
#include "flake_support.h"

namespace spangle::test::flake_energy {
namespace {

namespace fl = spangle::flake;

constexpr float kGrazing[] = {1.0f, 0.5f, 0.1f, 1e-3f, 1e-6f};

TEST(FlakeEnergy, EveryFootprintOfMirrorFlakesKeepsAtMostItsEnergy) {
    // Perfect white mirror flakes, shadowing off: a footprint reflects the mean over its flakes of
    // the share of each flake's cone above the horizon, never more than 1. The enumerated cache
    // is sampled in proportion to its lobe, so the estimate has no variance (up to float
    // rounding). The counting algorithm's aggregates (stand-in flakes in the cache and the smooth
    // lobe for the rest, normalised by the weights of both) keep at most their energy the same
    // way, footprint by footprint; the smooth part is sampled by its proposal, whose variance the
    // standard error covers. (Quadrature of eval() checks the same without sampling:
    // test_flake_quadrature.cpp.)
    for (const char* algorithm : {"enumerate", "tree"})
        for (double lambda : {5.0, 50.0, 500.0, 5000.0})
            for (float cos_o : kGrazing) {
                auto m = flake_material(true, {{"shadowing", {0.0}}, {"gamma", {3.0}}},
                                        {{"preset", "perfect"}, {"algorithm", algorithm}});
                for (uint64_t k = 0; k < 12; ++k) {
                    m->prepare(dir(cos_o, 0.7f), random_footprint(lambda, 700, k));
                    const BsdfHarness::Albedo a = m->albedo(4000, k);
                    EXPECT_LE(a.mean, 1.0 + 4.0 * a.se + 1e-4)
                        << algorithm << " lambda " << lambda << " cos_o " << cos_o << " footprint "
                        << k << ": +- " << a.se;
                    // (A footprint of 5 flakes may hold none that reflects wo.)
                    if (lambda >= 50.0) {
                        EXPECT_GT(a.mean, 0.5) << algorithm << " lambda " << lambda;
                    }
                }
            }
}

TEST(FlakeEnergy, WholeMaterialNeverGainsEnergy) {
    // White base, perfect white flakes, with no coat, a smooth coat and a rough one, shadowing on
    // and off, discrete footprints of both algorithms and the smooth lobe, down to grazing.
    struct Layer {
        const char* name;
        FlakeParams params;
    };
    const Layer layers[] = {{"no coat", {}},
                            {"smooth coat", {{"coat", {1.0}}}},
                            {"rough coat", {{"coat", {1.0}}, {"coat_roughness", {0.3}}}}};
    for (const Layer& layer : layers)
        for (double shadowing : {0.0, 1.0})
            for (const char* algorithm : {"tree", "enumerate"})
                for (float cos_o : kGrazing) {
                    FlakeParams p = {{"flake_weight", {0.5}},     {"base_color", {1.0}},
                                     {"density", {kTestDensity}}, {"shadowing", {shadowing}},
                                     {"min_flakes", {1000.0}},    {"max_flakes", {4000.0}}};
                    for (const auto& e : layer.params) p.push_back(e);
                    BsdfHarness m("flake", "flake", p,
                                  {{"preset", "perfect"}, {"algorithm", algorithm}});
                    // Discrete (30, 600), blended (2000) and smooth (no differentials).
                    for (double lambda : {30.0, 600.0, 2000.0, 0.0}) {
                        BsdfHarness::Point pt = random_footprint(std::max(lambda, 1.0), 900, 0);
                        pt.has_differentials = lambda > 0.0;
                        m.prepare(dir(cos_o, 0.4f), pt);
                        const BsdfHarness::Albedo a = m.albedo(8000, 3);
                        EXPECT_LE(a.mean, 1.0 + 4.0 * a.se + 1e-4)
                            << layer.name << " shadowing " << shadowing << " " << algorithm
                            << " lambda " << lambda << " cos_o " << cos_o << ": +- " << a.se;
                        EXPECT_GT(a.mean, 0.3) << layer.name << " cos_o " << cos_o
                                               << ": a white furnace keeps most of the light";
                    }
                }
}

TEST(FlakeEnergy, AWhiteBaseUnderACoatReflectsEverything) {
    // The light a coat reflects back down onto a diffuse base comes out again after bounces
    // between them: a white base under a smooth or rough coat reflects all of it, as the smooth
    // plugin's plastic does (it reflected 0.91 head-on: the inter-reflection was lost). A rough
    // coat's tabulated albedo is raised by its quadrature bound (never gaining energy), so it
    // may keep up to that bound (2e-3) back.
    const FlakeParams coats[] = {{{"coat", {1.0}}},
                                 {{"coat", {1.0}}, {"coat_roughness", {0.3}}},
                                 {{"coat", {1.0}}, {"coat_ior", {2.0}}, {"coat_roughness", {0.1}}}};
    for (const FlakeParams& coat : coats)
        for (float cos_o : {1.0f, 0.7f, 0.3f, 0.05f}) {
            FlakeParams p = {{"flake_weight", {0.0}}, {"base_color", {1.0}}};
            for (const auto& e : coat) p.push_back(e);
            BsdfHarness m("flake", "flake", p, {});
            BsdfHarness::Point pt;
            pt.has_differentials = false;
            m.prepare(dir(cos_o, 0.4f), pt);
            const BsdfHarness::Albedo a = m.albedo(20000, 5);
            EXPECT_NEAR(a.mean, 1.0, 4.0 * a.se + 3e-3)
                << coat.size() << " coat parameters, cos_o " << cos_o << ": +- " << a.se;
            EXPECT_LE(a.mean, 1.0 + 4.0 * a.se) << "cos_o " << cos_o;
        }
}

TEST(FlakeEnergy, DielectricFlakesPassWhatTheyDoNotReflectToTheBase) {
    // Glass or mica flakes over a white base: what a flake does not reflect passes through it to
    // the base and back (1 - F each way), so the furnace stays near white; it was absorbed, and
    // flakes of index 1 (invisible) turned a white base black. Never above 1, discrete and
    // smooth footprints, with and without a coat, down to grazing.
    for (const double ior : {1.0, 1.5, 2.4})
        for (const double weight : {0.6, 1.0})
            for (const double coat : {0.0, 1.0})
                for (float cos_o : {1.0f, 0.5f, 0.1f, 1e-3f}) {
                    BsdfHarness m("flake", "flake",
                                  {{"flake_weight", {weight}},
                                   {"base_color", {1.0}},
                                   {"flake_ior", {ior}},
                                   {"coat", {coat}},
                                   {"density", {kTestDensity}},
                                   {"min_flakes", {1000.0}},
                                   {"max_flakes", {4000.0}}},
                                  {{"fresnel", "dielectric"}});
                    for (double lambda : {30.0, 600.0, 0.0}) {
                        BsdfHarness::Point pt = random_footprint(std::max(lambda, 1.0), 950, 1);
                        pt.has_differentials = lambda > 0.0;
                        m.prepare(dir(cos_o, 0.4f), pt);
                        const BsdfHarness::Albedo a = m.albedo(8000, 7);
                        const std::string what =
                            fmt::format("ior {} weight {} coat {} cos_o {} lambda {}: {} +- {}",
                                        ior, weight, coat, cos_o, lambda, a.mean, a.se);
                        EXPECT_LE(a.mean, 1.0 + 4.0 * a.se + 1e-4) << what;
                        // Index 1: the flakes vanish, the white base (under its coat) reflects
                        // all. Denser flakes keep what their Fresnel does not send back down on
                        // the way out (the base's light they reflect down again is lost).
                        if (ior == 1.0 && cos_o >= 0.1f) {
                            EXPECT_NEAR(a.mean, 1.0, 4.0 * a.se + 5e-3) << what;
                        } else if (cos_o >= 0.1f) {
                            // (At cos 0.1 a flake sends about 40% back down on the way out,
                            // which this layering does not bring back: 0.63 with weight 1.)
                            EXPECT_GT(a.mean, cos_o >= 0.5f ? 0.75 : 0.55) << what;
                        }
                    }
                }
}

TEST(FlakeEnergy, AWhiteFurnaceOfSparseFlakesStaysWhite) {
    // White base and perfect white flakes covering 90% of the surface, footprints of 0.3 flakes
    // on average: a footprint without a flake is all base (albedo 1), one with a flake all flake
    // (at most 1). Every footprint stays at most 1 and the mean stays near 1 (it was
    // 0.1 + 0.9 (1 - e^-0.3) = 0.33 when an empty footprint kept the flakes' 90%).
    for (const char* algorithm : {"tree", "enumerate"}) {
        auto m = flake_material(true,
                                {{"flake_weight", {0.9}},
                                 {"base_color", {1.0}},
                                 {"shadowing", {0.0}},
                                 {"gamma", {3.0}}},
                                {{"preset", "perfect"}, {"algorithm", algorithm}});
        constexpr int kFootprints = 600;
        double sum = 0.0;
        for (int k = 0; k < kFootprints; ++k) {
            m->prepare(dir(0.8f, 0.3f), random_footprint(0.3, 401, static_cast<uint64_t>(k)));
            const BsdfHarness::Albedo a = m->albedo(2000, static_cast<uint64_t>(k));
            EXPECT_LE(a.mean, 1.0 + 4.0 * a.se + 1e-4) << algorithm << " footprint " << k;
            sum += a.mean;
        }
        EXPECT_GT(sum / kFootprints, 0.97) << algorithm;
    }
}

TEST(FlakeEnergy, RoughCoatAlbedoTableIsAnUpperBound) {
    // The layering is energy-conserving when the coat's tabulated albedo is at least its true
    // albedo, at every angle (between the table's nodes too). The reference: the same integral
    // (visible normals, F G2 / G1) on a grid 5x finer per side.
    for (float alpha : {0.02f, 0.3f, 1.0f})
        for (float ior : {1.3f, 2.5f}) {
            fl::Coat coat;
            coat.init(true, ior, alpha);
            for (int i = 0; i <= 24; ++i) {
                const float cos_o = std::max(1e-6f, std::pow(static_cast<float>(i) / 24.0f, 3.0f));
                const fl::V3 wo{std::sqrt(1.0f - cos_o * cos_o), 0.0f, cos_o};
                constexpr int kGrid = 512;
                double sum = 0.0;
                const float g1 = mf::ggx_g1(wo, alpha, alpha);
                for (int a = 0; a < kGrid; ++a)
                    for (int b = 0; b < kGrid; ++b) {
                        const fl::V3 h = mf::ggx_sample_visible(
                            wo, alpha, alpha, static_cast<float>((a + 0.5) / kGrid),
                            static_cast<float>((b + 0.5) / kGrid));
                        const fl::V3 wi = mf::reflect(wo, h);
                        if (!(wi.z > 0.0f)) continue;
                        sum += mf::fresnel_dielectric(mf::dot(wo, h), ior) *
                               mf::ggx_g2(wo, wi, alpha, alpha) / g1;
                    }
                const double fine = sum / (static_cast<double>(kGrid) * kGrid);
                EXPECT_GE(coat.albedo_at(cos_o), fine)
                    << "alpha " << alpha << " ior " << ior << " cos_o " << cos_o;
            }
        }
}

}  // namespace
}  // namespace spangle::test::flake_energy
