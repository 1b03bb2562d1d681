// Numerically hard situations for every material model, one named case each. Every case
// asserts: sampled f, pdf and wi finite; f >= 0 and pdf >= 0; pdf > 0 wherever a sample carries
// f > 0; eval() at the sampled directions gives pdf > 0 wherever it gives f > 0; and eval() over
// the whole sphere (under the horizon, exactly grazing, the mirror and the reverse of wo) stays
// finite and non-negative. Images of hard scenes are in test_render_stability.cpp.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>
#include <vector>

#include "bsdf_harness.h"
#include "core/hash.h"
#include "flake_support.h"

namespace spangle::test {
namespace {

using Numbers = std::vector<std::pair<std::string, std::vector<double>>>;
using Strings = std::vector<std::pair<std::string, std::string>>;

struct HardCase {
    std::string name;  ///< gtest name
    std::string plugin, model;
    Numbers numbers;
    Strings strings;
    Vec3 wo;
    bool backface = false;
    BsdfHarness::Point pt{};
};

/** A footprint of side d in uv (a slightly sheared square), or none. */
BsdfHarness::Point at(float u, float v, float du, float dv, bool differentials = true) {
    BsdfHarness::Point p;
    p.u = u;
    p.v = v;
    p.dudx = du;
    p.dvdy = dv;
    p.dvdx = 0.3f * dv;
    p.has_differentials = differentials;
    return p;
}

const BsdfHarness::Point kPoint = at(0.3f, 0.3f, 0.002f, 0.002f);

/** Flakes with the discrete lobe kept at every footprint size. */
Numbers flakes(Numbers extra = {}) {
    Numbers p = {{"min_flakes", {5e8}}, {"max_flakes", {1e9}}};
    for (auto& e : extra) p.push_back(e);
    return p;
}

std::vector<HardCase> hard_cases() {
    const Vec3 o = dir(0.7f, 0.3f);
    std::vector<HardCase> c;
    for (const char* model : {"diffuse", "conductor", "dielectric", "plastic"}) {
        const std::string m = model;
        // cos 1e-7: 1/cos factors in f and pdf reach 1e7; half vectors lose their precision.
        c.push_back({m + "_cos_1e_7", "smooth", m, {}, {}, dir(1e-7f, 0.4f)});
        // Exactly grazing: wo.z = 0 divides by zero in every microfacet formula.
        c.push_back({m + "_cos_0", "smooth", m, {}, {}, Vec3(1.0f, 0.0f, 0.0f)});
        // wo under the shading horizon (a shading normal bent away from the viewer).
        c.push_back({m + "_wo_under_horizon", "smooth", m, {}, {}, dir(-0.3f, 0.2f)});
        // Normal incidence: wo = n, where azimuths are undefined.
        c.push_back({m + "_normal_incidence", "smooth", m, {}, {}, Vec3(0.0f, 0.0f, 1.0f)});
    }
    for (const char* model : {"conductor", "dielectric", "plastic"}) {
        const std::string m = model;
        // Roughness 0: the delta lobe, whose f and pdf are both delta-scaled.
        c.push_back({m + "_roughness_0", "smooth", m, {{"roughness", {0.0}}}, {}, o});
        // Just above the delta threshold: D peaks at 1/(pi alpha^2) = 3e7.
        c.push_back({m + "_roughness_1e_4", "smooth", m, {{"roughness", {1.0001e-4}}}, {}, o});
        // Roughness 1: the widest lobe, G near 0 at grazing.
        c.push_back(
            {m + "_roughness_1", "smooth", m, {{"roughness", {1.0}}}, {}, dir(0.05f, 0.1f)});
        // Anisotropy 1000:1: the VNDF stretch is extreme in one axis.
        c.push_back({m + "_anisotropy_1000",
                     "smooth",
                     m,
                     {{"roughness", {1e-3}}, {"roughness_v", {1.0}}},
                     {},
                     dir(0.2f, 0.7f)});
    }
    for (const char* model : {"dielectric", "plastic"}) {
        const std::string m = model;
        for (double r : {0.0, 0.3}) {
            const std::string rough = r > 0.0 ? "_rough" : "_smooth";
            // IOR 1: an index-matched interface; the refraction half vector wi + eta wo is 0.
            c.push_back(
                {m + "_ior_1" + rough, "smooth", m, {{"ior", {1.0}}, {"roughness", {r}}}, {}, o});
            // IOR 10: Fresnel near 1 and a critical angle of 5.7 degrees from inside.
            c.push_back({m + "_ior_10" + rough,
                         "smooth",
                         m,
                         {{"ior", {10.0}}, {"roughness", {r}}},
                         {},
                         dir(0.3f, 0.5f)});
        }
    }
    for (double r : {0.0, 0.3}) {
        const std::string rough = r > 0.0 ? "_rough" : "_smooth";
        // From inside glass of IOR 10 at a shallow angle: total internal reflection.
        c.push_back({"dielectric_inside_ior_10" + rough,
                     "smooth",
                     "dielectric",
                     {{"ior", {10.0}}, {"roughness", {r}}},
                     {},
                     dir(0.3f, 0.5f),
                     true});
        // From inside an index-matched interface: eta = 1 seen from the back as well.
        c.push_back({"dielectric_inside_ior_1" + rough,
                     "smooth",
                     "dielectric",
                     {{"ior", {1.0}}, {"roughness", {r}}},
                     {},
                     dir(0.6f, 0.5f),
                     true});
    }
    // Conductor with k = 0: the complex Fresnel formula degenerates to a dielectric's.
    c.push_back({"conductor_k_0",
                 "smooth",
                 "conductor",
                 {{"eta", {1.5, 1.5, 1.5}}, {"k", {0.0, 0.0, 0.0}}},
                 {{"preset", "custom"}},
                 o});
    // Conductor with eta = 1, k = 0: reflects nothing at all (F = 0 everywhere).
    c.push_back({"conductor_eta_1_k_0",
                 "smooth",
                 "conductor",
                 {{"eta", {1.0, 1.0, 1.0}}, {"k", {0.0, 0.0, 0.0}}},
                 {{"preset", "custom"}},
                 o});

    // The flake model. Footprints and counts first.
    // Grazing at cos 1e-7: the footprint projects to a needle; 1/cos weights are huge.
    c.push_back(
        {"flake_cos_1e_7", "flake", "flake", flakes(), {}, dir(1e-7f, 0.3f), false, kPoint});
    // Exactly grazing.
    c.push_back({"flake_cos_0", "flake", "flake", flakes(), {}, Vec3(1, 0, 0), false, kPoint});
    // wo under the shading horizon.
    c.push_back({"flake_wo_under_horizon",
                 "flake",
                 "flake",
                 flakes(),
                 {},
                 dir(-0.2f, 0.3f),
                 false,
                 kPoint});
    // Zero-area footprint: no differentials' extent, no flakes expected.
    c.push_back({"flake_zero_area_footprint",
                 "flake",
                 "flake",
                 flakes(),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 0.0f, 0.0f)});
    // Needle footprint: 1e-9 by 0.5 uv, the quad-tree descends one axis only.
    c.push_back({"flake_needle_footprint",
                 "flake",
                 "flake",
                 flakes(),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 0.5f, 1e-9f)});
    // A footprint larger than the whole uv square (1e6): counts overflow 32 bits.
    c.push_back({"flake_footprint_larger_than_uv_square",
                 "flake",
                 "flake",
                 flakes(),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 1e6f, 1e6f)});
    // uv at 1e6: floats there are 0.06 apart, so a flake cell is below one ulp.
    c.push_back(
        {"flake_uv_1e6", "flake", "flake", flakes(), {}, o, false, at(1e6f, 1e6f, 0.002f, 0.002f)});
    // Negative uv: cell indices below zero must not wrap or index out of range.
    c.push_back({"flake_uv_negative",
                 "flake",
                 "flake",
                 flakes(),
                 {},
                 o,
                 false,
                 at(-1e6f, -3.5f, 0.002f, 0.002f)});
    // No differentials at all: the smooth limit.
    c.push_back({"flake_no_differentials",
                 "flake",
                 "flake",
                 flakes(),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 0.0f, 0.0f, false)});
    // One flake per unit square: almost every footprint is empty.
    c.push_back({"flake_density_1",
                 "flake",
                 "flake",
                 flakes({{"density", {1.0}}}),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 0.5f, 0.5f)});
    // 2^31-1 flakes per unit square at the deepest tree: leaf cells of 1e-7 uv.
    c.push_back({"flake_density_2e31_deep",
                 "flake",
                 "flake",
                 flakes({{"density", {2147483647.0}}, {"max_depth", {24.0}}}),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 1e-5f, 1e-5f)});
    // 2^31-1 flakes in a large footprint: 2e8 flakes expected in one point.
    c.push_back({"flake_density_2e31_large_footprint",
                 "flake",
                 "flake",
                 flakes({{"density", {2147483647.0}}}),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 0.3f, 0.3f)});
    // Gamma at both ends: 0.01 degrees (cones of 1e-8 sr) and 45 degrees.
    c.push_back(
        {"flake_gamma_0_01", "flake", "flake", flakes({{"gamma", {0.01}}}), {}, o, false, kPoint});
    c.push_back(
        {"flake_gamma_45", "flake", "flake", flakes({{"gamma", {45.0}}}), {}, o, false, kPoint});
    // Flake roughness at both ends: 0.001 (all flakes face the normal) and 1.
    c.push_back({"flake_roughness_0_001",
                 "flake",
                 "flake",
                 flakes({{"flake_roughness", {0.001}}}),
                 {},
                 o,
                 false,
                 kPoint});
    c.push_back({"flake_roughness_1",
                 "flake",
                 "flake",
                 flakes({{"flake_roughness", {1.0}}}),
                 {},
                 o,
                 false,
                 kPoint});
    // Smooth and rough clear coats at grazing angles: Fresnel near 1, refraction near critical.
    c.push_back({"flake_coat_grazing",
                 "flake",
                 "flake",
                 flakes({{"coat", {1.0}}}),
                 {},
                 dir(1e-3f, 0.3f),
                 false,
                 kPoint});
    c.push_back({"flake_rough_coat_grazing",
                 "flake",
                 "flake",
                 flakes({{"coat", {1.0}}, {"coat_roughness", {0.3}}}),
                 {},
                 dir(1e-5f, 0.3f),
                 false,
                 kPoint});
    // Coat of IOR 1 (invisible) and 10.
    c.push_back({"flake_coat_ior_1",
                 "flake",
                 "flake",
                 flakes({{"coat", {1.0}}, {"coat_ior", {1.0}}}),
                 {},
                 o,
                 false,
                 kPoint});
    c.push_back({"flake_coat_ior_10",
                 "flake",
                 "flake",
                 flakes({{"coat", {1.0}}, {"coat_ior", {10.0}}, {"coat_roughness", {0.3}}}),
                 {},
                 dir(0.1f, 0.3f),
                 false,
                 kPoint});
    // Every footprint cell enumerated (exact_flakes 1 forces the counting path everywhere).
    c.push_back({"flake_exact_flakes_1",
                 "flake",
                 "flake",
                 flakes({{"exact_flakes", {1.0}}}),
                 {},
                 o,
                 false,
                 at(0.3f, 0.3f, 0.02f, 0.02f)});
    // The smooth lobe at grazing, as far away objects use it.
    c.push_back({"flake_smooth_lobe_grazing",
                 "flake",
                 "flake",
                 {{"min_flakes", {0.0}}, {"max_flakes", {1.0}}},
                 {},
                 dir(1e-6f, 0.3f),
                 false,
                 kPoint});
    // The same hard cases with the reference algorithm.
    std::vector<HardCase> enumerate;
    for (const HardCase& h : c) {
        if (h.plugin != "flake") continue;
        HardCase e = h;
        e.name += "_enumerate";
        e.strings.push_back({"algorithm", "enumerate"});
        enumerate.push_back(e);
    }
    c.insert(c.end(), enumerate.begin(), enumerate.end());
    return c;
}

