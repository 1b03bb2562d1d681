// The smooth material plugin: diffuse and GGX microfacet models behind the Spangle material ABI.
//
// Models (the schemas below are the authority; `spangle plugins` prints them):
//
//   diffuse     Lambertian reflection.
//     albedo        color  [0.8]        fraction of light reflected
//   conductor   GGX metal with the exact unpolarised Fresnel of a complex index eta + i k.
//     preset        string "gold"       gold|silver|copper|aluminium|perfect|custom
//     eta, k        vec3   [-1]         per-channel complex index (linear Rec.709 bands); only
//                                       with preset = "custom", where both are required
//     roughness     float  0.2          GGX alpha along the tangent; below 1e-4 a mirror
//     roughness_v   float  -1           alpha along the bitangent; -1 = same as roughness
//     multiscatter  bool   true         the light of further bounces between microfacets
//                                       (Kulla and Conty 2017; albedo_tables.h)
//   dielectric  Rough glass: GGX reflection and transmission (Walter et al. 2007).
//     ior, roughness, roughness_v
//     multiscatter  bool   false        both lobes scaled by 1 / E(mu_o), the light of further
//                                       bounces (Turquin 2019; below)
//   metal_rough glTF's metallic-roughness BRDF with ior, specular and clear coat (metal_rough.cpp).
//   plastic     Diffuse base under a GGX dielectric coat; the base sees the light the coat's
//               reflection leaves (Kulla and Conty 2017 energy-preserving layering), so that
//               the white furnace returns exactly 1 for albedo 1 at every angle and roughness.
//     albedo, ior, roughness, roughness_v
//
// Conventions: local shading frame (z = normal), f excludes the cosine, the host orients the
// frame so that wo.z >= 0 on the side the ray came from (SPANGLE_SHADING_BACKFACE tells a
// dielectric it is inside). Invalid samples return f = 0, pdf = 0, flags = 0, never NaN.
// Transmission uses radiance transport (the 1/eta^2 factor), for a path tracer from the camera.

#include <spangle/plugin.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <string>

#include "../common/microfacet.h"
#include "../common/plugin_support.h"
#include "albedo_tables.h"
#include "metal_rough.h"

namespace {

using namespace spangle::mf;
using namespace spangle::plugin_support;

float param_f(const SpangleParams_v3* p, const char* name, int c = 0) {
    return static_cast<float>(param_number(p, name, c));
}

/** GGX alphas from roughness / roughness_v (-1 = isotropic). */
void read_alpha(const SpangleParams_v3* p, float& ax, float& ay) {
    ax = param_f(p, "roughness");
    const float v = param_f(p, "roughness_v");
    ay = v < 0.0f ? ax : v;
}

/** Whether roughness_v is -1 (the same as roughness) or in [0, 1]; else an error (a value in
 *  (-1, 0) was taken as -1 without a word). A textured one is checked where it is read. */
bool roughness_v_ok(const SpangleParams_v3* p, char* error, uint32_t cap) {
    const double v = param_number(p, "roughness_v", 0);
    if (v >= 0.0 || v == -1.0) return true;
    set_error(
        error, cap,
        "roughness_v " + std::to_string(v) + " must be -1 (the same as roughness) or in [0, 1]");
    return false;
}

bool is_delta(float ax, float ay) {
    return std::max(ax, ay) < kDeltaAlpha;
}

/** Clamps alphas away from zero for the rough formulas (the delta case never reaches them). */
void clamp_alpha(float& ax, float& ay) {
    ax = std::max(ax, kDeltaAlpha);
    ay = std::max(ay, kDeltaAlpha);
}

/** Per-shading-point data shared by all models: wo and a few quantities derived from it, and
 *  the point's values of the parameters a texture may vary. */
struct Closure {
    V3 wo;         ///< outgoing direction, local frame
    float eta;     ///< dielectric: relative index across the interface seen from wo
    float rgb[3];  ///< diffuse/plastic albedo
    float p_spec;  ///< plastic: probability of sampling the coat; conductor: of its multiple
                   ///< scattering (0: single scattering)
    float e_o;     ///< plastic: coat albedo at wo; conductor: GGX albedo for F = 1 at wo
    float e_avg;   ///< conductor: its cosine-weighted average
    float ax, ay;  ///< conductor/dielectric: GGX alphas here (clamped away from zero)
    float delta;   ///< conductor/dielectric: 1 where the roughness makes a mirror lobe
    float coat_t;  ///< coated conductor: 1 - w E_c(wo), what the coat lets through at wo
    float p_coat;  ///< coated conductor: probability of sampling the coat
};
static_assert(sizeof(Closure) == 60, "closure layout");

V3 wo_of(const SpangleShadingBatch_v3* b, uint32_t i) {
    return {b->wo_x[i], b->wo_y[i], b->wo_z[i]};
}
uint32_t closure_of(const uint32_t* index, uint32_t i) {
    return index ? index[i] : i;
}

void write_eval(SpangleEvalBatch_v3* q, uint32_t i, float r, float g, float b, float pdf) {
    const bool ok = std::isfinite(r) && std::isfinite(g) && std::isfinite(b) && std::isfinite(pdf);
    q->f_r[i] = ok ? r : 0.0f;
    q->f_g[i] = ok ? g : 0.0f;
    q->f_b[i] = ok ? b : 0.0f;
    q->pdf[i] = ok ? pdf : 0.0f;
}

void write_sample(SpangleSampleBatch_v3* q, uint32_t i, V3 wi, float r, float g, float b, float pdf,
                  uint32_t flags) {
    const bool ok = flags != 0 && pdf > 0.0f && std::isfinite(pdf) && std::isfinite(r) &&
                    std::isfinite(g) && std::isfinite(b) && std::isfinite(wi.x + wi.y + wi.z);
    q->wi_x[i] = ok ? wi.x : 0.0f;
    q->wi_y[i] = ok ? wi.y : 0.0f;
    q->wi_z[i] = ok ? wi.z : 1.0f;
    q->f_r[i] = ok ? r : 0.0f;
    q->f_g[i] = ok ? g : 0.0f;
    q->f_b[i] = ok ? b : 0.0f;
    q->pdf[i] = ok ? pdf : 0.0f;
    q->flags[i] = ok ? flags : 0u;
    if (q->eta) q->eta[i] = 1.0f;
}

void invalid_sample(SpangleSampleBatch_v3* q, uint32_t i) {
    write_sample(q, i, {0, 0, 1}, 0, 0, 0, 0, 0);
}

/** The per-point values of schema parameter k in batch b, or NULL when it is constant. */
const float* varying(const SpangleShadingBatch_v3* b, uint32_t k) {
    return b->param_values ? b->param_values[k] : nullptr;
}

/** The RGB of point i: from a texture when `tex` is given, else the constant. */
void color_at(const float* tex, uint32_t i, const float constant[3], float out[3]) {
    for (int c = 0; c < 3; ++c) out[c] = tex ? tex[3 * i + c] : constant[c];
}

/** Schema indices of roughness and roughness_v in the conductor and dielectric models. */
struct AlphaParams {
    uint32_t roughness, roughness_v;
};

/** The closure's GGX alphas: the model's (clamped) constants ax, ay, delta, or where a
 *  roughness is textured, alphas from point i's values and the other parameter's constant as
 *  written (raw_r, raw_rv: unclamped; raw_rv -1 = the same as roughness); then raised to the
 *  host's path-regularisation floor, where it gives one (a mirror becomes a rough lobe). */
void alpha_at(const SpangleShadingBatch_v3* b, uint32_t i, AlphaParams k, float raw_r, float raw_rv,
              float ax, float ay, bool delta, Closure& c) {
    const float* r = varying(b, k.roughness);
    const float* rv = varying(b, k.roughness_v);
    if (r || rv) {
        ax = r ? r[i] : raw_r;
        const float v = rv ? rv[i] : raw_rv;
        ay = v < 0.0f ? ax : v;
        delta = is_delta(ax, ay);
        clamp_alpha(ax, ay);
    }
    const float floor = roughness_floor(b, i);
    if (floor > 0.0f) {
        ax = std::max(ax, floor);
        ay = std::max(ay, floor);
        delta = delta && is_delta(ax, ay);
    }
    c.ax = ax;
    c.ay = ay;
    c.delta = delta ? 1.0f : 0.0f;
}

// ------------------------------------------------------------------------------------ diffuse

// clang-format off
const SpangleParamDesc_v3 kDiffuseParams[] = {
    {"albedo", SPANGLE_PARAM_COLOR, {0.8, 0.8, 0.8}, nullptr, 0.0, 1.0, nullptr, "fraction of light reflected diffusely (RGB)", SPANGLE_PARAM_TEXTURABLE},
};
// clang-format on

struct Diffuse {
    float albedo[3];
};

void* diffuse_create(const SpangleParams_v3* p, const SpangleHost_v3*, char* error, uint32_t cap) {
    auto* d = new (std::nothrow) Diffuse;
    if (!d) {
        set_error(error, cap, "out of memory");
        return nullptr;
    }
    for (int c = 0; c < 3; ++c) d->albedo[c] = param_f(p, "albedo", c);
    return d;
}

void diffuse_prepare(const void* inst, const SpangleShadingBatch_v3* b, void* closures,
                     SpangleArena_v3*) {
    const auto* d = static_cast<const Diffuse*>(inst);
    auto* out = static_cast<Closure*>(closures);
    const float* albedo = varying(b, 0);
    for (uint32_t i = 0; i < b->count; ++i) {
        out[i] = Closure{};
        out[i].wo = wo_of(b, i);
        color_at(albedo, i, d->albedo, out[i].rgb);
    }
}

void diffuse_eval(const void*, const void* closures, SpangleEvalBatch_v3* q) {
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const float cos_i = q->wi_z[i];
        if (cos_i <= 0.0f || c.wo.z <= 0.0f) {
            write_eval(q, i, 0, 0, 0, 0);
            continue;
        }
        write_eval(q, i, c.rgb[0] * kInvPi, c.rgb[1] * kInvPi, c.rgb[2] * kInvPi, cos_i * kInvPi);
    }
}

