#include "render/lights.h"

#include <cmath>

namespace spangle {

void LightTable::finalize() {
    std::vector<double> power(emitters_.size());
    for (std::size_t i = 0; i < emitters_.size(); ++i) {
        const AreaEmitter& e = emitters_[i];
        power[i] = static_cast<double>(luminance(e.radiance)) * static_cast<double>(e.area) *
                   (e.two_sided ? 2.0 : 1.0);
    }
    selection_ = Distribution1D(power);
}

Vec3 LightTable::emitted(uint32_t i, Vec3 w) const {
    const AreaEmitter& e = emitters_[i];
    const float c = dot(e.n, w);
    return (c > 0.0f || (e.two_sided && c < 0.0f)) ? e.radiance : Vec3(0.0f);
}

LightSample LightTable::sample(Vec3 p, float u0, float u1, float u2) const {
    LightSample s;
    if (selection_.empty()) return s;
    const uint32_t i = selection_.sample(u0);
    const AreaEmitter& e = emitters_[i];
    Vec3 q;
    if (e.parallelogram) {
        q = e.p0 + e.e1 * u1 + e.e2 * u2;
    } else {
        // Uniform point on a triangle: b0 = 1 - sqrt(u1), b1 = u2 sqrt(u1).
        const float r = std::sqrt(u1);
        q = e.p0 + e.e1 * (r * (1.0f - u2)) + e.e2 * (r * u2);
    }
    const Vec3 d = q - p;
    const float dist2 = dot(d, d);
    if (!(dist2 > 0.0f)) return s;
    const float dist = std::sqrt(dist2);
    const Vec3 wi = d / dist;
    const float cos_l = std::fabs(dot(e.n, wi));
    const Vec3 le = emitted(i, -wi);
    if (!(cos_l > 0.0f) || max_component(le) <= 0.0f) return s;
    s.wi = wi;
    s.dist = dist;
    s.radiance = le;
    s.pdf = selection_.pmf(i) * dist2 / (cos_l * e.area);
    return s;
}

float LightTable::pdf(uint32_t i, Vec3 p, Vec3 q) const {
    const AreaEmitter& e = emitters_[i];
    const Vec3 d = q - p;
    const float dist2 = dot(d, d);
    const float cos_l = std::fabs(dot(e.n, d)) / std::sqrt(dist2);
    if (!(cos_l > 0.0f) || !(dist2 > 0.0f)) return 0.0f;
    return selection_.pmf(i) * dist2 / (cos_l * e.area);
}

}  // namespace spangle
