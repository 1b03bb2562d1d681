#include "discrete_lobe.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace spangle::flake {

void flush_entries(V3 wo, float alpha, EntryBatch& b, std::vector<CacheEntry>& out) {
    constexpr uint32_t kSize = EntryBatch::kSize;
    const uint32_t n = std::min(b.n, kSize);
    b.n = 0;
    // Normals, the cosine with wo, the mirror direction's height and the weight: four at a time.
    alignas(64) float mx[kSize], my[kSize], mz[kSize], cos_om[kSize], rz[kSize], w[kSize];
    for (uint32_t i = 0; i < n; ++i) flake_normal_of(alpha, b.s[i], b.t[i], mx[i], my[i], mz[i]);
    for (uint32_t i = 0; i < n; ++i) {
        cos_om[i] = wo.x * mx[i] + wo.y * my[i] + wo.z * mz[i];
        rz[i] = mz[i] * (2.0f * cos_om[i]) - wo.z;
        w[i] = cos_om[i] / mz[i];
    }
    // The rest per flake (its Fresnel table and colour are its own), written in place: the
    // vector grown once and cut back to the entries kept.
    const std::size_t base = out.size();
    out.resize(base + n);
    CacheEntry* const dst = out.data() + base;
    uint32_t kept = 0;
    for (uint32_t i = 0; i < n; ++i) {
        if (cos_om[i] <= 0.0f || rz[i] <= 0.0f) continue;
        const float c2 = 2.0f * cos_om[i];
        float f[3];
        b.fresnel[i]->eval(cos_om[i], f);
        float rgb[3];
        for (int c = 0; c < 3; ++c) rgb[c] = w[i] * b.col[i][c] * f[c];
        CacheEntry& e = dst[kept++];
        e.r = {mx[i] * c2 - wo.x, my[i] * c2 - wo.y, rz[i]};
        const float scale = b.scale[i];
        for (int c = 0; c < 3; ++c) e.rgb[c] = rgb[c] * scale;
        e.lum = std::max(0.0f, luminance(rgb)) * scale;
        e.w = w[i] * scale;
    }
    out.resize(base + kept);
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

double cache_share_exact(float alpha, float cos_o) {
    const double c = std::clamp(static_cast<double>(cos_o), 0.0, 1.0);
    if (!(c > 0.0)) return 0.5;
    const double s = std::sqrt(std::max(0.0, 1.0 - c * c));
    const double a2 = static_cast<double>(alpha) * static_cast<double>(alpha);
    // Even in phi: the half turn [0, pi], its ends weighted 1/2.
    constexpr int kSteps = 512;
    double sum = 0.0;
    for (int i = 0; i <= kSteps; ++i) {
        const double phi = std::numbers::pi * i / kSteps;
        const double x = s * std::cos(phi);
        const double a = std::sqrt(x * x + c * c);
        // T = tan(pi/4 + delta/2) = (a + x) / c, written without cancellation where x < 0.
        const double t = x >= 0.0 ? (a + x) / c : c / (a - x);
        const double term = t * t / (a2 + t * t);
        sum += (i == 0 || i == kSteps) ? 0.5 * term : term;
    }
    return sum / kSteps;
}

void CacheShare::init(float alpha) {
    for (int i = 0; i < kNodes; ++i)
        at_node[i] = static_cast<float>(
            cache_share_exact(alpha, static_cast<float>(i) / static_cast<float>(kNodes - 1)));
}

float CacheShare::at(float cos_o) const {
    const float x = std::clamp(cos_o, 0.0f, 1.0f) * static_cast<float>(kNodes - 1);
    const int i = std::min(static_cast<int>(x), kNodes - 2);
    const float f = x - static_cast<float>(i);
    return at_node[i] + f * (at_node[i + 1] - at_node[i]);
}

}  // namespace spangle::flake