void diffuse_sample(const void*, const void* closures, SpangleSampleBatch_v3* q) {
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const V3 wi = cosine_hemisphere(q->u0[i], q->u1[i]);
        if (wi.z <= 0.0f || c.wo.z <= 0.0f) {
            invalid_sample(q, i);
            continue;
        }
        write_sample(q, i, wi, c.rgb[0] * kInvPi, c.rgb[1] * kInvPi, c.rgb[2] * kInvPi,
                     wi.z * kInvPi, SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_DIFFUSE);
    }
}

// ------------------------------------------------------------------------------------ coats

constexpr int kAlbedoTable = 64;  ///< coat albedo E(mu) tabulated at mu = (i + 0.5) / 64

/** A GGX dielectric coat (the plastic's, the coated conductor's) and its directional albedo:
 *  what it reflects of the light arriving at cosine mu, so that what lies under it sees the
 *  rest. */
struct CoatAlbedo {
    float ax = 0, ay = 0, ior = 1.5f;
    bool delta = true;        ///< a smooth (mirror) coat
    float e[kAlbedoTable]{};  ///< directional albedo of the coat's reflection
    float e_avg = 0;          ///< cosine-weighted average of e: 2 int e(mu) mu dmu
    /** Fills the table for alphas (raw, as read) and index. */
    void init(float ax_, float ay_, float ior_);
    /** The coat's GGX roughness for choosing lobes: 0 for a mirror. */
    float alpha() const { return delta ? 0.0f : 0.5f * (ax + ay); }
    /** The coat's reflection albedo at cosine mu (linear in the table). */
    float at(float mu) const {
        const float x =
            std::clamp(mu * kAlbedoTable - 0.5f, 0.0f, static_cast<float>(kAlbedoTable - 1));
        const int i = std::min(static_cast<int>(x), kAlbedoTable - 2);
        const float t = x - static_cast<float>(i);
        return e[i] * (1.0f - t) + e[i + 1] * t;
    }
    /** The rough coat's f (without the weight) and sampling pdf at wo, wi above the surface. */
    void rough(V3 wo, V3 wi, float& f, float& pdf) const {
        const V3 h = normalize(wo + wi);
        const float d = ggx_d(h, ax, ay);
        f = fresnel_dielectric(dot(wo, h), ior) * d * ggx_g2(wo, wi, ax, ay) / (4.0f * wo.z * wi.z);
        pdf = ggx_reflection_pdf(wo, h, ax, ay);
    }
};

/** Coat reflection albedo at cosine mu: int F D G2 / (4 mu) dwi, by VNDF importance sampling over
 *  a Hammersley set, where each sample weighs F G2 / G1. Deterministic and smooth in mu. */
float coat_albedo(const CoatAlbedo& m, float mu) {
    if (m.delta) return fresnel_dielectric(mu, m.ior);
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu};
    constexpr uint32_t kN = 1024;
    double sum = 0.0;
    for (uint32_t i = 0; i < kN; ++i) {
        const V3 h = ggx_sample_visible(wo, m.ax, m.ay, (static_cast<float>(i) + 0.5f) / kN,
                                        radical_inverse2(i));
        const V3 wi = reflect(wo, h);
        if (wi.z <= 0.0f) continue;
        sum += static_cast<double>(fresnel_dielectric(dot(wo, h), m.ior) *
                                   ggx_g2(wo, wi, m.ax, m.ay) / ggx_g1(wo, m.ax, m.ay));
    }
    return static_cast<float>(sum / kN);
}

void CoatAlbedo::init(float ax_, float ay_, float ior_) {
    ax = ax_;
    ay = ay_;
    delta = is_delta(ax, ay);
    clamp_alpha(ax, ay);
    ior = ior_;
    double avg = 0.0;
    for (int i = 0; i < kAlbedoTable; ++i) {
        const float mu = (static_cast<float>(i) + 0.5f) / kAlbedoTable;
        e[i] = std::min(1.0f, coat_albedo(*this, mu));
        avg += 2.0 * static_cast<double>(e[i] * mu) / kAlbedoTable;
    }
    e_avg = static_cast<float>(avg);
}

// ------------------------------------------------------------------------------------ conductor

