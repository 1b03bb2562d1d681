// The flake material plugin: base + stochastic mirror flakes + optional clear coat
// (../shared/FLAKES.md). Model "flake"; every parameter is in kParams below with its range and
// one-line doc, and `spangle plugins` prints them.
//
// Per shading point, prepare() decides from the expected flake count lambda (density x footprint
// area) between the discrete lobe (lambda <= min_flakes), the smooth lobe that is its expectation
// (lambda >= max_flakes, or no ray differentials), or a blend with weight smoothstep(log lambda).
// The discrete lobe's reflection cache lives in the host's per-batch arena.
//
// Whole material (directions in the local frame, no bending by the coat - a thin-coat model):
//   f = f_coat + (1 - E_c(o)) (1 - E_c(i)) [(1 - flake_weight) base / pi + flake_weight f_flakes]
// with E_c the coat's reflection albedo (Kulla and Conty 2017 layering), so energy <= 1 for every
// setting. The discrete lobe is not reciprocal (its cache is built around wo); a path tracer from
// the camera does not need reciprocity.

#include <spangle/plugin.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <new>
#include <numeric>
#include <string>
#include <vector>

#include "../common/plugin_support.h"
#include "flake_model.h"

namespace {

using namespace spangle;
using namespace spangle::flake;
using namespace spangle::plugin_support;
using mf::kInvPi;
using mf::kPi;

// clang-format off
const SpangleParamDesc_v1 kParams[] = {
    {"base_color", SPANGLE_PARAM_COLOR, {0.05, 0.05, 0.05}, nullptr, 0.0, 1.0, nullptr, "diffuse colour of the paint between the flakes"},
    {"flake_weight", SPANGLE_PARAM_FLOAT, {0.6, 0, 0}, nullptr, 0.0, 1.0, nullptr, "fraction of the surface covered by flakes"},
    {"density", SPANGLE_PARAM_FLOAT, {200000, 0, 0}, nullptr, 1.0, 2147483647.0, nullptr, "flakes per unit square of uv (per square metre with density_space = world)"},
    {"density_space", SPANGLE_PARAM_STRING, {0, 0, 0}, "uv", 0, 0, "uv|world", "whether density counts per uv unit square or per square metre of surface"},
    {"flake_roughness", SPANGLE_PARAM_FLOAT, {0.15, 0, 0}, nullptr, 0.001, 1.0, nullptr, "GGX alpha of the distribution of flake normals around the shading normal"},
    {"gamma", SPANGLE_PARAM_FLOAT, {3.0, 0, 0}, nullptr, 0.01, 45.0, nullptr, "half-angle in degrees of the cone each flake reflects into (larger: more, dimmer glints)"},
    {"footprint_scale", SPANGLE_PARAM_FLOAT, {1.0, 0, 0}, nullptr, 0.01, 100.0, nullptr, "size of the flake footprint in pixels"},
    {"leaf_size", SPANGLE_PARAM_INT, {16, 0, 0}, nullptr, 1.0, 1024.0, nullptr, "quad-tree nodes with at most this many flakes are leaves"},
    {"max_depth", SPANGLE_PARAM_INT, {12, 0, 0}, nullptr, 10.0, 24.0, nullptr, "deepest quad-tree level (V-Ray's tex_subdivs)"},
    {"binomial_exact_below", SPANGLE_PARAM_INT, {128, 0, 0}, nullptr, 0.0, 1000.0, nullptr, "splits of fewer flakes than this are sampled exactly, larger ones by the normal approximation"},
    {"min_flakes", SPANGLE_PARAM_FLOAT, {500, 0, 0}, nullptr, 0.0, 1e7, nullptr, "expected flake count below which only the discrete lobe is used"},
    {"max_flakes", SPANGLE_PARAM_FLOAT, {2000, 0, 0}, nullptr, 1.0, 1e7, nullptr, "expected flake count above which only the smooth lobe is used (bounds enumeration)"},
    {"fresnel", SPANGLE_PARAM_STRING, {0, 0, 0}, "conductor", 0, 0, "conductor|dielectric|schlick", "Fresnel of a flake: a metal (preset), a dielectric (flake_ior) or Schlick (flake_f0)"},
    {"preset", SPANGLE_PARAM_STRING, {0, 0, 0}, "aluminium", 0, 0, "gold|silver|copper|aluminium|perfect", "metal of conductor flakes"},
    {"flake_ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.01, 4.0, nullptr, "index of dielectric flakes"},
    {"flake_f0", SPANGLE_PARAM_FLOAT, {0.9, 0, 0}, nullptr, 0.0, 1.0, nullptr, "normal-incidence reflectance of Schlick flakes"},
    {"flake_color", SPANGLE_PARAM_COLOR, {1.0, 1.0, 1.0}, nullptr, 0.0, 1.0, nullptr, "tint of every flake when the colour table is off"},
    {"shadowing", SPANGLE_PARAM_BOOL, {1, 0, 0}, nullptr, 0, 1, nullptr, "apply Smith shadowing G1(wi) of the flake distribution"},
    {"color_table", SPANGLE_PARAM_BOOL, {0, 0, 0}, nullptr, 0, 1, nullptr, "give flakes colours from an HSL hue table instead of flake_color"},
    {"table_size", SPANGLE_PARAM_INT, {60, 0, 0}, nullptr, 1.0, 360.0, nullptr, "number of hues in the colour table"},
    {"table_s", SPANGLE_PARAM_FLOAT, {1.0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "HSL saturation of the table"},
    {"table_l", SPANGLE_PARAM_FLOAT, {0.5, 0, 0}, nullptr, 0.0, 1.0, nullptr, "HSL lightness of the table"},
    {"table_space", SPANGLE_PARAM_STRING, {0, 0, 0}, "srgb_texture", 0, 0, nullptr, "colour space the HSL table is defined in (any name of the OCIO config)"},
    {"hue_spread", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 360.0, nullptr, "degrees: flake hues are biased towards base_color's hue with this spread; 0 = uniform"},
    {"coat", SPANGLE_PARAM_BOOL, {0, 0, 0}, nullptr, 0, 1, nullptr, "add a clear coat on top"},
    {"coat_ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.01, 4.0, nullptr, "index of the clear coat"},
    {"coat_roughness", SPANGLE_PARAM_FLOAT, {0.0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "GGX alpha of the clear coat; below 1e-4 a smooth coat"},
    {"seed", SPANGLE_PARAM_INT, {0, 0, 0}, nullptr, 0.0, 2147483647.0, nullptr, "which realisation of flakes: change it for a different but equivalent pattern"},
};
// clang-format on
constexpr uint32_t kParamCount = sizeof(kParams) / sizeof(kParams[0]);

constexpr int kTable = 64;     ///< entries of the tables in cos(theta)
constexpr int kFresnel = 256;  ///< entries of the Fresnel table in cos(theta)

float lerp_table(const float* t, int n, float x01) {
    const float x = std::clamp(x01 * static_cast<float>(n) - 0.5f, 0.0f, static_cast<float>(n - 1));
    const int i = std::min(static_cast<int>(x), n - 2);
    const float f = x - static_cast<float>(i);
    return t[i] * (1.0f - f) + t[i + 1] * f;
}

float luminance(const float c[3]) {
    return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

/** A created material: parameters and every table derived from them. Read-only after create(),
 *  except the statistics counters. */
struct Material {
    FieldParams field;
    bool world_density = false;
    float density = 0;
    float alpha = 0.15f;
    Cone cone;
    float footprint_scale = 1;
    double min_flakes = 500, max_flakes = 2000;
    uint32_t enumerate_cap = 0;  ///< hard bound on flakes visited per shading point
    float base[3] = {0, 0, 0};
    float flake_weight = 0.6f;
    bool shadowing = true;
    float fresnel[kFresnel][3];      ///< flake Fresnel in the working space vs cos(theta)
    std::vector<float> table_rgb;    ///< colour table, working space (3 per entry)
    std::vector<float> table_cdf;    ///< cumulative probabilities of the entries
    float flake_rgb[3] = {1, 1, 1};  ///< colour when the table is off
    float mean_rgb[3] = {1, 1, 1};   ///< expected flake colour (for the smooth lobe)
    float p_valid[kTable];  ///< share of flake normals whose mirror direction is above the horizon
    bool coat = false, coat_delta = true;
    float coat_ior = 1.5f, coat_alpha = 0.0f;
    float coat_e[kTable];  ///< coat reflection albedo vs cos(theta)
    float coat_e_avg = 0.0f;

    // Statistics for --stats (relaxed atomics: summed per batch).
    mutable std::atomic<uint64_t> points{0}, discrete{0}, blended{0}, smooth{0}, truncated{0};
    mutable std::atomic<uint64_t> flakes_sum{0}, lambda_milli_sum{0}, lambda_count{0};
    mutable std::atomic<uint64_t> ns_prepare{0}, ns_eval{0}, ns_sample{0};
};

/** Per-shading-point closure. */
struct Closure {
    V3 wo;
    float t = 1.0f;                             ///< weight of the smooth flake lobe
    DiscreteLobe lobe;                          ///< the cache (count 0 when unused)
    float p_coat = 0, p_base = 0, p_flake = 0;  ///< lobe selection probabilities
    float e_coat_o = 0;                         ///< coat albedo at wo
    float g1_wo = 1;                            ///< G1 of the flake distribution at wo
    float pvalid_o = 1;                         ///< p_valid at wo
    uint32_t valid = 0;                         ///< wo above the surface
};

/** HSL (h in degrees) to RGB in the same space. */
void hsl_to_rgb(float h, float s, float l, float rgb[3]) {
    const float c = (1.0f - std::fabs(2.0f * l - 1.0f)) * s;
    const float hp = std::fmod(h, 360.0f) / 60.0f;
    const float x = c * (1.0f - std::fabs(std::fmod(hp, 2.0f) - 1.0f));
    float r = 0, g = 0, b = 0;
    if (hp < 1)
        r = c, g = x;
    else if (hp < 2)
        r = x, g = c;
    else if (hp < 3)
        g = c, b = x;
    else if (hp < 4)
        g = x, b = c;
    else if (hp < 5)
        r = x, b = c;
    else
        r = c, b = x;
    const float m = l - 0.5f * c;
    rgb[0] = r + m;
    rgb[1] = g + m;
    rgb[2] = b + m;
}

/** Hue in degrees of an RGB colour; negative when it has none (a grey). */
float hue_of(const float rgb[3]) {
    const float mx = std::max({rgb[0], rgb[1], rgb[2]}), mn = std::min({rgb[0], rgb[1], rgb[2]});
    const float c = mx - mn;
    if (!(c > 1e-6f * std::max(mx, 1e-6f))) return -1.0f;
    float h;
    if (mx == rgb[0])
        h = std::fmod((rgb[1] - rgb[2]) / c, 6.0f);
    else if (mx == rgb[1])
        h = (rgb[2] - rgb[0]) / c + 2.0f;
    else
        h = (rgb[0] - rgb[1]) / c + 4.0f;
    h *= 60.0f;
    return h < 0 ? h + 360.0f : h;
}

bool build_fresnel(Material& m, const SpangleParams_v1* p, const SpangleHost_v1* host,
                   std::string& why) {
    const std::string kind = param_string(p, "fresnel");
    float to_working[9];
    if (!rec709_to_working(host, to_working, why)) return false;
    const std::string preset = param_string(p, "preset");
    const mf::MetalPreset* metal = nullptr;
    for (const auto& mp : mf::kMetalPresets)
        if (preset == mp.name) metal = &mp;
    const auto ior = static_cast<float>(param_number(p, "flake_ior")),
               f0 = static_cast<float>(param_number(p, "flake_f0"));
    for (int i = 0; i < kFresnel; ++i) {
        const float c = (static_cast<float>(i) + 0.5f) / kFresnel;
        float f[3];
        for (int ch = 0; ch < 3; ++ch) {
            if (kind == "dielectric")
                f[ch] = mf::fresnel_dielectric(c, ior);
            else if (kind == "schlick")
                f[ch] = f0 + (1.0f - f0) * std::pow(1.0f - c, 5.0f);
            else if (!metal)
                f[ch] = 1.0f;  // "perfect"
            else
                f[ch] = mf::fresnel_conductor(c, metal->eta[ch], metal->k[ch]);
        }
        // Metals' indices are given per Rec.709 band: carry the reflectance into the working space.
        const bool coloured = kind == "conductor" && metal;
        for (int r = 0; r < 3; ++r)
            m.fresnel[i][r] =
                coloured ? std::clamp(to_working[3 * r] * f[0] + to_working[3 * r + 1] * f[1] +
                                          to_working[3 * r + 2] * f[2],
                                      0.0f, 1.0f)
                         : f[r];
    }
    return true;
}

bool build_colors(Material& m, const SpangleParams_v1* p, const SpangleHost_v1* host,
                  std::string& why) {
    for (int c = 0; c < 3; ++c)
        m.flake_rgb[c] = static_cast<float>(param_number(p, "flake_color", c));
    std::copy(m.flake_rgb, m.flake_rgb + 3, m.mean_rgb);
    if (param_number(p, "color_table") == 0.0) return true;
    const auto n = static_cast<int>(param_number(p, "table_size"));
    const auto s = static_cast<float>(param_number(p, "table_s")),
               l = static_cast<float>(param_number(p, "table_l"));
    m.table_rgb.resize(static_cast<std::size_t>(3 * n));
    for (int k = 0; k < n; ++k)
        hsl_to_rgb(360.0f * static_cast<float>(k) / static_cast<float>(n), s, l,
                   &m.table_rgb[static_cast<std::size_t>(3 * k)]);
    const std::string space = param_string(p, "table_space");
    char err[256] = {0};
    if (host->convert_to_working(host->context, space.c_str(), m.table_rgb.data(),
                                 static_cast<uint32_t>(n), err, sizeof(err)) != 0) {
        why = "colour table: " + std::string(err);
        return false;
    }
    for (float& x : m.table_rgb) x = std::max(0.0f, x);
    // Hue bias towards base_color: its hue measured in linear Rec.709 (working -> Rec.709 through
    // the inverse of the host's matrix).
    float to_working[9];
    if (!rec709_to_working(host, to_working, why)) return false;
    const float* a = to_working;
    const float det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                      a[2] * (a[3] * a[7] - a[4] * a[6]);
    float base709[3] = {m.base[0], m.base[1], m.base[2]};
    if (std::fabs(det) > 1e-12f) {
        const float inv[9] = {(a[4] * a[8] - a[5] * a[7]) / det, (a[2] * a[7] - a[1] * a[8]) / det,
                              (a[1] * a[5] - a[2] * a[4]) / det, (a[5] * a[6] - a[3] * a[8]) / det,
                              (a[0] * a[8] - a[2] * a[6]) / det, (a[2] * a[3] - a[0] * a[5]) / det,
                              (a[3] * a[7] - a[4] * a[6]) / det, (a[1] * a[6] - a[0] * a[7]) / det,
                              (a[0] * a[4] - a[1] * a[3]) / det};
        for (int r = 0; r < 3; ++r)
            base709[r] =
                inv[3 * r] * m.base[0] + inv[3 * r + 1] * m.base[1] + inv[3 * r + 2] * m.base[2];
    }
    const float base_hue = hue_of(base709);
    const auto spread = static_cast<float>(param_number(p, "hue_spread"));
    std::vector<double> w(static_cast<std::size_t>(n), 1.0);
    if (spread > 0.0f && base_hue >= 0.0f) {
        for (int k = 0; k < n; ++k) {
            float d = std::fabs(360.0f * static_cast<float>(k) / static_cast<float>(n) - base_hue);
            d = std::min(d, 360.0f - d);
            w[static_cast<std::size_t>(k)] = std::exp(-static_cast<double>(d * d) /
                                                      (2.0 * static_cast<double>(spread * spread)));
        }
    }
    const double total = std::accumulate(w.begin(), w.end(), 0.0);
    m.table_cdf.resize(static_cast<std::size_t>(n));
    double run = 0.0;
    m.mean_rgb[0] = m.mean_rgb[1] = m.mean_rgb[2] = 0.0f;
    for (int k = 0; k < n; ++k) {
        const double pk = w[static_cast<std::size_t>(k)] / total;
        run += pk;
        m.table_cdf[static_cast<std::size_t>(k)] = static_cast<float>(run);
        for (int c = 0; c < 3; ++c)
            m.mean_rgb[c] +=
                static_cast<float>(pk) * m.table_rgb[static_cast<std::size_t>(3 * k + c)];
    }
    m.table_cdf.back() = 1.0f;
    return true;
}

/** Colour of a flake from its uniform number. */
const float* flake_color(const Material& m, float u) {
    if (m.table_cdf.empty()) return m.flake_rgb;
    const auto it = std::upper_bound(m.table_cdf.begin(), m.table_cdf.end(), u);
    const auto k = static_cast<std::size_t>(std::min<std::ptrdiff_t>(
        it - m.table_cdf.begin(), static_cast<std::ptrdiff_t>(m.table_cdf.size()) - 1));
    return &m.table_rgb[3 * k];
}

/** Tables over cos(theta_o): the flake distribution's p_valid and the coat's albedo. */
void build_angle_tables(Material& m) {
    constexpr uint32_t kN = 1024;
    double avg = 0.0;
    for (int i = 0; i < kTable; ++i) {
        const float mu = (static_cast<float>(i) + 0.5f) / kTable;
        const V3 wo{std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu};
        uint32_t valid = 0;
        double coat = 0.0;
        for (uint32_t k = 0; k < kN; ++k) {
            const float u0 = (static_cast<float>(k) + 0.5f) / kN, u1 = radical_inverse2(k);
            // Visible flake normals: the share whose mirror direction stays above the horizon.
            const V3 h = mf::ggx_sample_visible(wo, m.alpha, m.alpha, u0, u1);
            if (mf::reflect(wo, h).z > 0.0f) ++valid;
            if (m.coat && !m.coat_delta) {
                const V3 hc = mf::ggx_sample_visible(wo, m.coat_alpha, m.coat_alpha, u0, u1);
                const V3 wi = mf::reflect(wo, hc);
                if (wi.z > 0.0f)
                    coat +=
                        static_cast<double>(mf::fresnel_dielectric(mf::dot(wo, hc), m.coat_ior) *
                                            mf::ggx_g2(wo, wi, m.coat_alpha, m.coat_alpha) /
                                            mf::ggx_g1(wo, m.coat_alpha, m.coat_alpha));
            }
        }
        m.p_valid[i] = std::max(1e-4f, static_cast<float>(valid) / kN);
        m.coat_e[i] = !m.coat        ? 0.0f
                      : m.coat_delta ? mf::fresnel_dielectric(mu, m.coat_ior)
                                     : std::min(1.0f, static_cast<float>(coat / kN));
        avg += 2.0 * static_cast<double>(m.coat_e[i] * mu) / kTable;
    }
    m.coat_e_avg = static_cast<float>(avg);
}

void* flake_create(const SpangleParams_v1* p, const SpangleHost_v1* host, char* error,
                   uint32_t cap) {
    auto* m = new (std::nothrow) Material;
    if (!m) {
        set_error(error, cap, "out of memory");
        return nullptr;
    }
    std::string why;
    m->min_flakes = param_number(p, "min_flakes");
    m->max_flakes = param_number(p, "max_flakes");
    if (!(m->min_flakes < m->max_flakes)) why = "min_flakes must be below max_flakes";
    for (int c = 0; c < 3; ++c) m->base[c] = static_cast<float>(param_number(p, "base_color", c));
    m->flake_weight = static_cast<float>(param_number(p, "flake_weight"));
    m->density = static_cast<float>(param_number(p, "density"));
    m->world_density = param_string(p, "density_space") == "world";
    m->alpha = static_cast<float>(param_number(p, "flake_roughness"));
    m->cone = Cone(static_cast<float>(param_number(p, "gamma")) * kPi / 180.0f);
    m->footprint_scale = static_cast<float>(param_number(p, "footprint_scale"));
    m->shadowing = param_number(p, "shadowing") != 0.0;
    m->field.seed = static_cast<uint64_t>(param_number(p, "seed"));
    m->field.alpha = m->alpha;
    m->field.leaf_size = static_cast<int>(param_number(p, "leaf_size"));
    m->field.max_depth = static_cast<int>(param_number(p, "max_depth"));
    m->field.exact_below = static_cast<int>(param_number(p, "binomial_exact_below"));
    m->enumerate_cap = static_cast<uint32_t>(std::min(4.0 * m->max_flakes + 64.0, 1e7));
    m->coat = param_number(p, "coat") != 0.0;
    m->coat_ior = static_cast<float>(param_number(p, "coat_ior"));
    m->coat_alpha =
        std::max(mf::kDeltaAlpha, static_cast<float>(param_number(p, "coat_roughness")));
    m->coat_delta = param_number(p, "coat_roughness") < static_cast<double>(mf::kDeltaAlpha);
    if (why.empty() && build_fresnel(*m, p, host, why) && build_colors(*m, p, host, why))
        build_angle_tables(*m);
    if (!why.empty()) {
        set_error(error, cap, why);
        delete m;
        return nullptr;
    }
    return m;
}

void flake_destroy(void* instance) {
    delete static_cast<Material*>(instance);
}

using Clock = std::chrono::steady_clock;
uint64_t ns_since(Clock::time_point t0) {
    return static_cast<uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count());
}

void flake_prepare(const void* inst, const SpangleShadingBatch_v1* b, void* closures,
                   SpangleArena_v1* arena) {
    const auto t0 = Clock::now();
    const Material& m = *static_cast<const Material*>(inst);
    auto* out = static_cast<Closure*>(closures);
    thread_local std::vector<CacheEntry> scratch;
    uint64_t n_discrete = 0, n_blended = 0, n_smooth = 0, n_trunc = 0, flakes = 0, lambda_milli = 0,
             n_lambda = 0;
    const double log_min = std::log(std::max(m.min_flakes, 1e-9)), log_max = std::log(m.max_flakes);
    for (uint32_t i = 0; i < b->count; ++i) {
        Closure& c = out[i];
        c = Closure{};
        c.wo = {b->wo_x[i], b->wo_y[i], b->wo_z[i]};
        c.valid = c.wo.z > 0.0f ? 1u : 0u;
        if (!c.valid) continue;
        c.g1_wo = mf::ggx_g1(c.wo, m.alpha, m.alpha);
        c.pvalid_o = lerp_table(m.p_valid, kTable, c.wo.z);
        c.e_coat_o = m.coat ? lerp_table(m.coat_e, kTable, c.wo.z) : 0.0f;
        // Distance blending from the expected count in the footprint.
        double lambda = INFINITY;
        if (b->flags[i] & SPANGLE_SHADING_HAS_DIFFERENTIALS) {
            const Footprint fp = make_footprint(b->u[i], b->v[i], b->du_dx[i], b->dv_dx[i],
                                                b->du_dy[i], b->dv_dy[i], m.footprint_scale);
            const double per_tile = m.world_density ? static_cast<double>(m.density) *
                                                          static_cast<double>(b->uv_area[i])
                                                    : static_cast<double>(m.density);
            lambda = per_tile * fp.area();
            if (lambda < m.max_flakes) {
                const double x = std::clamp(
                    (std::log(std::max(lambda, 1e-300)) - log_min) / (log_max - log_min), 0.0, 1.0);
                c.t = lambda <= m.min_flakes ? 0.0f : static_cast<float>(x * x * (3.0 - 2.0 * x));
                FieldParams field = m.field;
                field.flakes_per_tile = std::min(per_tile, 2147483647.0);
                scratch.clear();
                bool truncated = false;
                for_each_flake(field, fp, m.enumerate_cap, truncated, [&](const Flake& f) {
                    const float cos_om = mf::dot(c.wo, f.m);
                    if (cos_om <= 0.0f) return;
                    const V3 r = mf::reflect(c.wo, f.m);
                    if (r.z <= 0.0f) return;
                    // Projected area towards the viewer of a flake covering an equal share of the
                    // macro surface (FLAKES.md 4); G1(wo) is common to all and cancels in f.
                    const float w = cos_om / f.m.z;
                    const float* col = flake_color(m, f.color_u);
                    const int fi = std::min(kFresnel - 1, static_cast<int>(cos_om * kFresnel));
                    CacheEntry e;
                    e.r = r;
                    for (int ch = 0; ch < 3; ++ch) e.rgb[ch] = w * col[ch] * m.fresnel[fi][ch];
                    e.lum = std::max(0.0f, luminance(e.rgb));
                    e.w = w;
                    scratch.push_back(e);
                });
                flakes += scratch.size();
                if (truncated) {
                    // More flakes than the bound, or too many tiles: the smooth lobe takes over.
                    ++n_trunc;
                    c.t = 1.0f;
                } else if (!scratch.empty()) {
                    const auto count = static_cast<uint32_t>(scratch.size());
                    auto* entries = arena ? static_cast<CacheEntry*>(arena->allocate(
                                                arena->context, count * sizeof(CacheEntry), 16))
                                          : nullptr;
                    auto* cdf = arena ? static_cast<float*>(arena->allocate(
                                            arena->context, count * sizeof(float), 16))
                                      : nullptr;
                    if (entries && cdf) {
                        std::memcpy(entries, scratch.data(), count * sizeof(CacheEntry));
                        float run = 0.0f, wsum = 0.0f;
                        for (uint32_t j = 0; j < count; ++j) {
                            run += entries[j].lum;
                            cdf[j] = run;
                            wsum += entries[j].w;
                        }
                        c.lobe = DiscreteLobe{entries, cdf, count, wsum, run};
                    } else {
                        c.t = 1.0f;  // no scratch memory: degrade to the expectation
                    }
                }
            }
        }
        if (std::isfinite(lambda)) {
            lambda_milli += static_cast<uint64_t>(std::min(lambda, 1e12) * 1000.0);
            ++n_lambda;
        }
        if (c.t <= 0.0f)
            ++n_discrete;
        else if (c.t >= 1.0f)
            ++n_smooth;
        else
            ++n_blended;
        // Lobe selection in proportion to the energy each returns (a floor keeps every present
        // lobe sampled).
        const float under = 1.0f - c.e_coat_o;
        float w_coat = m.coat ? c.e_coat_o : 0.0f;
        float w_base = under * (1.0f - m.flake_weight) * luminance(m.base);
        float w_flake = under * m.flake_weight *
                        std::max(0.05f, luminance(m.mean_rgb) * luminance(m.fresnel[kFresnel - 1]));
        const float total = w_coat + w_base + w_flake;
        if (total > 0.0f) {
            c.p_coat = w_coat / total;
            c.p_base = w_base / total;
            c.p_flake = w_flake / total;
        }
    }
    m.points += b->count;
    m.discrete += n_discrete;
    m.blended += n_blended;
    m.smooth += n_smooth;
    m.truncated += n_trunc;
    m.flakes_sum += flakes;
    m.lambda_milli_sum += lambda_milli;
    m.lambda_count += n_lambda;
    m.ns_prepare += ns_since(t0);
}

/** The whole material at wi: f (RGB) and pdf. */
void eval_material(const Material& m, const Closure& c, V3 wi, float f[3], float& pdf) {
    f[0] = f[1] = f[2] = 0.0f;
    pdf = 0.0f;
    if (!c.valid || wi.z <= 0.0f) return;
    const V3 wo = c.wo;
    float f_coat = 0.0f, pdf_coat = 0.0f;
    float under = 1.0f;
    if (m.coat) {
        under = (1.0f - c.e_coat_o) * (1.0f - lerp_table(m.coat_e, kTable, wi.z));
        if (!m.coat_delta) {
            const V3 h = mf::normalize(wo + wi);
            const float d = mf::ggx_d(h, m.coat_alpha, m.coat_alpha);
            f_coat = mf::fresnel_dielectric(mf::dot(wo, h), m.coat_ior) * d *
                     mf::ggx_g2(wo, wi, m.coat_alpha, m.coat_alpha) / (4.0f * wo.z * wi.z);
            pdf_coat = mf::ggx_g1(wo, m.coat_alpha, m.coat_alpha) * d / (4.0f * wo.z);
        }
    }
    // Flakes: discrete and smooth lobes blended with t.
    float fl[3] = {0, 0, 0}, pdf_fl = 0.0f;
    const float g1_wi = m.shadowing ? mf::ggx_g1(wi, m.alpha, m.alpha) : 1.0f;
    if (c.t < 1.0f) {
        float fd[3], pd;
        eval_discrete(c.lobe, m.cone, wi, fd, pd);
        for (int ch = 0; ch < 3; ++ch) fl[ch] += (1.0f - c.t) * fd[ch] * g1_wi;
        pdf_fl += (1.0f - c.t) * pd;
    }
    if (c.t > 0.0f) {
        const V3 h = mf::normalize(wo + wi);
        const float d = mf::ggx_d(h, m.alpha, m.alpha);
        const int fi =
            std::min(kFresnel - 1, static_cast<int>(std::max(0.0f, mf::dot(wo, h)) * kFresnel));
        // The expectation of the discrete lobe: D G1(wo) [G1(wi)] F c / (4 cos_i E[W]/N), with
        // E[W]/N = cos_o p_valid(o) because flakes reflecting under the horizon are skipped.
        const float s = d * c.g1_wo * g1_wi / (4.0f * wi.z * wo.z * c.pvalid_o);
        for (int ch = 0; ch < 3; ++ch) fl[ch] += c.t * s * m.fresnel[fi][ch] * m.mean_rgb[ch];
        pdf_fl += c.t * c.g1_wo * d / (4.0f * wo.z);
    }
    for (int ch = 0; ch < 3; ++ch)
        f[ch] = f_coat +
                under * ((1.0f - m.flake_weight) * m.base[ch] * kInvPi + m.flake_weight * fl[ch]);
    pdf = c.p_coat * pdf_coat + c.p_base * wi.z * kInvPi + c.p_flake * pdf_fl;
    if (!std::isfinite(f[0] + f[1] + f[2]) || !std::isfinite(pdf)) f[0] = f[1] = f[2] = pdf = 0.0f;
}

void flake_eval(const void* inst, const void* closures, SpangleEvalBatch_v1* q) {
    const auto t0 = Clock::now();
    const Material& m = *static_cast<const Material*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        float f[3], pdf;
        eval_material(m, cl[q->closure_index ? q->closure_index[i] : i],
                      {q->wi_x[i], q->wi_y[i], q->wi_z[i]}, f, pdf);
        q->f_r[i] = f[0];
        q->f_g[i] = f[1];
        q->f_b[i] = f[2];
        q->pdf[i] = pdf;
    }
    m.ns_eval += ns_since(t0);
}

/** Picks `choice` < p and rescales u to a fresh uniform in [0, 1). */
bool pick(float& u, float p) {
    if (u < p) {
        u = std::min(u / p, 0x1.fffffep-1f);
        return true;
    }
    u = std::min((u - p) / std::max(1e-12f, 1.0f - p), 0x1.fffffep-1f);
    return false;
}

void flake_sample(const void* inst, const void* closures, SpangleSampleBatch_v1* q) {
    const auto t0 = Clock::now();
    const Material& m = *static_cast<const Material*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const Closure& c = cl[q->closure_index ? q->closure_index[i] : i];
        if (q->eta) q->eta[i] = 1.0f;
        const auto fail = [&] {
            q->wi_x[i] = q->wi_y[i] = 0.0f;
            q->wi_z[i] = 1.0f;
            q->f_r[i] = q->f_g[i] = q->f_b[i] = q->pdf[i] = 0.0f;
            q->flags[i] = 0;
        };
        if (!c.valid) {
            fail();
            continue;
        }
        float u = q->u2[i];
        V3 wi;
        uint32_t flags = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_GLOSSY;
        if (pick(u, c.p_coat)) {
            if (m.coat_delta) {
                const float fr = mf::fresnel_dielectric(c.wo.z, m.coat_ior);
                q->wi_x[i] = -c.wo.x;
                q->wi_y[i] = -c.wo.y;
                q->wi_z[i] = c.wo.z;
                q->f_r[i] = q->f_g[i] = q->f_b[i] = fr / c.wo.z;
                q->pdf[i] = c.p_coat;
                q->flags[i] = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_SPECULAR;
                continue;
            }
            wi = mf::reflect(
                c.wo, mf::ggx_sample_visible(c.wo, m.coat_alpha, m.coat_alpha, q->u0[i], q->u1[i]));
        } else if (pick(u, c.p_base / std::max(1e-12f, 1.0f - c.p_coat))) {
            wi = mf::cosine_hemisphere(q->u0[i], q->u1[i]);
            flags = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_DIFFUSE;
        } else if (pick(u, c.t)) {
            wi = mf::reflect(c.wo,
                             mf::ggx_sample_visible(c.wo, m.alpha, m.alpha, q->u0[i], q->u1[i]));
        } else if (!sample_discrete(c.lobe, m.cone, u, q->u0[i], q->u1[i], wi)) {
            fail();
            continue;
        }
        if (wi.z <= 0.0f) {
            fail();
            continue;
        }
        float f[3], pdf;
        eval_material(m, c, wi, f, pdf);  // the whole mixture, so MIS sees one density
        if (!(pdf > 0.0f)) {
            fail();
            continue;
        }
        q->wi_x[i] = wi.x;
        q->wi_y[i] = wi.y;
        q->wi_z[i] = wi.z;
        q->f_r[i] = f[0];
        q->f_g[i] = f[1];
        q->f_b[i] = f[2];
        q->pdf[i] = pdf;
        q->flags[i] = flags;
    }
    m.ns_sample += ns_since(t0);
}

uint32_t flake_stats(const void* inst, SpangleStat_v1* out, uint32_t capacity) {
    const Material& m = *static_cast<const Material*>(inst);
    const double points = static_cast<double>(m.points.load());
    const double per = points > 0 ? 1.0 / points : 0.0;
    const SpangleStat_v1 s[] = {
        {"shading points", points},
        {"mean expected flakes per footprint (lambda)",
         m.lambda_count ? static_cast<double>(m.lambda_milli_sum.load()) * 1e-3 /
                              static_cast<double>(m.lambda_count.load())
                        : 0.0},
        {"mean flakes enumerated per shading point",
         static_cast<double>(m.flakes_sum.load()) * per},
        {"fraction discrete", static_cast<double>(m.discrete.load()) * per},
        {"fraction blended", static_cast<double>(m.blended.load()) * per},
        {"fraction smooth", static_cast<double>(m.smooth.load()) * per},
        {"fraction truncated to smooth", static_cast<double>(m.truncated.load()) * per},
        {"ns per point in prepare", static_cast<double>(m.ns_prepare.load()) * per},
        {"ns per point in eval", static_cast<double>(m.ns_eval.load()) * per},
        {"ns per point in sample", static_cast<double>(m.ns_sample.load()) * per},
    };
    const auto n = static_cast<uint32_t>(sizeof(s) / sizeof(s[0]));
    for (uint32_t i = 0; i < std::min(n, capacity); ++i) out[i] = s[i];
    return n;
}

const SpangleMaterialModel_v1 kModels[] = {
    {"flake",
     "stochastic mirror flakes over a diffuse base, optional clear coat (Atanasov and Koylazov "
     "2016)",
     kParams, kParamCount, sizeof(Closure), flake_create, flake_destroy, flake_prepare, flake_eval,
     flake_sample, flake_stats},
};

const SpangleMaterialPlugin_v1 kPlugin = {
    SPANGLE_MATERIAL_ABI_VERSION,
    sizeof(SpangleMaterialPlugin_v1),
    "flake",
    "stochastic mirror flakes: glitter, metallic car paint, sparkling snow",
    kModels,
    1,
};

}  // namespace

extern "C" SPANGLE_PLUGIN_EXPORT const SpangleMaterialPlugin_v1* spangle_material_plugin(
    uint32_t host_abi_version) {
    return host_abi_version == SPANGLE_MATERIAL_ABI_VERSION ? &kPlugin : nullptr;
}
