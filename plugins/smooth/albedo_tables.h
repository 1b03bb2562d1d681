#pragma once
// The GGX lobe's directional albedo split by Schlick's Fresnel, E(mu) = f0 A(mu, alpha) +
// f90 B(mu, alpha), which metal_rough uses to give its diffuse base the light the specular lobe
// leaves (see metal_rough.cpp), and metal_rough's metal and the conductor to return the light
// single scattering loses (multiple scattering, below).
//
// The tables are shipped as numbers (albedo_tables_data.inc) rather than made when the plugin
// loads: 32 x 32 entries of 512 visible-normal samples each cost about 180 million instructions,
// which every process that renders a metal_rough material paid before its first sample (measured
// with callgrind: 13% of the instructions of a 160x90, 4-spp render of the car of
// tests/bench/cycles_time_to_quality.py).
// compute_albedo_tables() is the quadrature they were written from; the test
// MetalRoughTables.ShippedTablesAreTheQuadrature recomputes it and compares, and writes the file
// anew when they differ (after a change of the quadrature or of the GGX functions).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

#include "../common/microfacet.h"
#include "../common/plugin_support.h"

namespace spangle::smooth {

constexpr int kAlbedoMu = 32;             ///< cosines mu = (i + 0.5) / 32
constexpr int kAlbedoRough = 32;          ///< sqrt(alpha) = j / 31
constexpr float kAlbedoMinAlpha = 1e-3f;  ///< alphas below are clamped (a near-mirror)

struct AlbedoTables {
    float a[kAlbedoRough][kAlbedoMu], b[kAlbedoRough][kAlbedoMu];  ///< at (sqrt alpha, mu)
    float a_avg[kAlbedoRough], b_avg[kAlbedoRough];  ///< cosine-weighted averages 2 int E mu dmu
};

/** A(mu, alpha), B(mu, alpha) by VNDF sampling over a Hammersley set: each sample of the visible
 *  normals weighs G2 / G1 times (1 - w) or w, w = (1 - v.h)^5. */
inline AlbedoTables compute_albedo_tables() {
    using namespace spangle::mf;
    AlbedoTables t{};
    constexpr uint32_t kN = 512;
    for (int j = 0; j < kAlbedoRough; ++j) {
        const float r = static_cast<float>(j) / (kAlbedoRough - 1);
        const float alpha = std::max(r * r, kAlbedoMinAlpha);
        double avg_a = 0.0, avg_b = 0.0;
        for (int i = 0; i < kAlbedoMu; ++i) {
            const float mu = (static_cast<float>(i) + 0.5f) / kAlbedoMu;
            const V3 wo{std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu};
            double sa = 0.0, sb = 0.0;
            for (uint32_t k = 0; k < kN; ++k) {
                const V3 h =
                    ggx_sample_visible(wo, alpha, alpha, (static_cast<float>(k) + 0.5f) / kN,
                                       plugin_support::radical_inverse2(k));
                const V3 wi = reflect(wo, h);
                if (wi.z <= 0.0f) continue;
                const float g = ggx_g2(wo, wi, alpha, alpha) / ggx_g1(wo, alpha, alpha);
                const float w = std::pow(1.0f - std::clamp(dot(wo, h), 0.0f, 1.0f), 5.0f);
                sa += static_cast<double>((1.0f - w) * g);
                sb += static_cast<double>(w * g);
            }
            t.a[j][i] = static_cast<float>(sa / kN);
            t.b[j][i] = static_cast<float>(sb / kN);
            avg_a += 2.0 * static_cast<double>(t.a[j][i] * mu) / kAlbedoMu;
            avg_b += 2.0 * static_cast<double>(t.b[j][i] * mu) / kAlbedoMu;
        }
        t.a_avg[j] = static_cast<float>(avg_a);
        t.b_avg[j] = static_cast<float>(avg_b);
    }
    return t;
}

/** The tables as shipped. */
inline const AlbedoTables& shipped_albedo_tables() {
    static constexpr AlbedoTables kTables = {
#include "albedo_tables_data.inc"
    };
    return kTables;
}

/** Bilinear lookup of both tables, A and B, at (mu, alpha): one set of weights for the two. */
inline void albedo_lookup(const AlbedoTables& tab, float mu, float alpha, float& a, float& b) {
    const float x = std::clamp(mu * kAlbedoMu - 0.5f, 0.0f, static_cast<float>(kAlbedoMu - 1));
    const float y = std::clamp(std::sqrt(alpha) * (kAlbedoRough - 1), 0.0f,
                               static_cast<float>(kAlbedoRough - 1));
    const int i = std::min(static_cast<int>(x), kAlbedoMu - 2),
              j = std::min(static_cast<int>(y), kAlbedoRough - 2);
    const float s = x - static_cast<float>(i), t = y - static_cast<float>(j);
    const auto bilerp = [&](const float(&v)[kAlbedoRough][kAlbedoMu]) {
        return (v[j][i] * (1 - s) + v[j][i + 1] * s) * (1 - t) +
               (v[j + 1][i] * (1 - s) + v[j + 1][i + 1] * s) * t;
    };
    a = bilerp(tab.a);
    b = bilerp(tab.b);
}

/** Linear lookup of an average table at alpha. */
inline float albedo_avg_lookup(const float (&row)[kAlbedoRough], float alpha) {
    const float y = std::clamp(std::sqrt(alpha) * (kAlbedoRough - 1), 0.0f,
                               static_cast<float>(kAlbedoRough - 1));
    const int j = std::min(static_cast<int>(y), kAlbedoRough - 2);
    const float t = y - static_cast<float>(j);
    return row[j] * (1 - t) + row[j + 1] * t;
}

// Multiple scattering (Kulla and Conty 2017, "Revisiting physically based shading at
// Imageworks"). Single-scattering GGX drops the light that bounces more than once between the
// microfacets: 1 - E(mu_o) for F = 1, E = A + B above (0.69 of it at alpha 1 head-on). The
// compensation lobe returns it, spread over wi as
//     f_ms = F_ms (1 - E(mu_o)) (1 - E(mu_i)) / (pi (1 - E_avg)),
// whose cosine-weighted integral over wi is exactly 1 - E(mu_o), so that a white conductor
// reflects everything at every angle and roughness; it is symmetric in wo and wi. For a
// coloured metal each further bounce is tinted by the average Fresnel F_avg = 2 int F mu dmu:
//     F_ms = F_avg^2 E_avg / (1 - F_avg (1 - E_avg)),
// the sum over bounces of what leaves after each (1 for F_avg = 1).

/** E(mu) of GGX for F = 1 at alpha (isotropic; an anisotropic lobe takes sqrt(ax ay)). */
inline float ggx_albedo(float mu, float alpha) {
    float a, b;
    albedo_lookup(shipped_albedo_tables(), std::max(mu, 0.0f), alpha, a, b);
    return std::min(a + b, 1.0f);
}

/** E_avg of GGX for F = 1 at alpha. */
inline float ggx_albedo_avg(float alpha) {
    const AlbedoTables& t = shipped_albedo_tables();
    return std::min(albedo_avg_lookup(t.a_avg, alpha) + albedo_avg_lookup(t.b_avg, alpha), 0.9999f);
}

/** f_ms / F_ms at (mu_o, mu_i): the shape of the compensation lobe (see above). */
inline float ms_shape(float e_o, float e_i, float e_avg) {
    return std::max(0.0f, 1.0f - e_o) * std::max(0.0f, 1.0f - e_i) /
           (3.14159265358979f * (1.0f - e_avg));
}

/** F_ms of a channel whose Fresnel averages f_avg over the hemisphere (see above). */
inline float ms_colour(float f_avg, float e_avg) {
    return f_avg * f_avg * e_avg / (1.0f - f_avg * (1.0f - e_avg));
}

/** The text of albedo_tables_data.inc for t: every float as a hexadecimal literal (exact). */
inline std::string albedo_tables_source(const AlbedoTables& t) {
    std::string out =
        "// Written by albedo_tables_source(compute_albedo_tables()) (albedo_tables.h); the test\n"
        "// MetalRoughTables.ShippedTablesAreTheQuadrature checks it. Do not edit by hand.\n";
    char buf[32];
    const auto row = [&](const float* v, int n) {
        out += "{";
        for (int i = 0; i < n; ++i) {
            std::snprintf(buf, sizeof buf, "%s%af", i % 4 == 0 ? "\n    " : " ",
                          static_cast<double>(v[i]));
            out += buf;
            if (i + 1 < n) out += ",";
        }
        out += "},\n";
    };
    for (const auto* table : {&t.a, &t.b}) {
        out += "{\n";
        for (int j = 0; j < kAlbedoRough; ++j) row((*table)[j], kAlbedoMu);
        out += "},\n";
    }
    row(t.a_avg, kAlbedoRough);
    row(t.b_avg, kAlbedoRough);
    return out;
}

}  // namespace spangle::smooth