// clang-format off
const SpangleParamDesc_v3 kConductorParams[] = {
    {"preset", SPANGLE_PARAM_STRING, {0, 0, 0}, "gold", 0.0, 0.0, "gold|silver|copper|aluminium|perfect|custom", "metal whose complex index to use; 'custom' takes eta and k; 'perfect' reflects everything", 0},
    {"eta", SPANGLE_PARAM_VEC3, {-1, -1, -1}, nullptr, -1.0, 100.0, nullptr, "real part of the index per channel (Rec.709 bands); only with preset = custom", 0},
    {"k", SPANGLE_PARAM_VEC3, {-1, -1, -1}, nullptr, -1.0, 100.0, nullptr, "imaginary part (extinction) per channel; only with preset = custom", 0},
    {"roughness", SPANGLE_PARAM_FLOAT, {0.2, 0, 0}, nullptr, 0.0, 1.0, nullptr, "GGX alpha along the tangent; below 1e-4 a perfect mirror", SPANGLE_PARAM_TEXTURABLE},
    {"roughness_v", SPANGLE_PARAM_FLOAT, {-1, 0, 0}, nullptr, -1.0, 1.0, nullptr, "GGX alpha along the bitangent (anisotropy); -1 = same as roughness", SPANGLE_PARAM_TEXTURABLE},
    {"multiscatter", SPANGLE_PARAM_BOOL, {1, 0, 0}, nullptr, 0.0, 1.0, nullptr, "return the light that bounces more than once between the microfacets (Kulla-Conty, as Cycles' Multiscatter GGX); false: single-scattering GGX with height-correlated shadowing (pbrt-v4's; Mitsuba 3's separable shadowing is darker still), darker when rough", 0},
    {"coat", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "weight of a clear dielectric coat over the metal (lacquered metal, pbrt-v4's coatedconductor): 0 none, 1 a full coat", 0},
    {"coat_ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.0, 10.0, nullptr, "index of the coat; the metal's index is taken relative to it", 0},
    {"coat_roughness", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "GGX alpha of the coat; below 1e-4 a smooth coat", 0},
};
// clang-format on

/** The single-scattering albedo E (F = 1) of one anisotropic GGX lobe, against the view's
 *  cosine mu and azimuth phi from the tangent (E(phi) = E(-phi) = E(pi - phi): a quarter turn
 *  holds every view), and its cosine-weighted average over the hemisphere. The isotropic tables
 *  at one alpha for every view cannot stand in: at the mean of the two alphas a white 0.8/0.2
 *  lobe seen along its rough axis returned 1.03 of the light at 80 degrees and 0.83 across it,
 *  and at the alpha of each view's plane of incidence 1.21 and 0.53. */
struct AnisoAlbedo {
    static constexpr int kMu = 32;    ///< mu_i = (i / (kMu - 1))^2, at least 1e-4
    static constexpr int kPhi = 9;    ///< phi_j = j / (kPhi - 1) pi / 2
    static constexpr int kGrid = 32;  ///< visible-normal quadrature, kGrid^2 midpoints
    float e[kPhi][kMu] = {};
    float e_avg = 0.0f;
    /** E at w (bilinear in phi and sqrt(mu)). */
    float at(V3 w) const;
};

float aniso_mu(int i) {
    const float x = static_cast<float>(i) / (AnisoAlbedo::kMu - 1);
    return std::max(1e-4f, x * x);
}

float AnisoAlbedo::at(V3 w) const {
    const float x = std::sqrt(std::clamp(w.z, 0.0f, 1.0f)) * (kMu - 1);
    const int i = std::min(static_cast<int>(x), kMu - 2);
    const float fx = std::min(1.0f, x - static_cast<float>(i));
    const float phi = std::atan2(std::fabs(w.y), std::fabs(w.x));  // (0, 0): 0
    const float y = std::clamp(phi * (2.0f / kPi), 0.0f, 1.0f) * (kPhi - 1);
    const int j = std::min(static_cast<int>(y), kPhi - 2);
    const float fy = std::min(1.0f, y - static_cast<float>(j));
    const float lo = e[j][i] + fx * (e[j][i + 1] - e[j][i]);
    const float hi = e[j + 1][i] + fx * (e[j + 1][i + 1] - e[j + 1][i]);
    return lo + fy * (hi - lo);
}

/** E of the lobe (ax, ay) by quadrature over its visible normals (G2 / G1 of each reflection,
 *  midpoints of a kGrid x kGrid square), and E_avg from the interpolated table (the azimuthal
 *  mean of the interpolant, linear in phi, is the trapezoid rule over the nodes), so that the
 *  compensation lobe returns exactly 1 - E(wo) of what the table says. About 10 ms. */
std::shared_ptr<const AnisoAlbedo> make_aniso_albedo(float ax, float ay) {
    auto t = std::make_shared<AnisoAlbedo>();
    constexpr int g = AnisoAlbedo::kGrid;
    for (int j = 0; j < AnisoAlbedo::kPhi; ++j) {
        const float phi = static_cast<float>(j) / (AnisoAlbedo::kPhi - 1) * (0.5f * kPi);
        for (int i = 0; i < AnisoAlbedo::kMu; ++i) {
            const float mu = aniso_mu(i), s = std::sqrt(std::max(0.0f, 1.0f - mu * mu));
            const V3 wo{s * std::cos(phi), s * std::sin(phi), mu};
            const float g1 = ggx_g1(wo, ax, ay);
            double sum = 0.0;
            for (int a = 0; a < g; ++a)
                for (int b = 0; b < g; ++b) {
                    const V3 h = ggx_sample_visible(wo, ax, ay, (static_cast<float>(a) + 0.5f) / g,
                                                    (static_cast<float>(b) + 0.5f) / g);
                    const V3 wi = reflect(wo, h);
                    if (wi.z > 0.0f && g1 > 0.0f)
                        sum += static_cast<double>(ggx_g2(wo, wi, ax, ay) / g1);
                }
            t->e[j][i] = std::clamp(static_cast<float>(sum / (g * g)), 0.0f, 1.0f);
        }
    }
    constexpr int kM = 512;
    double avg = 0.0;
    for (int j = 0; j < AnisoAlbedo::kPhi; ++j) {
        const float phi = static_cast<float>(j) / (AnisoAlbedo::kPhi - 1) * (0.5f * kPi);
        double row = 0.0;
        for (int k = 0; k < kM; ++k) {
            const float mu = (static_cast<float>(k) + 0.5f) / kM, s = std::sqrt(1.0f - mu * mu);
            row += 2.0 *
                   static_cast<double>(t->at({s * std::cos(phi), s * std::sin(phi), mu}) * mu) / kM;
        }
        const double w = (j == 0 || j == AnisoAlbedo::kPhi - 1) ? 0.5 : 1.0;
        avg += w * row / (AnisoAlbedo::kPhi - 1);
    }
    t->e_avg = static_cast<float>(std::min(avg, 0.9999));
    return t;
}

struct Conductor {
    float ax, ay;
    float raw_r, raw_rv;  ///< roughness, roughness_v as written
    bool delta;
    bool perfect;  ///< F = 1 (white furnace reference)
    float eta[3], k[3];
    float to_working[9];  ///< linear Rec.709 -> working space, row-major
    bool multiscatter;    ///< Kulla-Conty compensation (albedo_tables.h)
    float f_avg[3];       ///< cosine-weighted hemispherical average of the Fresnel term
    /** Multiple scattering of an anisotropic lobe: its own albedo table, for the points at the
     *  material's alphas (a textured roughness elsewhere falls back to the isotropic tables at
     *  the mean alpha); null when isotropic or single-scattering. */
    std::shared_ptr<const AnisoAlbedo> aniso;
    /** A clear coat of weight `coat` (0: none) over the metal: it reflects coat x its GGX
     *  dielectric lobe, and the metal under it is seen through (1 - coat E_c(wo)) (1 - coat
     *  E_c(wi)), E_c the coat's directional albedo (as the plastic's diffuse base is). */
    float coat = 0.0f;
    CoatAlbedo coat_e;
};

/** Reads the Rec.709 -> working-space matrix; reports a failure through the ABI buffer. */
bool rec709_matrix(const SpangleHost_v3* host, float m[9], char* error, uint32_t cap) {
    std::string why;
    if (rec709_to_working(host, m, why)) return true;
    set_error(error, cap, "cannot convert Fresnel colours: " + why);
    return false;
}

/** Fresnel reflectance in the working space for cosine c. */
void conductor_fresnel(const Conductor& m, float c, float out[3]) {
    if (m.perfect) {
        out[0] = out[1] = out[2] = 1.0f;
        return;
    }
    float f[3];
    for (int ch = 0; ch < 3; ++ch) f[ch] = fresnel_conductor(c, m.eta[ch], m.k[ch]);
    for (int r = 0; r < 3; ++r)
        out[r] = std::clamp(m.to_working[3 * r] * f[0] + m.to_working[3 * r + 1] * f[1] +
                                m.to_working[3 * r + 2] * f[2],
                            0.0f, 1.0f);
}

void* conductor_create(const SpangleParams_v3* p, const SpangleHost_v3* host, char* error,
                       uint32_t cap) {
    if (!roughness_v_ok(p, error, cap)) return nullptr;
    Conductor c{};
    read_alpha(p, c.ax, c.ay);
    c.raw_r = param_f(p, "roughness");
    c.raw_rv = param_f(p, "roughness_v");
    c.delta = is_delta(c.ax, c.ay);
    clamp_alpha(c.ax, c.ay);
    const std::string preset = param_string(p, "preset").c_str();
    const bool given = param_f(p, "eta") >= 0.0f || param_f(p, "k") >= 0.0f;
    if (preset == "custom") {
        for (int ch = 0; ch < 3; ++ch) {
            c.eta[ch] = param_f(p, "eta", ch);
            c.k[ch] = param_f(p, "k", ch);
            if (c.eta[ch] <= 0.0f || c.k[ch] < 0.0f) {
                set_error(error, cap, "preset 'custom' needs eta > 0 and k >= 0 in every channel");
                return nullptr;
            }
        }
    } else if (given) {
        set_error(error, cap,
                  "eta and k are only used with preset = \"custom\"; preset '" + preset +
                      "' already defines them");
        return nullptr;
    } else if (preset == "perfect") {
        c.perfect = true;
    } else {
        for (const MetalPreset& m : kMetalPresets)
            if (preset == m.name) {
                std::copy(m.eta, m.eta + 3, c.eta);
                std::copy(m.k, m.k + 3, c.k);
            }
    }
    c.coat = param_f(p, "coat");
    if (c.coat > 0.0f) {
        c.coat_e.init(param_f(p, "coat_roughness"), param_f(p, "coat_roughness"),
                      param_f(p, "coat_ior"));
        // The metal meets the coat, not air: its index relative to the coat's (as pbrt-v4's
        // coatedconductor), blended towards air as the coat thins.
        const float outside = 1.0f + c.coat * (c.coat_e.ior - 1.0f);
        for (int ch = 0; ch < 3; ++ch) {
            c.eta[ch] /= outside;
            c.k[ch] /= outside;
        }
    }
    if (!rec709_matrix(host, c.to_working, error, cap)) return nullptr;
    c.multiscatter = param_number(p, "multiscatter", 0) != 0.0;
    if (c.multiscatter && !c.delta && c.ax != c.ay) c.aniso = make_aniso_albedo(c.ax, c.ay);
    // F_avg = 2 int F(mu) mu dmu by the midpoint rule (F is smooth; 256 points: 1e-5).
    constexpr int kN = 256;
    double sum[3] = {0, 0, 0};
    for (int i = 0; i < kN; ++i) {
        const float mu = (static_cast<float>(i) + 0.5f) / kN;
        float f[3];
        conductor_fresnel(c, mu, f);
        for (int ch = 0; ch < 3; ++ch) sum[ch] += 2.0 * static_cast<double>(f[ch] * mu) / kN;
    }
    for (int ch = 0; ch < 3; ++ch) c.f_avg[ch] = static_cast<float>(sum[ch]);
    auto* out = new (std::nothrow) Conductor(c);
    if (!out) set_error(error, cap, "out of memory");
    return out;
}

/** GGX alpha of the multiple-scattering tables for an anisotropic lobe: the mean of the two
 *  (the geometric mean returned too little of the loss, 0.83 of a white 0.2/0.8 lobe's light
 *  head-on, the root mean square slightly more than all of it, 1.013): the fallback for an
 *  anisotropic roughness that varies over the surface (a texture), which gets back most of its
 *  loss, not all, and may gain a few per cent seen along its rough axis. A material's own
 *  anisotropic alphas use their own table (AnisoAlbedo). */
float ms_alpha(const Closure& c) {
    return 0.5f * (c.ax + c.ay);
}

/** The material's anisotropic albedo table when the point has the material's own alphas. */
const AnisoAlbedo* own_aniso(const Conductor& m, const Closure& c) {
    return m.aniso && c.ax == m.ax && c.ay == m.ay ? m.aniso.get() : nullptr;
}

void conductor_prepare(const void* inst, const SpangleShadingBatch_v3* b, void* closures,
                       SpangleArena_v3*) {
    const auto& m = *static_cast<const Conductor*>(inst);
    auto* out = static_cast<Closure*>(closures);
    for (uint32_t i = 0; i < b->count; ++i) {
        Closure& c = out[i];
        c = Closure{};
        c.wo = wo_of(b, i);
        alpha_at(b, i, {3, 4}, m.raw_r, m.raw_rv, m.ax, m.ay, m.delta, c);
        if (m.multiscatter && c.delta == 0.0f && c.wo.z > 0.0f) {
            if (const AnisoAlbedo* t = own_aniso(m, c)) {
                c.e_o = t->at(c.wo);
                c.e_avg = t->e_avg;
            } else {
                const float alpha = ms_alpha(c);
                c.e_o = spangle::smooth::ggx_albedo(c.wo.z, alpha);
                c.e_avg = spangle::smooth::ggx_albedo_avg(alpha);
            }
            // The share of the light (F = 1) single scattering loses at wo.
            c.p_spec = 1.0f - c.e_o;
        }
        if (m.coat > 0.0f && c.wo.z > 0.0f) {
            const float ec = m.coat * m.coat_e.at(c.wo.z);
            c.coat_t = 1.0f - ec;
            // The coat in proportion to what it reflects against what the metal under it
            // reflects at most (its Fresnel at wo), the sharper weighed up (sharp_lobe_weight),
            // never below 5% for either.
            float f[3];
            conductor_fresnel(m, c.wo.z, f);
            const float coat = ec * sharp_lobe_weight(m.coat_e.alpha());
            const float metal = c.coat_t * rec709_luminance(f) *
                                sharp_lobe_weight(c.delta != 0.0f ? 0.0f : ms_alpha(c));
            c.p_coat = coat + metal > 0.0f ? std::clamp(coat / (coat + metal), 0.05f, 0.95f) : 0.5f;
        }
    }
}

/** f and pdf of the rough conductor for wo, wi above the surface and their half vector h:
 *  single-scattering GGX plus, where the closure has it, the multiple-scattering lobe
 *  (albedo_tables.h), sampled in proportion p_spec by the cosine. */
void conductor_rough(const Conductor& m, const Closure& c, V3 wo, V3 wi, V3 h, float f[3],
                     float& pdf) {
    const float d = ggx_d(h, c.ax, c.ay);
    conductor_fresnel(m, dot(wo, h), f);
    const float s = d * ggx_g2(wo, wi, c.ax, c.ay) / (4.0f * wo.z * wi.z);
    pdf = ggx_reflection_pdf(wo, h, c.ax, c.ay);
    for (int ch = 0; ch < 3; ++ch) f[ch] *= s;
    if (c.p_spec > 0.0f) {
        const AnisoAlbedo* t = own_aniso(m, c);
        const float e_i = t ? t->at(wi) : spangle::smooth::ggx_albedo(wi.z, ms_alpha(c));
        const float shape = spangle::smooth::ms_shape(c.e_o, e_i, c.e_avg);
        for (int ch = 0; ch < 3; ++ch)
            f[ch] += spangle::smooth::ms_colour(m.f_avg[ch], c.e_avg) * shape;
        pdf = (1.0f - c.p_spec) * pdf + c.p_spec * wi.z * kInvPi;
    }
}

/** f and pdf of the coated conductor's lobes that are not mirrors at wi: the rough coat's
 *  reflection (times its weight) and the rough metal seen through the coat at wo and at wi. */
void coated_eval(const Conductor& m, const Closure& c, V3 wo, V3 wi, float f[3], float& pdf) {
    f[0] = f[1] = f[2] = 0.0f;
    pdf = 0.0f;
    if (wo.z <= 0.0f || wi.z <= 0.0f) return;
    if (c.delta == 0.0f) {
        float fm[3], pm;
        conductor_rough(m, c, wo, wi, normalize(wo + wi), fm, pm);
        const float t = c.coat_t * (1.0f - m.coat * m.coat_e.at(wi.z));
        for (int ch = 0; ch < 3; ++ch) f[ch] = t * fm[ch];
        pdf = (1.0f - c.p_coat) * pm;
    }
    if (!m.coat_e.delta) {
        float fc, pc;
        m.coat_e.rough(wo, wi, fc, pc);
        for (int ch = 0; ch < 3; ++ch) f[ch] += m.coat * fc;
        pdf += c.p_coat * pc;
    }
}

void conductor_eval(const void* inst, const void* closures, SpangleEvalBatch_v3* q) {
    const auto& m = *static_cast<const Conductor*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const V3 wo = c.wo;
        const V3 wi{q->wi_x[i], q->wi_y[i], q->wi_z[i]};
        if (m.coat > 0.0f) {
            float f[3], pdf;
            coated_eval(m, c, wo, wi, f, pdf);
            write_eval(q, i, f[0], f[1], f[2], pdf);
            continue;
        }
        if (c.delta > 0.0f || wo.z <= 0.0f || wi.z <= 0.0f) {
            write_eval(q, i, 0, 0, 0, 0);
            continue;
        }
        float f[3], pdf;
        conductor_rough(m, c, wo, wi, normalize(wo + wi), f, pdf);
        write_eval(q, i, f[0], f[1], f[2], pdf);
    }
}

