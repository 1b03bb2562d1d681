#include "discrete_lobe.h"

#include <algorithm>
#include <cmath>

namespace spangle::flake {

bool make_entry(V3 wo, V3 m, const float col[3], const FresnelTable& fresnel, CacheEntry& e,
                float scale) {
    const float cos_om = mf::dot(wo, m);
    if (cos_om <= 0.0f) return false;
    const V3 r = mf::reflect(wo, m);
    if (r.z <= 0.0f) return false;
    // Projected area towards the viewer of a flake covering an equal share of the macro surface
    // (FLAKES.md 4); G1(wo) is common to all flakes and cancels in f.
    const float w = cos_om / m.z;
    float f[3];
    fresnel.eval(cos_om, f);
    float rgb[3];
    for (int c = 0; c < 3; ++c) rgb[c] = w * col[c] * f[c];
    e.r = r;
    for (int c = 0; c < 3; ++c) e.rgb[c] = rgb[c] * scale;
    e.lum = std::max(0.0f, luminance(rgb)) * scale;
    e.w = w * scale;
    return true;
}

Cone::Cone(float gamma_rad) {
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
    threshold = 4.0f * sin2_half;
    solid_angle = 4.0f * mf::kPi * sin2_half;
}

void cone_sums(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float rgb[3], float& lum) {
    rgb[0] = rgb[1] = rgb[2] = lum = 0.0f;
    for (uint32_t j = 0; j < lobe.count; ++j) {
        const CacheEntry& e = lobe.entries[j];
        const float dx = wi.x - e.r.x, dy = wi.y - e.r.y, dz = wi.z - e.r.z;
        if (dx * dx + dy * dy + dz * dz > cone.threshold) continue;
        rgb[0] += e.rgb[0];
        rgb[1] += e.rgb[1];
        rgb[2] += e.rgb[2];
        lum += e.lum;
    }
}

void eval_discrete(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float norm, float f[3],
                   float& pdf) {
    f[0] = f[1] = f[2] = 0.0f;
    pdf = 0.0f;
    if (lobe.count == 0 || !(norm > 0.0f) || wi.z <= 0.0f) return;
    float sum[3], lum;
    cone_sums(lobe, cone, wi, sum, lum);
    const float k = 1.0f / (norm * cone.solid_angle * wi.z);
    for (int c = 0; c < 3; ++c) f[c] = sum[c] * k;
    pdf = lobe.lum_sum > 0.0f ? lum / (lobe.lum_sum * cone.solid_angle) : 0.0f;
}

V3 sample_cone(V3 r, float sin2_half, float c0, float c1) {
    // cos(theta) = 1 - c0 (1 - cos gamma), with 1 - cos gamma = 2 sin^2(gamma/2).
    const float one_minus_cos = c0 * 2.0f * sin2_half;
    const float cos_t = 1.0f - one_minus_cos;
    const float sin_t = std::sqrt(std::max(0.0f, one_minus_cos * (2.0f - one_minus_cos)));
    const float phi = 2.0f * mf::kPi * c1;
    // Orthonormal basis around r (Duff et al. 2017).
    const float sign = std::copysign(1.0f, r.z);
    const float a = -1.0f / (sign + r.z), b = r.x * r.y * a;
    const V3 s{1.0f + sign * r.x * r.x * a, sign * b, -sign * r.x};
    const V3 t{b, sign + r.y * r.y * a, -r.y};
    return mf::normalize(s * (sin_t * std::cos(phi)) + t * (sin_t * std::sin(phi)) + r * cos_t);
}

bool sample_discrete(const DiscreteLobe& lobe, const Cone& cone, float u0, float u1, float u2,
                     V3& wi) {
    if (lobe.count == 0 || !(lobe.lum_sum > 0.0f)) return false;
    // Binary search, bounded by the table; u0 = 0 and u0 -> 1 both land on valid entries.
    const float target = u0 * lobe.lum_sum;
    const float* it = std::upper_bound(lobe.cdf, lobe.cdf + lobe.count, target);
    const auto j = static_cast<uint32_t>(std::min<std::ptrdiff_t>(it - lobe.cdf, lobe.count - 1));
    wi = sample_cone(lobe.entries[j].r, cone.sin2_half, u1, u2);
    return wi.z > 0.0f;
}

}  // namespace spangle::flake