/** gtest prints the case by name, not as bytes. */
void PrintTo(const HardCase& h, std::ostream* os) {
    *os << h.name;
}

class BsdfStability : public ::testing::TestWithParam<HardCase> {};

TEST_P(BsdfStability, FiniteNonNegativeAndConsistent) {
    const HardCase& h = GetParam();
    BsdfHarness m(h.plugin, h.model, h.numbers, h.strings);
    m.prepare(h.wo, h.pt, h.backface);
    const auto samples = m.sample(4000, 11);
    std::vector<Vec3> sampled;
    std::size_t carrying = 0;
    for (const auto& s : samples) {
        ASSERT_TRUE(std::isfinite(s.pdf) && is_finite(s.f) && is_finite(s.wi));
        ASSERT_GE(s.pdf, 0.0f);
        ASSERT_GE(std::min({s.f.x, s.f.y, s.f.z}), 0.0f);
        if (s.flags == 0) continue;
        if (max_component(s.f) > 0.0f) {
            ASSERT_GT(s.pdf, 0.0f) << "a sample carries f > 0 with pdf 0";
            ++carrying;
        }
        ASSERT_NEAR(length(s.wi), 1.0f, 1e-3f);
        if ((s.flags & SPANGLE_SAMPLE_SPECULAR) == 0) sampled.push_back(s.wi);
    }
    // The smooth models conserve energy at every wo: the mean sample weight f |cos| / pdf (the
    // directional albedo) is at most 1. (A flake footprint may reflect more than the average.)
    if (h.plugin == "smooth") {
        double albedo = 0.0;
        for (const auto& s : samples)
            if (s.flags != 0 && s.pdf > 0.0f)
                albedo += static_cast<double>(max_component(s.f) * std::fabs(s.wi.z) / s.pdf) /
                          static_cast<double>(samples.size());
        EXPECT_LE(albedo, 1.01) << "directional albedo above 1";
    }
    // An index-matched interface passes light straight through, unweakened.
    if (h.model == "dielectric" && h.name.find("ior_1_") != std::string::npos) {
        for (const auto& s : samples) {
            ASSERT_NE(s.flags, 0u);
            EXPECT_NEAR(dot(s.wi, h.wo), -1.0f, 1e-5f);
            EXPECT_NEAR(max_component(s.f) * std::fabs(s.wi.z) / s.pdf, 1.0f, 1e-4f);
        }
    }
    std::vector<Vec3> f;
    std::vector<float> pdf;
    m.eval(sampled, f, pdf);
    for (std::size_t i = 0; i < sampled.size(); ++i) {
        ASSERT_TRUE(is_finite(f[i]) && std::isfinite(pdf[i]));
        if (max_component(f[i]) > 0.0f) {
            ASSERT_GT(pdf[i], 0.0f) << "eval: f > 0 where pdf is 0";
        }
    }
    // The whole sphere, and the directions formulas divide by.
    std::vector<Vec3> all = {{0, 0, 1},    {0, 0, -1},   {1, 0, 0}, {0, -1, 0},
                             mirror(h.wo), h.wo * -1.0f, h.wo,      {h.wo.x, h.wo.y, -h.wo.z}};
    for (uint32_t i = 0; i < 1000; ++i)
        all.push_back(dir(2.0f * sample_1d(6, i, 0, 0) - 1.0f, 2.0f * kPi * sample_1d(6, i, 0, 1)));
    m.eval(all, f, pdf);
    for (std::size_t i = 0; i < all.size(); ++i) {
        ASSERT_TRUE(is_finite(f[i]) && std::isfinite(pdf[i])) << "direction " << i;
        ASSERT_GE(pdf[i], 0.0f);
        ASSERT_GE(std::min({f[i].x, f[i].y, f[i].z}), 0.0f);
    }
    // Where the case is not degenerate by construction, light must still get through: a material
    // that silently turns black passes every check above.
    const bool may_be_black = h.wo.z <= 0.0f || h.name.find("eta_1_k_0") != std::string::npos ||
                              h.name.find("zero_area") != std::string::npos ||
                              h.name.find("density_1_") != std::string::npos ||
                              h.name.ends_with("density_1");
    if (!may_be_black) {
        EXPECT_GT(carrying, 0u) << "no sample carries light";
    }
}

INSTANTIATE_TEST_SUITE_P(Stability, BsdfStability, ::testing::ValuesIn(hard_cases()),
                         [](const ::testing::TestParamInfo<HardCase>& p) { return p.param.name; });

}  // namespace
}  // namespace spangle::test