/** Samples the coated conductor for point i of q (wo above the surface): the coat with
 *  probability p_coat, else the metal under it; f and pdf of the whole lobe, a mirror's as a
 *  delta with its probability. */
void coated_sample(const Conductor& m, const Closure& c, SpangleSampleBatch_v3* q, uint32_t i) {
    const V3 wo = c.wo;
    const V3 mirror{-wo.x, -wo.y, wo.z};
    const bool coat_delta = m.coat_e.delta, metal_delta = c.delta > 0.0f;
    float f[3], pdf;
    if (coat_delta && metal_delta) {
        // One mirror: the coat's reflection and the metal's seen through the coat both ways.
        conductor_fresnel(m, wo.z, f);
        const float fc = m.coat * fresnel_dielectric(wo.z, m.coat_e.ior);
        const float t2 = c.coat_t * c.coat_t;
        for (float& x : f) x = (fc + t2 * x) / wo.z;
        write_sample(q, i, mirror, f[0], f[1], f[2], 1.0f,
                     SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_SPECULAR);
        return;
    }
    const float u2 = q->u2[i];
    const bool coat = u2 < c.p_coat;
    if (coat && coat_delta) {
        const float fc = m.coat * fresnel_dielectric(wo.z, m.coat_e.ior) / wo.z;
        write_sample(q, i, mirror, fc, fc, fc, c.p_coat,
                     SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_SPECULAR);
        return;
    }
    if (!coat && metal_delta) {
        conductor_fresnel(m, wo.z, f);
        const float t2 = c.coat_t * c.coat_t / wo.z;
        write_sample(q, i, mirror, f[0] * t2, f[1] * t2, f[2] * t2, 1.0f - c.p_coat,
                     SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_SPECULAR);
        return;
    }
    V3 wi;
    bool diffuse = false;
    if (coat) {
        wi = ggx_sample_reflection(wo, m.coat_e.ax, m.coat_e.ay, q->u0[i], q->u1[i]);
    } else {
        // The metal's own choice (its multiple scattering) by the rest of u2, rescaled.
        const float v = std::min((u2 - c.p_coat) / (1.0f - c.p_coat), 0x1.fffffep-1f);
        diffuse = c.p_spec > 0.0f && v < c.p_spec;
        wi = diffuse ? cosine_hemisphere(q->u0[i], q->u1[i])
                     : ggx_sample_reflection(wo, c.ax, c.ay, q->u0[i], q->u1[i]);
    }
    if (wi.z <= 0.0f) {
        invalid_sample(q, i);
        return;
    }
    coated_eval(m, c, wo, wi, f, pdf);
    write_sample(
        q, i, wi, f[0], f[1], f[2], pdf,
        SPANGLE_SAMPLE_REFLECTION | (diffuse ? SPANGLE_SAMPLE_DIFFUSE : SPANGLE_SAMPLE_GLOSSY));
}

