// Path regularisation in the flake plugin: with the host's roughness floor, a flake paint's clear
// coat is no sharper than the floor (rounded up to one of a few rough coats), its flakes and base
// are untouched, and the whole material still keeps its energy and samples by its pdf.

#include <gtest/gtest.h>

#include <cmath>

#include "flake_support.h"

namespace spangle::test::flake_regularisation {
namespace {

/** wi spread over the upper hemisphere (Fibonacci). */
std::vector<Vec3> hemisphere(uint32_t n) {
    std::vector<Vec3> wi;
    for (uint32_t k = 0; k < n; ++k) {
        const float z = (static_cast<float>(k) + 0.5f) / static_cast<float>(n);
        wi.push_back(dir(z, 2.39996323f * static_cast<float>(k)));
    }
    return wi;
}

/** A flake paint with a white base and a coat of the given roughness, prepared at a footprint of
 *  the discrete regime or without differentials (`smooth`), with a floor (0: none). */
std::unique_ptr<BsdfHarness> paint(double coat_roughness, Vec3 wo, float floor, bool smooth,
                                   double base = 0.5) {
    auto m = flake_material(false,
                            {{"coat", {1.0}},
                             {"coat_roughness", {coat_roughness}},
                             {"base_color", {base}},
                             {"flake_weight", {0.5}}},
                            {{"preset", "perfect"}});
    BsdfHarness::Point pt = footprint(60.0, 3.3f, 7.1f);
    pt.has_differentials = !smooth;
    pt.roughness_floor = floor;
    m->prepare(wo, pt);
    return m;
}

void expect_same(const BsdfHarness& a, const BsdfHarness& b, const char* what) {
    const std::vector<Vec3> wi = hemisphere(3000);
    std::vector<Vec3> fa, fb;
    std::vector<float> pa, pb;
    a.eval(wi, fa, pa);
    b.eval(wi, fb, pb);
    for (std::size_t i = 0; i < wi.size(); ++i) {
        ASSERT_EQ(fa[i].y, fb[i].y) << what << " wi " << i;
        ASSERT_EQ(pa[i], pb[i]) << what << " wi " << i;
    }
}

TEST(FlakeRegularisation, ASmoothCoatUnderAFloorIsTheRoughCoatOfTheLevelAbove) {
    const Vec3 wo = dir(0.6f, 0.4f);
    for (bool smooth : {false, true}) {
        // Floors 0.41 and 0.5 (after a diffuse bounce) take the 0.5 coat, 0.2 the 0.25 one.
        expect_same(*paint(0.0, wo, 0.41f, smooth), *paint(0.5, wo, 0.0f, smooth), "0.41");
        expect_same(*paint(0.0, wo, 0.5f, smooth), *paint(0.5, wo, 0.0f, smooth), "0.5");
        expect_same(*paint(0.0, wo, 0.2f, smooth), *paint(0.25, wo, 0.0f, smooth), "0.2");
        // A coat already as rough as the level: its own.
        expect_same(*paint(0.3, wo, 0.2f, smooth), *paint(0.3, wo, 0.0f, smooth), "own");
    }
    // And no sample of a floored coat is a delta.
    for (const auto& s : paint(0.0, wo, 0.45f, false)->sample(4000, 3))
        EXPECT_EQ(s.flags & SPANGLE_SAMPLE_SPECULAR, 0u);
}

TEST(FlakeRegularisation, AFlooredPaintKeepsItsEnergyAndSamplesByItsPdf) {
    for (float cos_o : {0.9f, 0.3f, 0.02f}) {
        const Vec3 wo = dir(cos_o, 1.1f);
        // White furnace: white base, perfect white flakes, a floored coat over them.
        auto m = paint(0.0, wo, 0.45f, true, 1.0);
        const auto [mean, se] = m->albedo(40000, 9);
        EXPECT_LE(mean, 1.0 + 4.0 * se) << "cos_o " << cos_o;
        EXPECT_GT(mean, 0.8) << "cos_o " << cos_o;
        const auto samples = m->sample(3000, 11);
        std::vector<Vec3> f;
        std::vector<float> pdf;
        m->eval(samples, f, pdf);
        for (std::size_t i = 0; i < samples.size(); ++i) {
            if (samples[i].flags == 0) continue;
            EXPECT_NEAR(pdf[i], samples[i].pdf, 1e-3f * samples[i].pdf) << "cos_o " << cos_o;
        }
    }
}

// A smooth coat (the beetle's) is the only lobe that sees a small bright light in its mirror
// direction (a softbox, the sun): its reflection there converges as the share of BSDF samples
// that pick it. By energy alone (the coat reflects 4% head-on and 9% at cos 0.5, against a red
// base and flakes) that share
// was 7.1% at cos 0.9 and 15.0% at cos 0.5 with these samples; a sharp coat is now chosen 3x as
// often as its energy says (mf::sharp_lobe_weight), as the smooth plugin's coats are, so at least
// twice as many samples find it (18.8% and 34.4%).
TEST(FlakeCoat, ASmoothCoatGetsThreeTimesItsEnergyShareOfSamples) {
    const std::pair<float, double> cases[] = {{0.9f, 0.071}, {0.5f, 0.150}};  // cos, share before
    for (const auto& [cos_o, before] : cases) {
        const Vec3 wo = dir(cos_o, 0.4f);
        auto m = flake_material(false,
                                {{"coat", {1.0}},
                                 {"coat_roughness", {0.0}},
                                 {"base_color", {0.5, 0.02, 0.03}},
                                 {"flake_weight", {0.5}}},
                                {{"preset", "perfect"}});
        m->prepare(wo, footprint(60.0, 3.3f, 7.1f));
        const Vec3 mirror{-wo.x, -wo.y, wo.z};
        uint32_t in = 0;
        const std::vector<BsdfHarness::Sample> s = m->sample(20000, 99);
        for (const BsdfHarness::Sample& x : s)
            if (x.pdf > 0.0f &&
                x.wi.x * mirror.x + x.wi.y * mirror.y + x.wi.z * mirror.z > 1.0f - 1e-6f)
                ++in;
        const double share = static_cast<double>(in) / static_cast<double>(s.size());
        EXPECT_GT(share, 2.0 * before) << "cos " << cos_o;
        EXPECT_LT(share, 0.5) << "cos " << cos_o << ": the other lobes keep most samples";
    }
}

}  // namespace
}  // namespace spangle::test::flake_regularisation
