// Statistical tests of the smooth plugin's metal_rough model (glTF's metallic-roughness BRDF)
// through its ABI: chi-square of sample() against pdf() for dielectric, metal, mixed and coated
// points at three angles; white furnace (a white dielectric returns 1; nothing returns more);
// reciprocity; sample() and eval() agree.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "../../plugins/smooth/albedo_tables.h"
#include "bsdf_harness.h"
#include "chi2.h"
#include "warp_chi2.h"

namespace spangle::test::metal_rough {
namespace {

constexpr uint32_t kSamples = 100000;
constexpr double kSignificance = 0.01;

using Params = std::vector<std::pair<std::string, std::vector<double>>>;

/** One chi-square case: the model's parameters and wo. */
struct ChiCase {
    std::string name;
    Params params;
    float roughness;  ///< perceptual: the warp's alpha is its square
    float cos_o;
};

/** gtest prints a case by its name. */
void PrintTo(const ChiCase& c, std::ostream* os) {
    *os << c.name;
}

/** Four kinds of point at three angles. */
std::vector<ChiCase> all_cases() {
    struct Kind {
        const char* name;
        float roughness;
        Params params;
    };
    const Kind kinds[] = {
        {"dielectric", 0.5f, {{"metallic", {0.0}}, {"base_color", {0.6, 0.5, 0.4}}}},
        {"metal", 0.3f, {{"metallic", {1.0}}, {"base_color", {0.9, 0.6, 0.3}}}},
        {"mixed_coated",
         0.8f,
         {{"metallic", {0.5}},
          {"clearcoat", {0.5}},
          {"clearcoat_roughness", {0.3}},
          {"ior", {1.8}},
          {"specular", {0.7}},
          {"specular_color", {1.0, 0.8, 0.6}}}},
        {"glossy_coat",
         0.1f,
         {{"metallic", {0.0}},
          {"clearcoat", {1.0}},
          {"clearcoat_roughness", {0.05}},
          {"base_color", {0.1, 0.1, 0.5}}}},
        {"velvet",
         0.6f,
         {{"metallic", {0.0}},
          {"base_color", {0.3, 0.05, 0.1}},
          {"sheen_color", {1.0, 0.8, 0.9}},
          {"sheen_roughness", {0.3}}}},
        {"fine_sheen_coated",
         0.4f,
         {{"metallic", {0.2}},
          {"sheen_color", {0.5, 0.5, 0.5}},
          {"sheen_roughness", {0.07}},
          {"clearcoat", {0.3}},
          {"clearcoat_roughness", {0.3}}}},
    };
    std::vector<ChiCase> out;
    for (const Kind& k : kinds)
        for (float c : {0.95f, 0.5f, 0.1f}) {
            Params p = k.params;
            p.push_back({"roughness", {k.roughness}});
            out.push_back(
                {fmt::format("{}_cos{}", k.name, static_cast<int>(c * 100)), p, k.roughness, c});
        }
    return out;
}

/** wo at cosine cos_o, off-axis. */
Vec3 wo_for(float cos_o) {
    const float s = std::sqrt(1.0f - cos_o * cos_o);
    return {s * std::cos(0.7f), s * std::sin(0.7f), cos_o};
}

class MetalRoughChi2 : public ::testing::TestWithParam<ChiCase> {};

TEST_P(MetalRoughChi2, SampleMatchesPdf) {
    const ChiCase& c = GetParam();
    BsdfHarness bsdf("smooth", "metal_rough", c.params);
    const Vec3 wo = wo_for(c.cos_o);
    bsdf.prepare(wo);
    // Bins in the slope space of the base lobe; the diffuse and coat lobes land in the same
    // bins (any binning is a valid chi-square test, this one resolves the sharpest lobe).
    const float alpha = std::max(c.roughness * c.roughness, 1e-3f);
    const Warp warp{wo, alpha, alpha, 0.0f};
    double total = 0.0;
    const double per_test =
        1.0 - std::pow(1.0 - kSignificance, 1.0 / static_cast<double>(all_cases().size()));
    const Chi2Result r = warped_chi2(bsdf, warp, kSamples, 4243, per_test, c.name, total);
    EXPECT_LT(total, 1.0 + 2e-3) << "the pdf integrates to more than 1";
    EXPECT_GT(r.p_value, per_test) << c.name << ": chi2 " << r.statistic << " with " << r.dof
                                   << " dof, pooled " << r.pooled << " cells";
}

INSTANTIATE_TEST_SUITE_P(MetalRough, MetalRoughChi2, ::testing::ValuesIn(all_cases()),
                         [](const ::testing::TestParamInfo<ChiCase>& p) { return p.param.name; });

/** Albedo estimates of channel `ch` from kSamples samples, seed 78. */
BsdfHarness::Albedo albedo(const BsdfHarness& b, int ch) {
    return b.albedo(kSamples, 78, ch);
}

TEST(MetalRoughFurnace, WhiteDielectricReturnsOne) {
    for (float r : {0.0f, 0.1f, 0.5f, 1.0f})
        for (float c : {1.0f, 0.6f, 0.2f, 0.05f})
            for (double specular : {1.0, 0.3}) {
                BsdfHarness b("smooth", "metal_rough",
                              {{"metallic", {0.0}},
                               {"roughness", {r}},
                               {"specular", {specular}},
                               {"base_color", {1.0, 1.0, 1.0}}});
                b.prepare(wo_for(c));
                const auto [mean, se] = albedo(b, 1);
                // E(o) + (1 - E(o)) = 1 by construction; 5e-3 allows for the albedo tables
                // (512-point quadratures, bilinear in 32 cosines x 32 roughnesses).
                EXPECT_NEAR(mean, 1.0, 4.0 * se + 5e-3)
                    << "roughness " << r << " cos " << c << " specular " << specular;
            }
}

TEST(MetalRoughFurnace, WhiteMetalReturnsOne) {
    // A white metal with its multiple scattering (the default) reflects everything at every
    // roughness and angle (5e-3 for the tables, as above); without it (multiscatter = false,
    // glTF's reference BRDF) it loses light at high roughness.
    for (float r : {0.0f, 0.3f, 0.7f, 1.0f})
        for (float c : {1.0f, 0.6f, 0.2f, 0.05f}) {
            BsdfHarness b(
                "smooth", "metal_rough",
                {{"metallic", {1.0}}, {"roughness", {r}}, {"base_color", {1.0, 1.0, 1.0}}});
            b.prepare(wo_for(c));
            const auto [mean, se] = albedo(b, 1);
            EXPECT_NEAR(mean, 1.0, 4.0 * se + 5e-3) << "roughness " << r << " cos " << c;
            BsdfHarness s("smooth", "metal_rough",
                          {{"metallic", {1.0}},
                           {"roughness", {r}},
                           {"base_color", {1.0, 1.0, 1.0}},
                           {"multiscatter", {0.0}}});
            s.prepare(wo_for(c));
            const auto [mean1, se1] = albedo(s, 1);
            EXPECT_LE(mean1, 1.0 + 4.0 * se1 + 5e-3) << "roughness " << r << " cos " << c;
            if (r >= 1.0f && c >= 0.6f) {
                EXPECT_LT(mean1, 0.8) << "single scattering loses light, cos " << c;
            }
        }
}

TEST(MetalRoughFurnace, NoPointReturnsMoreThanItReceives) {
    for (const ChiCase& k : all_cases())
        for (float c : {1.0f, 0.3f, 0.05f}) {
            Params p = k.params;
            p.push_back({"base_color", {1.0, 1.0, 1.0}});  // the brightest base
            BsdfHarness b("smooth", "metal_rough", p);
            b.prepare(wo_for(c));
            for (int ch = 0; ch < 3; ++ch) {
                const auto [mean, se] = albedo(b, ch);
                // The coat takes only what it reflects; the metal loses energy to single
                // scattering; 5e-3 as above.
                EXPECT_LE(mean, 1.0 + 4.0 * se + 5e-3) << k.name << " cos " << c << " ch " << ch;
            }
        }
}

TEST(MetalRoughSheen, AWhiteSheenOverAWhiteBaseKeepsItsLightAndLightsTheRim) {
    // The base keeps what the sheen leaves (1 - E_s, the lesser of the two directions'), so a
    // white sheen over a white dielectric returns at most everything, and nearly everything:
    // what is lost is the difference of E_s between the two directions. Seen at grazing, the
    // sheen brightens the surface (the velvet rim).
    for (float r : {0.07f, 0.3f, 1.0f})
        for (float c : {1.0f, 0.6f, 0.2f, 0.05f}) {
            BsdfHarness b("smooth", "metal_rough",
                          {{"metallic", {0.0}},
                           {"roughness", {0.5}},
                           {"base_color", {1.0, 1.0, 1.0}},
                           {"sheen_color", {1.0, 1.0, 1.0}},
                           {"sheen_roughness", {r}}});
            b.prepare(wo_for(c));
            const auto [mean, se] = albedo(b, 1);
            EXPECT_LE(mean, 1.0 + 4.0 * se + 5e-3) << "sheen roughness " << r << " cos " << c;
            EXPECT_GE(mean, 0.85) << "sheen roughness " << r << " cos " << c;
        }
    const Params plain{{"metallic", {0.0}}, {"roughness", {0.6}}, {"base_color", {0.2, 0.2, 0.2}}};
    Params velvet = plain;
    velvet.push_back({"sheen_color", {1.0, 1.0, 1.0}});
    velvet.push_back({"sheen_roughness", {0.3}});
    BsdfHarness a("smooth", "metal_rough", plain), v("smooth", "metal_rough", velvet);
    const Vec3 grazing = wo_for(0.1f);
    a.prepare(grazing);
    v.prepare(grazing);
    std::vector<Vec3> fa, fv;
    std::vector<float> pdf;
    const Vec3 wi = grazing;  // back towards the viewer, at grazing: the rim
    a.eval({wi}, fa, pdf);
    v.eval({wi}, fv, pdf);
    EXPECT_GT(fv[0].y, 2.0f * fa[0].y) << "a sheen lights the rim";
}

TEST(MetalRoughReciprocity, EvalIsSymmetric) {
    for (const ChiCase& k : all_cases()) {
        BsdfHarness a("smooth", "metal_rough", k.params), b("smooth", "metal_rough", k.params);
        for (uint32_t i = 0; i < 100; ++i) {
            const auto dir = [&](uint32_t d) {
                const float z = 0.05f + 0.95f * sample_1d(6, i, d, 0);
                const float phi = 2.0f * kPi * sample_1d(6, i, d, 1);
                const float s = std::sqrt(1.0f - z * z);
                return Vec3(s * std::cos(phi), s * std::sin(phi), z);
            };
            const Vec3 w1 = dir(0), w2 = dir(1);
            std::vector<Vec3> f12, f21;
            std::vector<float> pdf;
            a.prepare(w1);
            a.eval({w2}, f12, pdf);
            b.prepare(w2);
            b.eval({w1}, f21, pdf);
            // 1e-4 relative: float rounding of the same terms in another order.
            for (int ch = 0; ch < 3; ++ch)
                EXPECT_NEAR(f12[0][ch], f21[0][ch], 1e-4f * std::max(1.0f, f12[0][ch]))
                    << k.name << " pair " << i;
        }
    }
}

TEST(MetalRoughConsistency, SampleAndEvalAgree) {
    for (const ChiCase& c : all_cases()) {
        BsdfHarness bsdf("smooth", "metal_rough", c.params);
        bsdf.prepare(wo_for(c.cos_o));
        const auto samples = bsdf.sample(2000, 98);
        std::vector<Vec3> f;
        std::vector<float> pdf;
        bsdf.eval(samples, f, pdf);
        std::size_t valid = 0;
        for (std::size_t i = 0; i < samples.size(); ++i) {
            const auto& s = samples[i];
            ASSERT_TRUE(std::isfinite(s.pdf) && std::isfinite(s.f.x)) << c.name;
            if (s.flags == 0) continue;
            ++valid;
            EXPECT_NEAR(pdf[i], s.pdf, 1e-5f * s.pdf) << c.name;
            EXPECT_NEAR(f[i].y, s.f.y, 1e-5f * s.f.y + 1e-7f) << c.name;
        }
        EXPECT_GT(valid, samples.size() / 2) << c.name << ": most samples are invalid";
    }
}

/** The albedo tables metal_rough ships are the quadrature they were written from: bit for bit
 *  on the machine that wrote them, within float rounding elsewhere (another libm may round a
 *  sine or a power differently in the last place). When they differ by more, the quadrature or
 *  the GGX functions changed: the file is written anew next to the test's working directory. */
TEST(MetalRoughTables, ShippedTablesAreTheQuadrature) {
    const smooth::AlbedoTables computed = smooth::compute_albedo_tables();
    const smooth::AlbedoTables& shipped = smooth::shipped_albedo_tables();
    double worst = 0.0;
    int differ = 0;
    const auto compare = [&](float a, float b) {
        worst = std::max(worst, std::fabs(static_cast<double>(a) - static_cast<double>(b)));
        differ += a != b ? 1 : 0;
    };
    for (int j = 0; j < smooth::kAlbedoRough; ++j) {
        for (int i = 0; i < smooth::kAlbedoMu; ++i) {
            compare(computed.a[j][i], shipped.a[j][i]);
            compare(computed.b[j][i], shipped.b[j][i]);
        }
        compare(computed.a_avg[j], shipped.a_avg[j]);
        compare(computed.b_avg[j], shipped.b_avg[j]);
    }
    // Sanity of the tables themselves: a white GGX reflects at most what it receives, and the
    // smoothest lobe at normal incidence nearly all of it.
    EXPECT_GT(shipped.a[0][smooth::kAlbedoMu - 1] + shipped.b[0][smooth::kAlbedoMu - 1], 0.99f);
    for (int j = 0; j < smooth::kAlbedoRough; ++j)
        for (int i = 0; i < smooth::kAlbedoMu; ++i)
            EXPECT_LE(shipped.a[j][i] + shipped.b[j][i], 1.0f + 1e-6f) << j << "," << i;
    if (worst > 1e-6) {
        const std::filesystem::path out = std::filesystem::absolute("albedo_tables_data.inc.new");
        std::ofstream(out) << smooth::albedo_tables_source(computed);
        ADD_FAILURE() << differ << " entries differ, by up to " << worst
                      << "; the quadrature's tables are in " << out.string()
                      << ": copy them to plugins/smooth/albedo_tables_data.inc";
    }
    RecordProperty("entries_differing_in_the_last_place", differ);
}

}  // namespace
}  // namespace spangle::test::metal_rough