void conductor_sample(const void* inst, const void* closures, SpangleSampleBatch_v3* q) {
    const auto& m = *static_cast<const Conductor*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const V3 wo = c.wo;
        if (wo.z <= 0.0f) {
            invalid_sample(q, i);
            continue;
        }
        if (m.coat > 0.0f) {
            coated_sample(m, c, q, i);
            continue;
        }
        float f[3];
        if (c.delta > 0.0f) {
            conductor_fresnel(m, wo.z, f);
            const float inv = 1.0f / wo.z;  // delta lobe: f and pdf carry the same Dirac factor
            write_sample(q, i, {-wo.x, -wo.y, wo.z}, f[0] * inv, f[1] * inv, f[2] * inv, 1.0f,
                         SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_SPECULAR);
            continue;
        }
        // The multiple-scattering lobe by the cosine, with probability p_spec.
        const bool ms = c.p_spec > 0.0f && q->u2[i] < c.p_spec;
        V3 wi, h;
        if (ms) {
            wi = cosine_hemisphere(q->u0[i], q->u1[i]);
            h = normalize(wo + wi);
        } else {
            wi = ggx_sample_reflection(wo, c.ax, c.ay, q->u0[i], q->u1[i]);
            h = normalize(wo + wi);
        }
        if (wi.z <= 0.0f) {
            invalid_sample(q, i);
            continue;
        }
        float pdf;
        conductor_rough(m, c, wo, wi, h, f, pdf);
        write_sample(
            q, i, wi, f[0], f[1], f[2], pdf,
            SPANGLE_SAMPLE_REFLECTION | (ms ? SPANGLE_SAMPLE_DIFFUSE : SPANGLE_SAMPLE_GLOSSY));
    }
}

