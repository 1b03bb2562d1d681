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

}  // namespace

bool build_colors(ColorTable& t, const float base_rgb[3], const SpangleParams_v3* p,
                  const SpangleHost_v3* host, std::string& why) {
    for (int c = 0; c < 3; ++c) t.single[c] = static_cast<float>(param_number(p, "flake_color", c));
    std::copy(t.single, t.single + 3, t.mean);
    if (param_number(p, "color_table") == 0.0) return true;
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
        why = "colour table: " + std::string(err);
        return false;
    }
    for (float& x : t.rgb) x = std::max(0.0f, x);
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
