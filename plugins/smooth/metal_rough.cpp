// metal_rough: glTF 2.0's metallic-roughness material (glTF 2.0, Appendix B) as one BSDF.
//
//   f = cc Fc(v.h) Dc G2c / (4 |n.v| |n.l|)  +  (1 - Ec(v)) (1 - Ec(l)) f_base
//   f_base = (1 - metallic) f_dielectric + metallic f_metal
//   f_metal = F_schlick(base_color, v.h) D G2 / (4 |n.v| |n.l|)
//             + F_ms (1 - E1(v)) (1 - E1(l)) / (pi (1 - E1_avg))   (multiscatter; albedo_tables.h)
//   f_dielectric = F_schlick(f0, f90, v.h) D G2 / (4 |n.v| |n.l|)
//                  + base_color / pi (1 - E(v)) (1 - E(l)) / (1 - E_avg)
//   f0 = min(((ior - 1) / (ior + 1))^2 specular_color, 1) specular, f90 = specular
//
// D and G2 are GGX with alpha = roughness^2 (height-correlated Smith), the clear coat's with
// alpha = clearcoat_roughness^2, f0 = 0.04 and f90 = 1 (ior 1.5), weighted by `clearcoat`.
// glTF mixes the diffuse base by (1 - F(v.h)), which is not energy-conserving at grazing
// angles; here the base sees the light the specular lobe leaves (Kulla and Conty 2017, the
// plastic model's layering): E(mu) = f0 A(mu, alpha) + f90 B(mu, alpha) is the specular
// lobe's exact directional albedo, with A and B tabulated once for GGX (Schlick's Fresnel is
// affine in f0 and f90). The white furnace of a white dielectric returns 1; the coat only
// takes light away. Alphas below 1e-3 are clamped there (a near-mirror, sampled as glossy).
//
// Parameters (textures: base_color and specular_color sRGB, the rest data):
//   base_color          color [1]    base colour (dielectric albedo, metal F0)
//   metallic, roughness float 1, 1   glTF's factors; roughness is perceptual (alpha = r^2)
//   metallic_roughness  color [1]    glTF's packed texture: G multiplies roughness, B metallic
//   ior                 float 1.5    KHR_materials_ior
//   specular            float 1      KHR_materials_specular specularFactor
//   specular_color      color [1]    KHR_materials_specular specularColorFactor
//   clearcoat           float 0      KHR_materials_clearcoat clearcoatFactor
//   clearcoat_roughness float 0      KHR_materials_clearcoat clearcoatRoughnessFactor
//   multiscatter        bool  true   the metal's multiple scattering (Kulla and Conty 2017)
//   sheen_color         color [0]    KHR_materials_sheen sheenColorFactor (velvet, cloth)
//   sheen_roughness     float 0      KHR_materials_sheen sheenRoughnessFactor
//
// Sheen (KHR_materials_sheen, after Estevez and Kulla 2017 and Neubelt and Pettineo 2013): a
// layer over the base, under the coat:
//   f_under = sheen_color D_charlie(h) V(v, l) / max(1, E_s(v), E_s(l))
//             + f_base min(1 - s E'_s(v), 1 - s E'_s(l)),   E'_s = min(E_s, 1)
//   D_charlie = (2 + 1/a) sin(theta_h)^(1/a) / (2 pi), a = sheen_roughness^2 (r >= 0.07),
//   V = 1 / (4 (n.l + n.v - n.l n.v)),  s = max(sheen_color)
// E_s(mu, r) is the sheen lobe's directional albedo, a table made once per process by
// quadrature (sheen_albedo below). At grazing views of a fine sheen it exceeds 1 (the lobe with
// this visibility gains energy there); dividing by the larger of the two directions' E_s (or 1)
// keeps the lobe reciprocal and its albedo at most min(E_s, 1). The base sees what the sheen
// leaves, so a white sheen over a white base returns about all the light. The sheen is sampled
// with the diffuse lobe (cosine).

#include "metal_rough.h"