// ------------------------------------------------------------------------------------ dielectric

// clang-format off
const SpangleParamDesc_v3 kDielectricParams[] = {
    {"ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.0, 10.0, nullptr, "index of refraction inside (the outside is 1); within 1e-3 of 1 an index-matched interface light passes straight through", 0},
    {"roughness", SPANGLE_PARAM_FLOAT, {0.0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "GGX alpha along the tangent; below 1e-4 a smooth interface", SPANGLE_PARAM_TEXTURABLE},
    {"roughness_v", SPANGLE_PARAM_FLOAT, {-1, 0, 0}, nullptr, -1.0, 1.0, nullptr, "GGX alpha along the bitangent; -1 = same as roughness", SPANGLE_PARAM_TEXTURABLE},
    {"multiscatter", SPANGLE_PARAM_BOOL, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "return the light that bounces more than once between the microfacets (energy compensation, as Cycles' Multiscatter GGX glass; the Blender add-on and the glTF importer set it); false: single-scattering GGX with height-correlated shadowing (pbrt-v4's; Mitsuba 3's separable shadowing is darker still), darker when rough", 0},
    {"transmission_color", SPANGLE_PARAM_COLOR, {1, 1, 1}, nullptr, 0.0, 1.0, nullptr, "colour of the light that passes through a closed object (coloured glass: glTF's transmission and Blender's Principled BSDF take the base colour): each crossing of the surface tints by its square root, as Cycles does; the reflection stays white", SPANGLE_PARAM_TEXTURABLE},
};
// clang-format on
constexpr uint32_t kDielectricTint = 4;  ///< transmission_color's schema index

// Multiple scattering of rough glass (Turquin 2019, "Practical multiple scattering compensation
// for microfacet models"; Cycles' Multiscatter GGX glass does the same): single-scattering GGX
// reflection and transmission together lose 1 - E(mu_o) of the energy that reaches the surface
// from wo, E the single-scattering albedo of both lobes (transmission counted as energy, without
// radiance transport's 1/eta^2). Both lobes are scaled by 1 / E(mu_o): the white furnace returns
// everything from either side, and the split between reflection and transmission is single
// scattering's. E depends on the index, so each index gets its own table, made once per process.

/** Cosines mu = (i / 31)^2 (the first at 1e-4): dense at grazing, where E falls fast under a
 *  smooth interface of a high index (inside, near total internal reflection), and reaching
 *  head-on, where E of rough glass seen from inside still changes. */
constexpr int kGlassMu = 32;
constexpr int kGlassRough = 16;  ///< sqrt(alpha) = j / 15

/** E of one index, from outside (eta = ior) and from inside (eta = 1 / ior). */
struct GlassAlbedo {
    float e[2][kGlassRough][kGlassMu];
};

/** E at (mu, alpha) from the side whose relative index is eta: over a Hammersley set of visible
 *  normals h, each weighs F G2(wo, reflected) / G1 + (1 - F) G2(wo, refracted) / G1, so that the
 *  choice between the lobes is not sampled. */
float glass_albedo(float mu, float alpha, float eta) {
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu};
    constexpr uint32_t kN = 256;
    const float g1 = ggx_g1(wo, alpha, alpha);
    double sum = 0.0;
    for (uint32_t k = 0; k < kN; ++k) {
        const V3 h = ggx_sample_visible(wo, alpha, alpha, (static_cast<float>(k) + 0.5f) / kN,
                                        radical_inverse2(k));
        const float R = fresnel_dielectric(dot(wo, h), eta);
        const V3 wr = reflect(wo, h);
        if (wr.z > 0.0f) sum += static_cast<double>(R * ggx_g2(wo, wr, alpha, alpha) / g1);
        V3 wt;
        if (R < 1.0f && refract(wo, h, eta, wt) && wt.z < 0.0f)
            sum += static_cast<double>((1.0f - R) * ggx_g2(wo, wt, alpha, alpha) / g1);
    }
    return static_cast<float>(std::min(1.0, sum / kN));
}

/** The table of an index, shared by every material of that index in the process. */
std::shared_ptr<const GlassAlbedo> glass_albedo_table(float ior) {
    static std::mutex mutex;
    static std::map<float, std::weak_ptr<const GlassAlbedo>> made;
    std::lock_guard<std::mutex> lock(mutex);
    if (auto hit = made[ior].lock()) return hit;
    auto t = std::make_shared<GlassAlbedo>();
    for (int side = 0; side < 2; ++side)
        for (int j = 0; j < kGlassRough; ++j) {
            const float r = static_cast<float>(j) / (kGlassRough - 1);
            const float alpha = std::max(r * r, kDeltaAlpha);
            for (int i = 0; i < kGlassMu; ++i) {
                const float s = static_cast<float>(i) / (kGlassMu - 1);
                t->e[side][j][i] =
                    glass_albedo(std::max(s * s, 1e-4f), alpha, side == 0 ? ior : 1.0f / ior);
            }
        }
    made[ior] = t;
    return t;
}

/** Bilinear lookup of E from one side at (mu, alpha). */
float glass_albedo_at(const GlassAlbedo& t, int side, float mu, float alpha) {
    const float x = std::clamp(std::sqrt(std::max(mu, 0.0f)) * (kGlassMu - 1), 0.0f,
                               static_cast<float>(kGlassMu - 1));
    const float y =
        std::clamp(std::sqrt(alpha) * (kGlassRough - 1), 0.0f, static_cast<float>(kGlassRough - 1));
    const int i = std::min(static_cast<int>(x), kGlassMu - 2),
              j = std::min(static_cast<int>(y), kGlassRough - 2);
    const float s = x - static_cast<float>(i), u = y - static_cast<float>(j);
    const auto& e = t.e[side];
    return (e[j][i] * (1 - s) + e[j][i + 1] * s) * (1 - u) +
           (e[j + 1][i] * (1 - s) + e[j + 1][i + 1] * s) * u;
}

struct Dielectric {
    float ax, ay, ior;
    float tint[3];        ///< transmission_color
    float raw_r, raw_rv;  ///< roughness, roughness_v as written
    bool delta;
    /** ior within 1e-3 of 1: an index-matched interface. Light passes straight through (a delta
     *  transmission, rough or not: the half vector of refraction, wi eta + wo, vanishes). */
    bool matched;
    /** The single-scattering albedo of this index (null without multiple scattering). */
    std::shared_ptr<const GlassAlbedo> albedo;
};

void* dielectric_create(const SpangleParams_v3* p, const SpangleHost_v3*, char* error,
                        uint32_t cap) {
    if (!roughness_v_ok(p, error, cap)) return nullptr;
    Dielectric d{};
    read_alpha(p, d.ax, d.ay);
    d.raw_r = param_f(p, "roughness");
    d.raw_rv = param_f(p, "roughness_v");
    d.delta = is_delta(d.ax, d.ay);
    clamp_alpha(d.ax, d.ay);
    d.ior = param_f(p, "ior");
    for (int c = 0; c < 3; ++c) d.tint[c] = param_f(p, "transmission_color", c);
    d.matched = d.ior < 1.001f;
    // A smooth interface loses nothing (unless textured rough: the table is made then too).
    if (param_number(p, "multiscatter", 0) != 0.0 && !d.matched)
        d.albedo = glass_albedo_table(d.ior);
    auto* out = new (std::nothrow) Dielectric(d);
    if (!out) set_error(error, cap, "out of memory");
    return out;
}

void dielectric_prepare(const void* inst, const SpangleShadingBatch_v3* b, void* closures,
                        SpangleArena_v3*) {
    const auto& m = *static_cast<const Dielectric*>(inst);
    auto* out = static_cast<Closure*>(closures);
    const float* tint = varying(b, kDielectricTint);
    for (uint32_t i = 0; i < b->count; ++i) {
        out[i] = Closure{};
        out[i].wo = wo_of(b, i);
        // Each crossing tints by the square root: a closed object (two crossings) by the colour.
        color_at(tint, i, m.tint, out[i].rgb);
        for (float& k : out[i].rgb) k = std::sqrt(std::max(k, 0.0f));
        // The host turned the frame towards wo: from the back side, wo is inside the glass.
        const bool inside = (b->flags[i] & SPANGLE_SHADING_BACKFACE) != 0;
        out[i].eta = inside ? 1.0f / m.ior : m.ior;
        alpha_at(b, i, {1, 2}, m.raw_r, m.raw_rv, m.ax, m.ay, m.delta, out[i]);
        // e_o: the scale of both lobes, 1 / E(mu_o) with multiple scattering, else 1.
        out[i].e_o = 1.0f;
        if (m.albedo && out[i].delta == 0.0f && out[i].wo.z > 0.0f) {
            const float e =
                glass_albedo_at(*m.albedo, inside ? 1 : 0, out[i].wo.z, ms_alpha(out[i]));
            if (e > 0.0f) out[i].e_o = 1.0f / e;
        }
    }
}

constexpr float kWhite[3] = {1.0f, 1.0f, 1.0f};  ///< the reflection's (untinted) colour

/** f and pdf of the rough dielectric for wo.z > 0 (pbrt-v4's formulation of Walter et al.). */
void dielectric_rough(const Closure& c, V3 wo, V3 wi, float eta, float& f, float& pdf) {
    f = pdf = 0.0f;
    const bool reflect_ = wi.z > 0.0f;
    const float etap = reflect_ ? 1.0f : eta;
    V3 h = normalize(wi * etap + wo);
    if (h.z < 0.0f) h = h * -1.0f;
    if (wi.z == 0.0f || dot(h, wi) * wi.z < 0.0f || dot(h, wo) * wo.z < 0.0f) return;
    const float R = fresnel_dielectric(dot(wo, h), eta), T = 1.0f - R;
    const float d = ggx_d(h, c.ax, c.ay);
    const float g = ggx_g2(wo, wi, c.ax, c.ay);
    const float vis = ggx_visible_d(wo, h, c.ax, c.ay);
    if (reflect_) {
        f = d * g * R / (4.0f * wo.z * wi.z);
        pdf = vis / (4.0f * std::fabs(dot(wo, h))) * R;
    } else {
        const float denom = (dot(wi, h) + dot(wo, h) / eta) * (dot(wi, h) + dot(wo, h) / eta);
        if (!(denom > 0.0f)) return;
        const float dwh_dwi = std::fabs(dot(wi, h)) / denom;
        f = T * d * g * std::fabs(dot(wi, h) * dot(wo, h) / (wi.z * wo.z * denom)) / (eta * eta);
        pdf = vis * dwh_dwi * T;
    }
}

void dielectric_eval(const void* inst, const void* closures, SpangleEvalBatch_v3* q) {
    const auto& m = *static_cast<const Dielectric*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        if (c.delta > 0.0f || m.matched || c.wo.z <= 0.0f) {
            write_eval(q, i, 0, 0, 0, 0);
            continue;
        }
        float f, pdf;
        dielectric_rough(c, c.wo, {q->wi_x[i], q->wi_y[i], q->wi_z[i]}, c.eta, f, pdf);
        f *= c.e_o;
        if (q->wi_z[i] < 0.0f)
            write_eval(q, i, f * c.rgb[0], f * c.rgb[1], f * c.rgb[2], pdf);
        else
            write_eval(q, i, f, f, f, pdf);
    }
}

