#include "palette.h"

#include <cmath>
#include <numeric>

#include "../common/microfacet.h"
#include "../common/plugin_support.h"

namespace spangle::flake {

using namespace spangle::plugin_support;

float FresnelTable::normal_luminance() const {
    return luminance(rgb[kNodes - 1]);
}

bool build_fresnel(FresnelTable& t, const SpangleParams_v3* p, const SpangleHost_v3* host,
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
    for (int i = 0; i < FresnelTable::kNodes; ++i) {
        const float c = static_cast<float>(i) / static_cast<float>(FresnelTable::kNodes - 1);
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
            t.rgb[i][r] = coloured
                              ? std::clamp(to_working[3 * r] * f[0] + to_working[3 * r + 1] * f[1] +
                                               to_working[3 * r + 2] * f[2],
                                           0.0f, 1.0f)
                              : f[r];
    }
    return true;
}

namespace {

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

/** base (working space) expressed in linear Rec.709, through the inverse of the host's matrix. */
bool base_in_rec709(const float base[3], const SpangleHost_v3* host, float out[3],
                    std::string& why) {
    float a[9];
    if (!rec709_to_working(host, a, why)) return false;
    std::copy(base, base + 3, out);
    const float det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                      a[2] * (a[3] * a[7] - a[4] * a[6]);
    if (!(std::fabs(det) > 1e-12f)) return true;
    const float inv[9] = {(a[4] * a[8] - a[5] * a[7]) / det, (a[2] * a[7] - a[1] * a[8]) / det,
                          (a[1] * a[5] - a[2] * a[4]) / det, (a[5] * a[6] - a[3] * a[8]) / det,
                          (a[0] * a[8] - a[2] * a[6]) / det, (a[2] * a[3] - a[0] * a[5]) / det,
                          (a[3] * a[7] - a[4] * a[6]) / det, (a[1] * a[6] - a[0] * a[7]) / det,
                          (a[0] * a[4] - a[1] * a[3]) / det};
    for (int r = 0; r < 3; ++r)
        out[r] = inv[3 * r] * base[0] + inv[3 * r + 1] * base[1] + inv[3 * r + 2] * base[2];
    return true;
}

/** The variation of flake colours, in HSV of the working space's linear values. */
struct Variation {
    float hue = 0;         ///< degrees: hue offsets uniform in [-hue, hue]
    float saturation = 0;  ///< saturation offsets uniform in [-saturation, saturation]
    float value = 0;       ///< value factors uniform in [1 - value, 1 + value]
};

/** RGB (non-negative) to HSV: h in degrees (0 for a grey), s and v as in Smith 1978. */
void rgb_to_hsv(const float rgb[3], float& h, float& s, float& v) {
    v = std::max({rgb[0], rgb[1], rgb[2]});
    const float mn = std::min({rgb[0], rgb[1], rgb[2]});
    s = v > 0.0f ? (v - mn) / v : 0.0f;
    h = std::max(0.0f, hue_of(rgb));
}

/** HSV to RGB (h in degrees, any real: wrapped). */
void hsv_to_rgb(float h, float s, float v, float rgb[3]) {
    float hp = std::fmod(h, 360.0f) / 60.0f;
    if (hp < 0.0f) hp += 6.0f;
    const float c = v * s, x = c * (1.0f - std::fabs(std::fmod(hp, 2.0f) - 1.0f));
    const int sector = std::min(static_cast<int>(hp), 5);
    const float r[6] = {c, x, 0, 0, x, c}, g[6] = {x, c, c, x, 0, 0}, b[6] = {0, 0, x, c, c, x};
    const float m = v - c;
    rgb[0] = r[sector] + m;
    rgb[1] = g[sector] + m;
    rgb[2] = b[sector] + m;
}

/** Variant v of colour `in`: its offsets are the v-th point of the R2 sequence (Roberts 2018),
 *  stratified over the cube of (hue, saturation, value) offsets. A grey keeps its (absent)
 *  hue and saturation; the value never exceeds max(1, the colour's own value), so varied
 *  flakes reflect no more than the brightest of the table. */
void vary(const float in[3], uint32_t v, const Variation& var, float out[3]) {
    constexpr double kG = 1.2207440846057596;  // the plastic number: x^4 = x + 1's real root
    constexpr double kA[3] = {1.0 / kG, 1.0 / (kG * kG), 1.0 / (kG * kG * kG)};
    float x[3];
    for (int k = 0; k < 3; ++k) {
        const double a = 0.5 + kA[k] * static_cast<double>(v + 1);
        x[k] = static_cast<float>(2.0 * (a - std::floor(a)) - 1.0);
    }
    float h, s, val;
    rgb_to_hsv(in, h, s, val);
    const float s2 = s > 0.0f ? std::clamp(s + var.saturation * x[1], 0.0f, 1.0f) : 0.0f;
    const float v2 = std::clamp(val * (1.0f + var.value * x[2]), 0.0f, std::max(1.0f, val));
    hsv_to_rgb(h + var.hue * x[0], s2, v2, out);
}

/** Fills t.varied (kVariants per entry of probability w[k] / sum w, a single entry when the
 *  table is off) and sets t.mean to the varied colours' exact mean; nothing without variation.
 */
void build_variants(ColorTable& t, const SpangleParams_v3* p, const std::vector<double>& w) {
    Variation var;
    var.hue = static_cast<float>(param_number(p, "hue_variation"));
    var.saturation = static_cast<float>(param_number(p, "saturation_variation"));
    var.value = static_cast<float>(param_number(p, "value_variation"));
    if (var.hue == 0.0f && var.saturation == 0.0f && var.value == 0.0f) return;
    const std::size_t entries = t.cdf.empty() ? 1 : t.cdf.size();
    const double total = std::accumulate(w.begin(), w.end(), 0.0);
    t.varied.resize(3 * entries * ColorTable::kVariants);
    double mean[3] = {0.0, 0.0, 0.0};
    for (std::size_t k = 0; k < entries; ++k) {
        const float* in = t.cdf.empty() ? t.single : &t.rgb[3 * k];
        const double pk = w[k] / total / ColorTable::kVariants;
        for (uint32_t v = 0; v < ColorTable::kVariants; ++v) {
            float* out = &t.varied[3 * (k * ColorTable::kVariants + v)];
            vary(in, v, var, out);
            for (int c = 0; c < 3; ++c) mean[c] += pk * static_cast<double>(out[c]);
        }
    }
    for (int c = 0; c < 3; ++c) t.mean[c] = static_cast<float>(mean[c]);
}

}  // namespace

bool build_colors(ColorTable& t, const float base_rgb[3], const SpangleParams_v3* p,
                  const SpangleHost_v3* host, std::string& why) {
    for (int c = 0; c < 3; ++c) t.single[c] = static_cast<float>(param_number(p, "flake_color", c));
    std::copy(t.single, t.single + 3, t.mean);
    if (param_number(p, "color_table") == 0.0) {
        build_variants(t, p, {1.0});
        return true;
    }
    const auto n = static_cast<int>(param_number(p, "table_size"));
    const auto s = static_cast<float>(param_number(p, "table_s")),
               l = static_cast<float>(param_number(p, "table_l"));
    t.rgb.resize(static_cast<std::size_t>(3 * n));
    for (int k = 0; k < n; ++k)
        hsl_to_rgb(360.0f * static_cast<float>(k) / static_cast<float>(n), s, l,
                   &t.rgb[static_cast<std::size_t>(3 * k)]);
    const std::string space = param_string(p, "table_space");
    char err[256] = {0};
    if (host->convert_to_working(host->context, space.c_str(), t.rgb.data(),
                                 static_cast<uint32_t>(n), err, sizeof(err)) != 0) {
        // (Naming the parameter: the host places the error at its line.)
        why = "colour table: table_space: " + std::string(err);
        return false;
    }
    // Within [0, 1] in the working space, as colour parameters are: a table in a wider space
    // (ACEScg into Rec.709) gave flakes reflecting 1.4-1.7 times the light in one channel.
    for (float& x : t.rgb) x = std::clamp(x, 0.0f, 1.0f);
    // Hue bias towards base_color: its hue measured in linear Rec.709.
    float base709[3];
    if (!base_in_rec709(base_rgb, host, base709, why)) return false;
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
    t.cdf.resize(static_cast<std::size_t>(n));
    double run = 0.0;
    double mean[3] = {0.0, 0.0, 0.0};
    for (int k = 0; k < n; ++k) {
        const double pk = w[static_cast<std::size_t>(k)] / total;
        run += pk;
        t.cdf[static_cast<std::size_t>(k)] = static_cast<float>(run);
        for (int c = 0; c < 3; ++c)
            mean[c] += pk * static_cast<double>(t.rgb[static_cast<std::size_t>(3 * k + c)]);
    }
    t.cdf.back() = 1.0f;
    for (int c = 0; c < 3; ++c) t.mean[c] = static_cast<float>(mean[c]);
    build_variants(t, p, w);
    t.guide.resize(ColorTable::kGuide);
    std::size_t k = 0;
    for (int b = 0; b < ColorTable::kGuide; ++b) {
        const float lo = static_cast<float>(b) / ColorTable::kGuide;
        while (k + 1 < t.cdf.size() && t.cdf[k] <= lo) ++k;
        t.guide[static_cast<std::size_t>(b)] = static_cast<uint16_t>(k);
    }
    return true;
}

}  // namespace spangle::flake