#include <algorithm>
#include <cmath>
#include <new>

#include "../common/microfacet.h"
#include "../common/plugin_support.h"
#include "albedo_tables.h"

namespace spangle::smooth {
namespace {

using namespace spangle::mf;
using namespace spangle::plugin_support;

constexpr float kMinAlpha = kAlbedoMinAlpha;  ///< alphas below are clamped (a near-mirror)

// clang-format off
const SpangleParamDesc_v3 kParams[] = {
    {"base_color", SPANGLE_PARAM_COLOR, {1, 1, 1}, nullptr, 0.0, 1.0, nullptr, "glTF baseColor: albedo of the dielectric, F0 of the metal", SPANGLE_PARAM_TEXTURABLE},
    {"metallic", SPANGLE_PARAM_FLOAT, {1, 0, 0}, nullptr, 0.0, 1.0, nullptr, "glTF metallicFactor: 0 dielectric, 1 metal", SPANGLE_PARAM_TEXTURABLE},
    {"roughness", SPANGLE_PARAM_FLOAT, {1, 0, 0}, nullptr, 0.0, 1.0, nullptr, "glTF roughnessFactor, perceptual: GGX alpha = roughness^2 (at least 1e-3)", SPANGLE_PARAM_TEXTURABLE},
    {"metallic_roughness", SPANGLE_PARAM_COLOR, {1, 1, 1}, nullptr, 0.0, 1.0, nullptr, "glTF metallicRoughnessTexture (read as data): G multiplies roughness, B metallic", SPANGLE_PARAM_TEXTURABLE},
    {"ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.0, 10.0, nullptr, "index of refraction of the dielectric (KHR_materials_ior)", 0},
    {"specular", SPANGLE_PARAM_FLOAT, {1, 0, 0}, nullptr, 0.0, 1.0, nullptr, "strength of the dielectric's specular reflection (KHR_materials_specular)", SPANGLE_PARAM_TEXTURABLE},
    {"specular_color", SPANGLE_PARAM_COLOR, {1, 1, 1}, nullptr, 0.0, 10.0, nullptr, "tint of the dielectric's F0 (KHR_materials_specular)", SPANGLE_PARAM_TEXTURABLE},
    {"clearcoat", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "strength of a clear coat of index 1.5 (KHR_materials_clearcoat)", SPANGLE_PARAM_TEXTURABLE},
    {"clearcoat_roughness", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "perceptual roughness of the clear coat: alpha = roughness^2 (at least 1e-3)", SPANGLE_PARAM_TEXTURABLE},
    {"multiscatter", SPANGLE_PARAM_BOOL, {1, 0, 0}, nullptr, 0.0, 1.0, nullptr, "the metal returns the light that bounces more than once between its microfacets (Kulla-Conty, as Cycles' Multiscatter GGX); false: single-scattering GGX (glTF's reference BRDF), darker when rough", 0},
    {"sheen_color", SPANGLE_PARAM_COLOR, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "colour of a sheen layer over the base (KHR_materials_sheen sheenColorFactor: velvet, cloth); 0: none", SPANGLE_PARAM_TEXTURABLE},
    {"sheen_roughness", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "roughness of the sheen (KHR_materials_sheen sheenRoughnessFactor): low, a rim at grazing angles; high, a soft haze (at least 0.07)", SPANGLE_PARAM_TEXTURABLE},
};
// clang-format on

enum Param : uint32_t {
    kBase,
    kMetallic,
    kRoughness,
    kPacked,
    kIor,
    kSpecular,
    kSpecColor,
    kCoat,
    kCoatRough,
    kMultiscatter,
    kSheen,
    kSheenRough
};

constexpr float kMinSheenRoughness = 0.07f;  ///< below, the lobe is a line at the horizon

/** The sheen's microfacet distribution (Charlie) at h, for alpha a. */
float charlie_d(V3 h, float a) {
    const float sin2 = std::max(0.0f, 1.0f - h.z * h.z);
    return (2.0f + 1.0f / a) * std::pow(sin2, 0.5f / a) * (0.5f * kInvPi);
}

/** The sheen's visibility term (Neubelt and Pettineo's, as glTF's sample viewer uses). */
float sheen_v(float mu_o, float mu_i) {
    return 1.0f / (4.0f * (mu_i + mu_o - mu_i * mu_o));
}

/** E_s(mu, r): the sheen lobe's directional albedo for a white sheen, tabulated in mu (kSheenMu
 *  points in sqrt(mu)) and roughness r (kSheenR points over [0.07, 1]). */
constexpr int kSheenMu = 48, kSheenR = 12;
struct SheenAlbedo {
    float e[kSheenR][kSheenMu];
};

/** The albedo at one (mu, r), by a midpoint rule over wi (cos theta_i in 48 steps, phi in 48):
 *  the lobe is smooth in wi (broad even for r 0.07: sin(theta_h)^204 spans tens of degrees);
 *  within 1% of a 1024 x 1024 rule. More than 1 at grazing views of a fine sheen (5.4 at
 *  mu 0.001, r 0.07: Charlie's lobe with this visibility is not energy-conserving there). */
float sheen_albedo_at(float mu, float r) {
    const float a = r * r;
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu};
    constexpr int kN = 48;
    double sum = 0.0;
    for (int i = 0; i < kN; ++i) {
        const float ci = (static_cast<float>(i) + 0.5f) / kN;
        const float si = std::sqrt(std::max(0.0f, 1.0f - ci * ci));
        for (int j = 0; j < kN; ++j) {
            const float phi = 2.0f * kPi * (static_cast<float>(j) + 0.5f) / kN;
            const V3 wi{si * std::cos(phi), si * std::sin(phi), ci};
            const V3 h = normalize(wo + wi);
            sum += static_cast<double>(charlie_d(h, a) * sheen_v(mu, ci) * ci);
        }
    }
    // d(omega) = d(cos) d(phi): each cell 1/kN x 2 pi/kN.
    return static_cast<float>(sum * (2.0 * M_PI) / (kN * kN));
}

const SheenAlbedo& sheen_albedo() {
    static const SheenAlbedo table = [] {
        SheenAlbedo t{};
        for (int j = 0; j < kSheenR; ++j)
            for (int i = 0; i < kSheenMu; ++i) {
                const float x = static_cast<float>(i) / (kSheenMu - 1);
                const float r = kMinSheenRoughness +
                                (1.0f - kMinSheenRoughness) * static_cast<float>(j) / (kSheenR - 1);
                t.e[j][i] = sheen_albedo_at(std::max(x * x, 1e-4f), r);
            }
        return t;
    }();
    return table;
}

/** E_s at (mu, r), bilinear in (sqrt(mu), r). */
float sheen_albedo_lookup(float mu, float r) {
    const SheenAlbedo& t = sheen_albedo();
    const float x = std::clamp(std::sqrt(std::max(mu, 0.0f)) * (kSheenMu - 1), 0.0f,
                               static_cast<float>(kSheenMu - 1));
    const float y =
        std::clamp((r - kMinSheenRoughness) / (1.0f - kMinSheenRoughness) * (kSheenR - 1), 0.0f,
                   static_cast<float>(kSheenR - 1));
    const int i = std::min(static_cast<int>(x), kSheenMu - 2),
              j = std::min(static_cast<int>(y), kSheenR - 2);
    const float u = x - static_cast<float>(i), v = y - static_cast<float>(j);
    return (t.e[j][i] * (1 - u) + t.e[j][i + 1] * u) * (1 - v) +
           (t.e[j + 1][i] * (1 - u) + t.e[j + 1][i + 1] * u) * v;
}

/** The instance: the parameters' constants. */
struct MetalRough {
    float base[3], metallic, roughness, packed[3], ior, specular, spec_color[3], coat, coat_rough;
    bool multiscatter;
    float sheen[3], sheen_rough;
};

/** One shading point. */
struct Closure {
    V3 wo;            ///< local frame
    float base[3];    ///< base colour
    float f0[3];      ///< dielectric F0 per channel
    float f90;        ///< dielectric F90 (= specular)
    float metallic;   ///< in [0, 1]
    float alpha;      ///< base GGX alpha
    float coat;       ///< clear coat weight
    float alpha_c;    ///< coat GGX alpha
    float e_o[3];     ///< dielectric specular albedo at wo
    float e_avg[3];   ///< its cosine-weighted average
    float e1_o;       ///< GGX albedo for F = 1 at wo (the metal's multiple scattering)
    float e1_avg;     ///< its cosine-weighted average
    float ms[3];      ///< the metal's multiple-scattering colour F_ms (0: single scattering)
    float ec_o;       ///< coat albedo at wo, times `coat`
    float p_diffuse;  ///< probability of sampling the diffuse lobe (and the sheen)
    float p_spec;     ///< the base specular lobe (the coat: the rest)
    float sheen[3];   ///< sheen colour (0: no sheen)
    float sheen_max;  ///< its largest channel
    float sheen_r;    ///< sheen roughness (at least kMinSheenRoughness)
    float es_o;       ///< sheen albedo at wo (white)
};

/** Rec.709 luminance weights (for sampling probabilities only). */
float lum(const float c[3]) {
    return rec709_luminance(c);
}

/** Component c of a numeric parameter as a float. */
float param_f(const SpangleParams_v3* p, const char* name, int c = 0) {
    return static_cast<float>(param_number(p, name, c));
}

/** The instance of a validated parameter set. */
void* create(const SpangleParams_v3* p, const SpangleHost_v3*, char* error, uint32_t cap) {
    auto* m = new (std::nothrow) MetalRough{};
    if (!m) {
        set_error(error, cap, "out of memory");
        return nullptr;
    }
    for (int c = 0; c < 3; ++c) {
        m->base[c] = param_f(p, "base_color", c);
        m->packed[c] = param_f(p, "metallic_roughness", c);
        m->spec_color[c] = param_f(p, "specular_color", c);
    }
    m->metallic = param_f(p, "metallic");
    m->roughness = param_f(p, "roughness");
    m->ior = param_f(p, "ior");
    m->specular = param_f(p, "specular");
    m->coat = param_f(p, "clearcoat");
    m->coat_rough = param_f(p, "clearcoat_roughness");
    m->multiscatter = param_number(p, "multiscatter", 0) != 0.0;
    for (int c = 0; c < 3; ++c) m->sheen[c] = param_f(p, "sheen_color", c);
    m->sheen_rough = param_f(p, "sheen_roughness");
    // A sheen (a texture's is its mean here): the albedo table now, not in a render thread.
    if (std::max({m->sheen[0], m->sheen[1], m->sheen[2]}) > 0.0f) (void)sheen_albedo();
    return m;
}

/** Frees an instance made by create(). */
void destroy(void* instance) {
    delete static_cast<MetalRough*>(instance);
}

/** Parameter k at point i: the texture's value when it is textured, else the constant. */
float at(const SpangleShadingBatch_v3* b, uint32_t k, uint32_t i, float constant, int c = 0,
         int channels = 1) {
    const float* v = b->param_values ? b->param_values[k] : nullptr;
    return v ? v[static_cast<uint32_t>(channels) * i + static_cast<uint32_t>(c)] : constant;
}

/** Per point: the parameters' values, Fresnel terms, albedos at wo, lobe probabilities. */
void prepare(const void* inst, const SpangleShadingBatch_v3* b, void* closures, SpangleArena_v3*) {
    const auto& m = *static_cast<const MetalRough*>(inst);
    const AlbedoTables& t = shipped_albedo_tables();
    auto* out = static_cast<Closure*>(closures);
    const float r0 = (m.ior - 1.0f) / (m.ior + 1.0f);
    for (uint32_t i = 0; i < b->count; ++i) {
        Closure& c = out[i];
        c = Closure{};
        c.wo = {b->wo_x[i], b->wo_y[i], b->wo_z[i]};
        const float specular = at(b, kSpecular, i, m.specular);
        for (int ch = 0; ch < 3; ++ch) {
            c.base[ch] = at(b, kBase, i, m.base[ch], ch, 3);
            const float tint = at(b, kSpecColor, i, m.spec_color[ch], ch, 3);
            c.f0[ch] = std::min(r0 * r0 * tint, 1.0f) * specular;
        }
        c.f90 = specular;
        const float rough =
            at(b, kRoughness, i, m.roughness) * at(b, kPacked, i, m.packed[1], 1, 3);
        c.metallic = std::clamp(
            at(b, kMetallic, i, m.metallic) * at(b, kPacked, i, m.packed[2], 2, 3), 0.0f, 1.0f);
        c.alpha = std::max(rough * rough, kMinAlpha);
        c.coat = at(b, kCoat, i, m.coat);
        const float rc = at(b, kCoatRough, i, m.coat_rough);
        c.alpha_c = std::max(rc * rc, kMinAlpha);
        const float floor = roughness_floor(b, i);  // path regularisation
        c.alpha = std::max(c.alpha, floor);
        c.alpha_c = std::max(c.alpha_c, floor);
        const float mu = std::max(c.wo.z, 0.0f);
        float a, bb;
        albedo_lookup(t, mu, c.alpha, a, bb);
        const float aa = albedo_avg_lookup(t.a_avg, c.alpha),
                    ba = albedo_avg_lookup(t.b_avg, c.alpha);
        float e_metal[3];
        c.e1_o = std::min(a + bb, 1.0f);
        c.e1_avg = std::min(aa + ba, 0.9999f);
        for (int ch = 0; ch < 3; ++ch) {
            c.e_o[ch] = c.f0[ch] * a + c.f90 * bb;
            c.e_avg[ch] = c.f0[ch] * aa + c.f90 * ba;
            e_metal[ch] = c.base[ch] * a + bb;
            // Schlick's F from base_color to 1 averages base + (1 - base) / 21.
            const float f_avg = c.base[ch] + (1.0f - c.base[ch]) / 21.0f;
            c.ms[ch] = m.multiscatter ? ms_colour(f_avg, c.e1_avg) : 0.0f;
        }
        float ac = 0.0f, bc = 0.0f;
        if (c.coat > 0.0f) albedo_lookup(t, mu, c.alpha_c, ac, bc);
        c.ec_o = c.coat * (0.04f * ac + bc);
        for (int ch = 0; ch < 3; ++ch) c.sheen[ch] = at(b, kSheen, i, m.sheen[ch], ch, 3);
        c.sheen_max = std::max({c.sheen[0], c.sheen[1], c.sheen[2]});
        c.sheen_r = std::max(at(b, kSheenRough, i, m.sheen_rough), kMinSheenRoughness);
        c.es_o = c.sheen_max > 0.0f ? sheen_albedo_lookup(mu, c.sheen_r) : 0.0f;
        // The base under the sheen keeps what the sheen leaves (at wo, for the weights).
        const float keep = 1.0f - c.sheen_max * std::min(c.es_o, 1.0f);
        // Lobes in proportion to the energy each returns at wo (a sharp lobe weighed up:
        // sharp_lobe_weight), a tenth of the samples shared equally among the present lobes so
        // that none is starved.
        const float under = 1.0f - c.ec_o;
        // The metal's multiple scattering is sampled with the diffuse lobe (its shape is close
        // to cosine).
        const float ms_o = c.metallic * lum(c.ms) * (1.0f - c.e1_o);
        const float sheen_o = lum(c.sheen) * std::min(c.es_o, 1.0f);
        float w[3] = {
            under *
                (keep * ((1.0f - c.metallic) * lum(c.base) * (1.0f - lum(c.e_o)) + ms_o) + sheen_o),
            under * keep * ((1.0f - c.metallic) * lum(c.e_o) + c.metallic * lum(e_metal)) *
                sharp_lobe_weight(c.alpha),
            c.ec_o * sharp_lobe_weight(c.alpha_c)};
        const bool present[3] = {
            (c.metallic < 1.0f && lum(c.base) > 0.0f) || ms_o > 0.0f || sheen_o > 0.0f, true,
            c.coat > 0.0f};
        float sum = 0.0f;
        int n = 0;
        for (int k = 0; k < 3; ++k) {
            if (!present[k]) w[k] = 0.0f;
            sum += w[k];
            n += present[k] ? 1 : 0;
        }
        for (int k = 0; k < 3; ++k)
            w[k] = present[k] ? 0.9f * (sum > 0.0f ? w[k] / sum : 1.0f / static_cast<float>(n)) +
                                    0.1f / static_cast<float>(n)
                              : 0.0f;
        c.p_diffuse = w[0];
        c.p_spec = w[1];
    }
}

/** f (per channel) and pdf of the whole mixture for wo, wi in the upper hemisphere. */
void evaluate(const Closure& c, V3 wi, float f[3], float& pdf) {
    const AlbedoTables& t = shipped_albedo_tables();
    const V3 wo = c.wo;
    const V3 h = normalize(wo + wi);
    const float x = 1.0f - std::clamp(dot(wo, h), 0.0f, 1.0f), x2 = x * x;
    const float w = x2 * x2 * x;  // Schlick's (1 - v.h)^5 (powf was 4% of a render's time)
    const float d = ggx_d(h, c.alpha, c.alpha);
    const float s = d * ggx_g2(wo, wi, c.alpha, c.alpha) / (4.0f * wo.z * wi.z);
    float a_i, b_i;
    albedo_lookup(t, wi.z, c.alpha, a_i, b_i);
    const float ms = ms_shape(c.e1_o, a_i + b_i, c.e1_avg);
    // The clear coat (none: its terms are 0, and their lookups are skipped).
    float ec_i = 0.0f, coat = 0.0f, coat_pdf = 0.0f;
    if (c.coat > 0.0f) {
        float ac_i, bc_i;
        albedo_lookup(t, wi.z, c.alpha_c, ac_i, bc_i);
        ec_i = c.coat * (0.04f * ac_i + bc_i);
        const float dc = ggx_d(h, c.alpha_c, c.alpha_c);
        const float sc = dc * ggx_g2(wo, wi, c.alpha_c, c.alpha_c) / (4.0f * wo.z * wi.z);
        coat = c.coat * (0.04f + 0.96f * w) * sc;
        coat_pdf = ggx_reflection_pdf(wo, h, c.alpha_c, c.alpha_c);
    }
    const float under = (1.0f - c.ec_o) * (1.0f - ec_i);
    // The sheen layer and what it leaves the base (1 without a sheen).
    float sheen = 0.0f, keep = 1.0f;
    if (c.sheen_max > 0.0f) {
        const float a_s = c.sheen_r * c.sheen_r;
        const float es_i = sheen_albedo_lookup(wi.z, c.sheen_r);
        sheen = charlie_d(h, a_s) * sheen_v(wo.z, wi.z) / std::max({1.0f, c.es_o, es_i});
        keep = std::min(1.0f - c.sheen_max * std::min(c.es_o, 1.0f),
                        1.0f - c.sheen_max * std::min(es_i, 1.0f));
    }
    for (int ch = 0; ch < 3; ++ch) {
        const float fd = c.f0[ch] + (c.f90 - c.f0[ch]) * w;
        const float e_i = c.f0[ch] * a_i + c.f90 * b_i;
        const float diffuse = c.base[ch] * kInvPi * (1.0f - c.e_o[ch]) * (1.0f - e_i) /
                              std::max(1e-6f, 1.0f - c.e_avg[ch]);
        const float fm = c.base[ch] + (1.0f - c.base[ch]) * w;
        const float metal = fm * s + c.ms[ch] * ms;
        const float base = (1.0f - c.metallic) * (fd * s + diffuse) + c.metallic * metal;
        f[ch] = coat + under * (c.sheen[ch] * sheen + keep * base);
    }
    const float p_coat = 1.0f - c.p_diffuse - c.p_spec;
    pdf = c.p_diffuse * wi.z * kInvPi + c.p_spec * ggx_reflection_pdf(wo, h, c.alpha, c.alpha) +
          (p_coat > 0.0f ? p_coat * coat_pdf : 0.0f);
}

/** The closure of query i (closure_index, or i). */
uint32_t closure_of(const uint32_t* index, uint32_t i) {
    return index ? index[i] : i;
}

/** f and pdf of each query (0 for either direction below the surface). */
void eval(const void*, const void* closures, SpangleEvalBatch_v3* q) {
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const V3 wi{q->wi_x[i], q->wi_y[i], q->wi_z[i]};
        float f[3] = {0, 0, 0}, pdf = 0.0f;
        if (c.wo.z > 0.0f && wi.z > 0.0f) evaluate(c, wi, f, pdf);
        const bool ok = std::isfinite(f[0] + f[1] + f[2] + pdf);
        q->f_r[i] = ok ? f[0] : 0.0f;
        q->f_g[i] = ok ? f[1] : 0.0f;
        q->f_b[i] = ok ? f[2] : 0.0f;
        q->pdf[i] = ok ? pdf : 0.0f;
    }
}

/** A lobe by u2, a direction from it (u0, u1), f and pdf of the whole mixture. */
void sample(const void*, const void* closures, SpangleSampleBatch_v3* q) {
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const float u = q->u2[i];
        const bool diffuse = u < c.p_diffuse;
        V3 wi{0, 0, 1};
        if (diffuse) {
            wi = cosine_hemisphere(q->u0[i], q->u1[i]);
        } else {
            // The coat only where there is one (p_coat = 1 - p_diffuse - p_spec may round to a
            // few 1e-8 without a coat, and the pdf has no coat term then).
            const bool spec = u < c.p_diffuse + c.p_spec || !(c.coat > 0.0f);
            const float alpha = spec ? c.alpha : c.alpha_c;
            wi = ggx_sample_reflection(c.wo, alpha, alpha, q->u0[i], q->u1[i]);
        }
        float f[3] = {0, 0, 0}, pdf = 0.0f;
        if (c.wo.z > 0.0f && wi.z > 0.0f) evaluate(c, wi, f, pdf);
        const bool ok = pdf > 0.0f && std::isfinite(f[0] + f[1] + f[2] + pdf + wi.x + wi.y + wi.z);
        q->wi_x[i] = ok ? wi.x : 0.0f;
        q->wi_y[i] = ok ? wi.y : 0.0f;
        q->wi_z[i] = ok ? wi.z : 1.0f;
        q->f_r[i] = ok ? f[0] : 0.0f;
        q->f_g[i] = ok ? f[1] : 0.0f;
        q->f_b[i] = ok ? f[2] : 0.0f;
        q->pdf[i] = ok ? pdf : 0.0f;
        q->flags[i] = ok ? SPANGLE_SAMPLE_REFLECTION |
                               (diffuse ? SPANGLE_SAMPLE_DIFFUSE : SPANGLE_SAMPLE_GLOSSY)
                         : 0u;
        if (q->eta) q->eta[i] = 1.0f;
    }
}

}  // namespace

const SpangleMaterialModel_v3& metal_rough_model() {
    static const SpangleMaterialModel_v3 model = {
        "metal_rough",
        "glTF's metallic-roughness BRDF with ior, specular and clear coat",
        kParams,
        sizeof(kParams) / sizeof(kParams[0]),
        sizeof(Closure),
        create,
        destroy,
        prepare,
        eval,
        sample,
        nullptr,
        smooth_requirements,
    };
    return model;
}

}  // namespace spangle::smooth