void dielectric_sample(const void* inst, const void* closures, SpangleSampleBatch_v3* q) {
    const auto& m = *static_cast<const Dielectric*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const V3 wo = c.wo;
        if (wo.z <= 0.0f) {
            invalid_sample(q, i);
            continue;
        }
        if (m.matched) {
            const V3 wi = wo * -1.0f;
            const float f = 1.0f / wo.z;
            write_sample(q, i, wi, f * c.rgb[0], f * c.rgb[1], f * c.rgb[2], 1.0f,
                         SPANGLE_SAMPLE_TRANSMISSION | SPANGLE_SAMPLE_SPECULAR);
            if (q->eta) q->eta[i] = c.eta;
            continue;
        }
        const V3 h =
            c.delta > 0.0f ? V3{0, 0, 1} : ggx_sample_visible(wo, c.ax, c.ay, q->u0[i], q->u1[i]);
        const float R = fresnel_dielectric(dot(wo, h), c.eta), T = 1.0f - R;
        V3 wi;
        const bool reflect_ = q->u2[i] < R;
        if (reflect_) {
            wi = reflect(wo, h);
        } else if (!refract(wo, h, c.eta, wi)) {
            invalid_sample(q, i);  // unreachable in exact arithmetic: TIR means R = 1
            continue;
        }
        const uint32_t lobe = reflect_ ? SPANGLE_SAMPLE_REFLECTION : SPANGLE_SAMPLE_TRANSMISSION;
        if (c.delta > 0.0f) {
            const float cos_i = std::fabs(wi.z);
            const float f = reflect_ ? R / cos_i : T / (cos_i * c.eta * c.eta);
            const float* k = reflect_ ? kWhite : c.rgb;
            write_sample(q, i, wi, f * k[0], f * k[1], f * k[2], reflect_ ? R : T,
                         lobe | SPANGLE_SAMPLE_SPECULAR);
            if (q->eta && !reflect_) q->eta[i] = c.eta;
            continue;
        }
        if (reflect_ ? wi.z <= 0.0f : wi.z >= 0.0f) {
            invalid_sample(q, i);
            continue;
        }
        float f, pdf;
        dielectric_rough(c, wo, wi, c.eta, f, pdf);
        f *= c.e_o;
        const float* k = reflect_ ? kWhite : c.rgb;
        write_sample(q, i, wi, f * k[0], f * k[1], f * k[2], pdf, lobe | SPANGLE_SAMPLE_GLOSSY);
        if (q->eta && !reflect_) q->eta[i] = c.eta;
    }
}

// ------------------------------------------------------------------------------------ plastic

// clang-format off
const SpangleParamDesc_v3 kPlasticParams[] = {
    {"albedo", SPANGLE_PARAM_COLOR, {0.8, 0.8, 0.8}, nullptr, 0.0, 1.0, nullptr, "diffuse colour of the base under the coat", SPANGLE_PARAM_TEXTURABLE},
    {"ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.0, 10.0, nullptr, "index of the coat", 0},
    {"roughness", SPANGLE_PARAM_FLOAT, {0.1, 0, 0}, nullptr, 0.0, 1.0, nullptr, "GGX alpha of the coat along the tangent; below 1e-4 a smooth coat", 0},
    {"roughness_v", SPANGLE_PARAM_FLOAT, {-1, 0, 0}, nullptr, -1.0, 1.0, nullptr, "GGX alpha of the coat along the bitangent; -1 = same as roughness", 0},
};
// clang-format on

struct Plastic {
    CoatAlbedo coat;  ///< the coat: its alphas, index and albedo table
    float albedo[3];
};

float plastic_e(const Plastic& m, float mu) {
    return m.coat.at(mu);
}

void* plastic_create(const SpangleParams_v3* p, const SpangleHost_v3*, char* error, uint32_t cap) {
    if (!roughness_v_ok(p, error, cap)) return nullptr;
    auto* m = new (std::nothrow) Plastic{};
    if (!m) {
        set_error(error, cap, "out of memory");
        return nullptr;
    }
    float ax, ay;
    read_alpha(p, ax, ay);
    m->coat.init(ax, ay, param_f(p, "ior"));
    for (int c = 0; c < 3; ++c) m->albedo[c] = param_f(p, "albedo", c);
    return m;
}

void plastic_prepare(const void* inst, const SpangleShadingBatch_v3* b, void* closures,
                     SpangleArena_v3*) {
    const auto& m = *static_cast<const Plastic*>(inst);
    auto* out = static_cast<Closure*>(closures);
    const float* albedo = varying(b, 0);
    for (uint32_t i = 0; i < b->count; ++i) {
        Closure& c = out[i];
        c = Closure{};
        c.wo = wo_of(b, i);
        color_at(albedo, i, m.albedo, c.rgb);
        const float lum = rec709_luminance(c.rgb);
        c.e_o = plastic_e(m, std::max(c.wo.z, 0.0f));
        const float diffuse = lum * (1.0f - c.e_o);
        // Sample the coat in proportion to the energy it reflects, a sharp coat weighed up
        // (sharp_lobe_weight); never less than 10% of the time so that a dark base does not
        // starve the diffuse lobe of samples.
        const float coat = c.e_o * sharp_lobe_weight(m.coat.alpha());
        c.p_spec = coat + diffuse > 0.0f ? std::clamp(coat / (coat + diffuse), 0.1f, 0.9f) : 0.5f;
    }
}

/** The base's reflectance factor (1 - E(o)) (1 - E(i)) / (pi (1 - E_avg)), without albedo. */
float plastic_base(const Plastic& m, const Closure& c, float cos_i) {
    return (1.0f - c.e_o) * (1.0f - plastic_e(m, cos_i)) /
           (kPi * std::max(1e-6f, 1.0f - m.coat.e_avg));
}

void plastic_eval(const void* inst, const void* closures, SpangleEvalBatch_v3* q) {
    const auto& m = *static_cast<const Plastic*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const V3 wo = c.wo, wi{q->wi_x[i], q->wi_y[i], q->wi_z[i]};
        if (wo.z <= 0.0f || wi.z <= 0.0f) {
            write_eval(q, i, 0, 0, 0, 0);
            continue;
        }
        const float base = plastic_base(m, c, wi.z);
        float spec = 0.0f, spec_pdf = 0.0f;
        if (!m.coat.delta) m.coat.rough(wo, wi, spec, spec_pdf);
        const float pdf = c.p_spec * spec_pdf + (1.0f - c.p_spec) * wi.z * kInvPi;
        write_eval(q, i, spec + c.rgb[0] * base, spec + c.rgb[1] * base, spec + c.rgb[2] * base,
                   pdf);
    }
}

void plastic_sample(const void* inst, const void* closures, SpangleSampleBatch_v3* q) {
    const auto& m = *static_cast<const Plastic*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[closure_of(q->closure_index, i)];
        const V3 wo = c.wo;
        if (wo.z <= 0.0f) {
            invalid_sample(q, i);
            continue;
        }
        const bool coat = q->u2[i] < c.p_spec;
        if (coat && m.coat.delta) {
            const float fr = fresnel_dielectric(wo.z, m.coat.ior);
            const float f = fr / wo.z;
            write_sample(q, i, {-wo.x, -wo.y, wo.z}, f, f, f, c.p_spec,
                         SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_SPECULAR);
            continue;
        }
        const V3 wi = coat ? ggx_sample_reflection(wo, m.coat.ax, m.coat.ay, q->u0[i], q->u1[i])
                           : cosine_hemisphere(q->u0[i], q->u1[i]);
        if (wi.z <= 0.0f) {
            invalid_sample(q, i);
            continue;
        }
        // f and pdf of the whole mixture, so that MIS sees one consistent density.
        SpangleEvalBatch_v3 e{};
        float fr, fg, fb, pdf;
        const uint32_t index = closure_of(q->closure_index, i);
        e.count = 1;
        e.closure_index = &index;
        e.wi_x = &wi.x;
        e.wi_y = &wi.y;
        e.wi_z = &wi.z;
        e.f_r = &fr;
        e.f_g = &fg;
        e.f_b = &fb;
        e.pdf = &pdf;
        plastic_eval(inst, closures, &e);
        write_sample(
            q, i, wi, fr, fg, fb, pdf,
            SPANGLE_SAMPLE_REFLECTION | (coat ? SPANGLE_SAMPLE_GLOSSY : SPANGLE_SAMPLE_DIFFUSE));
    }
}

// ------------------------------------------------------------------------------------ the table

template <class T>
void destroy(void* instance) {
    delete static_cast<T*>(instance);
}

constexpr uint32_t count_of(const SpangleParamDesc_v3* begin, const SpangleParamDesc_v3* end) {
    return static_cast<uint32_t>(end - begin);
}
#define SPANGLE_PARAMS(a) a, count_of(a, a + sizeof(a) / sizeof(a[0]))

const SpangleMaterialModel_v3 kModels[] = {
    {"diffuse", "Lambertian diffuse reflection", SPANGLE_PARAMS(kDiffuseParams), sizeof(Closure),
     diffuse_create, destroy<Diffuse>, diffuse_prepare, diffuse_eval, diffuse_sample, nullptr,
     spangle::smooth::smooth_requirements},
    {"conductor", "GGX metal with complex Fresnel (presets or custom eta, k)",
     SPANGLE_PARAMS(kConductorParams), sizeof(Closure), conductor_create, destroy<Conductor>,
     conductor_prepare, conductor_eval, conductor_sample, nullptr,
     spangle::smooth::smooth_requirements},
    {"dielectric", "rough glass: GGX reflection and transmission",
     SPANGLE_PARAMS(kDielectricParams), sizeof(Closure), dielectric_create, destroy<Dielectric>,
     dielectric_prepare, dielectric_eval, dielectric_sample, nullptr,
     spangle::smooth::smooth_requirements},
    {"plastic", "diffuse base under a GGX dielectric coat", SPANGLE_PARAMS(kPlasticParams),
     sizeof(Closure), plastic_create, destroy<Plastic>, plastic_prepare, plastic_eval,
     plastic_sample, nullptr, spangle::smooth::smooth_requirements},
    spangle::smooth::metal_rough_model(),
};

const SpangleMaterialPlugin_v3 kPlugin = {
    SPANGLE_MATERIAL_ABI_VERSION,
    sizeof(SpangleMaterialPlugin_v3),
    "smooth",
    "smooth microfacet and diffuse materials",
    kModels,
    sizeof(kModels) / sizeof(kModels[0]),
};

}  // namespace

extern "C" SPANGLE_PLUGIN_EXPORT const SpangleMaterialPlugin_v3* spangle_material_plugin(
    uint32_t host_abi_version) {
    return host_abi_version == SPANGLE_MATERIAL_ABI_VERSION ? &kPlugin : nullptr;
}
