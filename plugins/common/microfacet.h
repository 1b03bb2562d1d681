#pragma once
// Microfacet and Fresnel mathematics shared by Spangle's material plugins (header-only, plugin
// side of the ABI: the engine never includes it).
//
// Local shading frame: z = normal, directions unit length. The GGX (Trowbridge-Reitz)
// distribution is anisotropic with roughness alpha_x along x and alpha_y along y.
// References: Walter et al. 2007 "Microfacet Models for Refraction through Rough Surfaces";
// Heitz 2014 "Understanding the Masking-Shadowing Function"; Heitz 2018 "Sampling the GGX
// Distribution of Visible Normals".

#include <algorithm>
#include <cmath>
#include <complex>

namespace spangle::mf {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;

/** Below this alpha a lobe is treated as a perfect mirror or interface (a delta lobe). */
constexpr float kDeltaAlpha = 1e-4f;

/** A small 3-vector for plugin-side maths. */
struct V3 {
    float x = 0, y = 0, z = 0;
};
inline V3 operator+(V3 a, V3 b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline V3 operator-(V3 a, V3 b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline V3 operator*(V3 a, float s) {
    return {a.x * s, a.y * s, a.z * s};
}
inline float dot(V3 a, V3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline V3 cross(V3 a, V3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline V3 normalize(V3 a) {
    const float l = std::sqrt(dot(a, a));
    return l > 0.0f ? a * (1.0f / l) : V3{0, 0, 1};
}
/** Mirror of w about n (both unit): 2 (w.n) n - w. */
inline V3 reflect(V3 w, V3 n) {
    return n * (2.0f * dot(w, n)) - w;
}

/** Refracts w (pointing away from the surface, on n's side) through a surface with relative
 *  index eta = eta_transmitted / eta_incident. Returns false on total internal reflection. */
inline bool refract(V3 w, V3 n, float eta, V3& wt) {
    const float cos_i = dot(n, w);
    const float sin2_t = std::max(0.0f, 1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return false;
    const float cos_t = std::sqrt(1.0f - sin2_t);
    wt = w * (-1.0f / eta) + n * (cos_i / eta - cos_t);
    return true;
}

/** GGX normal distribution D(h) for h in the local frame. */
inline float ggx_d(V3 h, float ax, float ay) {
    if (h.z <= 0.0f) return 0.0f;
    const float x = h.x / ax, y = h.y / ay;
    const float k = x * x + y * y + h.z * h.z;
    return 1.0f / (kPi * ax * ay * k * k);
}

/** Smith Lambda for GGX. */
inline float ggx_lambda(V3 w, float ax, float ay) {
    const float z2 = w.z * w.z;
    if (z2 <= 0.0f) return 0.0f;
    const float a2t2 = (ax * ax * w.x * w.x + ay * ay * w.y * w.y) / z2;
    return 0.5f * (std::sqrt(1.0f + a2t2) - 1.0f);
}

/** Smith masking G1(w). */
inline float ggx_g1(V3 w, float ax, float ay) {
    return 1.0f / (1.0f + ggx_lambda(w, ax, ay));
}

/** Height-correlated masking-shadowing G2(wo, wi). */
inline float ggx_g2(V3 wo, V3 wi, float ax, float ay) {
    return 1.0f / (1.0f + ggx_lambda(wo, ax, ay) + ggx_lambda(wi, ax, ay));
}

/** Density of visible normals D_wo(h) = G1(wo) max(0, wo.h) D(h) / wo.z (wo.z > 0). */
inline float ggx_visible_d(V3 wo, V3 h, float ax, float ay) {
    const float c = dot(wo, h);
    if (c <= 0.0f || wo.z <= 0.0f) return 0.0f;
    return ggx_g1(wo, ax, ay) * c * ggx_d(h, ax, ay) / wo.z;
}

/** Samples a visible normal for wo (wo.z > 0) with uniform u1, u2 (Heitz 2018). */
inline V3 ggx_sample_visible(V3 wo, float ax, float ay, float u1, float u2) {
    const V3 vh = normalize({ax * wo.x, ay * wo.y, wo.z});
    const float len2 = vh.x * vh.x + vh.y * vh.y;
    const V3 t1 = len2 > 0.0f ? V3{-vh.y, vh.x, 0.0f} * (1.0f / std::sqrt(len2)) : V3{1, 0, 0};
    const V3 t2 = cross(vh, t1);
    const float r = std::sqrt(u1);
    const float phi = 2.0f * kPi * u2;
    const float p1 = r * std::cos(phi);
    float p2 = r * std::sin(phi);
    const float s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * std::sqrt(std::max(0.0f, 1.0f - p1 * p1)) + s * p2;
    const V3 nh = t1 * p1 + t2 * p2 + vh * std::sqrt(std::max(0.0f, 1.0f - p1 * p1 - p2 * p2));
    return normalize({ax * nh.x, ay * nh.y, std::max(1e-7f, nh.z)});
}

/** Reflection sampling of GGX that spends no sample on normals whose mirror direction surely
 *  lies below the horizon (bounded VNDF sampling, Eto and Tokuyoshi 2023, on Dupuy and
 *  Benyoub's spherical-cap form of the visible normals, 2023).
 *
 *  In the stretched configuration (alpha 1) a visible normal is wo_s + o, o uniform on the
 *  sphere's cap z >= -wo_s.z, and o is the mirror direction there. The part of the cap below
 *  z = -k wo_s.z holds only normals whose real mirror direction is under the horizon, for
 *  k = (1 - a^2) s^2 / (s^2 + a^2 wo.z^2), s = 1 + sin(theta_o), a = min(alpha_x, alpha_y, 1)
 *  (their Eq. 5-6; exact bound for an isotropic lobe, conservative for an anisotropic one), so
 *  sampling the smaller cap loses nothing and gives each kept normal more density. A rough lobe
 *  seen from above loses many of plain VNDF's samples under the horizon (a zero estimate each:
 *  alpha 1 head-on half of them, alpha 0.8 at cos 0.9 37%, alpha 0.5 at cos 0.7 18%; grazing
 *  views and sharp lobes few); here few are lost, and the estimate's weight f cos / pdf shrinks
 *  by (k wo.z + t) / (wo.z + t) where it is not zero. f is unchanged, only the pdf differs
 *  (the host's path regularisation reads the pdf, so with filter_glossy the image moves a
 *  little too). */
inline float ggx_bounded_k(V3 wo, float ax, float ay) {
    const float a = std::min(std::min(ax, ay), 1.0f);
    const float s = 1.0f + std::sqrt(std::max(0.0f, wo.x * wo.x + wo.y * wo.y));
    const float a2 = a * a, s2 = s * s;
    return (1.0f - a2) * s2 / (s2 + a2 * wo.z * wo.z);
}

/** A mirror direction wi for wo (wo.z > 0) from uniform u0, u1, drawn with density
 *  ggx_reflection_pdf (see ggx_bounded_k). May lie under the horizon (then it is no sample). */
inline V3 ggx_sample_reflection(V3 wo, float ax, float ay, float u0, float u1) {
    const V3 ws = normalize({ax * wo.x, ay * wo.y, wo.z});
    const float b = ggx_bounded_k(wo, ax, ay) * ws.z;
    const float z = (1.0f - u1) * (1.0f + b) - b;
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    const float phi = 2.0f * kPi * u0;
    const V3 m = ws + V3{r * std::cos(phi), r * std::sin(phi), z};
    const V3 h = normalize({ax * m.x, ay * m.y, std::max(1e-7f, m.z)});
    return reflect(wo, h);
}

/** Density (solid angle) of ggx_sample_reflection's wi = reflect(wo, h), for wo.z > 0 and h
 *  the half vector: D(h) / (2 (k wo.z + |(alpha_x wo.x, alpha_y wo.y, wo.z)|)); k = 1 gives
 *  plain VNDF's G1(wo) D(h) / (4 wo.z). */
inline float ggx_reflection_pdf(V3 wo, V3 h, float ax, float ay) {
    if (wo.z <= 0.0f) return 0.0f;
    const float t = std::sqrt(ax * ax * wo.x * wo.x + ay * ay * wo.y * wo.y + wo.z * wo.z);
    return ggx_d(h, ax, ay) / (2.0f * (ggx_bounded_k(wo, ax, ay) * wo.z + t));
}

/** Unpolarised Fresnel reflectance of a dielectric interface. cos_i is the cosine on the side
 *  of incidence, eta = eta_transmitted / eta_incident; negative cos_i swaps the sides. */
inline float fresnel_dielectric(float cos_i, float eta) {
    cos_i = std::clamp(cos_i, -1.0f, 1.0f);
    if (cos_i < 0.0f) {
        eta = 1.0f / eta;
        cos_i = -cos_i;
    }
    const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return 1.0f;
    const float cos_t = std::sqrt(1.0f - sin2_t);
    const float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5f * (r_par * r_par + r_perp * r_perp);
}

/** Unpolarised Fresnel reflectance of a conductor with complex index eta + i k (relative to the
 *  outside medium), for cos_i in [0, 1]. Computed in double: k can be large. */
inline float fresnel_conductor(float cos_i, float eta, float k) {
    using C = std::complex<double>;
    const double c = std::clamp(static_cast<double>(cos_i), 0.0, 1.0);
    const C n(eta, k);
    const C sin2_t = (1.0 - c * c) / (n * n);
    const C cos_t = std::sqrt(1.0 - sin2_t);
    const C r_par = (n * c - cos_t) / (n * c + cos_t);
    const C r_perp = (c - n * cos_t) / (c + n * cos_t);
    return static_cast<float>(0.5 * (std::norm(r_par) + std::norm(r_perp)));
}

/** Complex indices at the Rec.709 primaries' dominant wavelengths (about 630, 532, 465 nm),
 *  from published optical constants (Johnson and Christy 1972 for Au, Ag, Cu; Rakic 1995 for Al).
 */
struct MetalPreset {
    const char* name;
    float eta[3], k[3];
};
inline constexpr MetalPreset kMetalPresets[] = {
    {"gold", {0.183f, 0.421f, 1.373f}, {3.424f, 2.346f, 1.770f}},
    {"silver", {0.155f, 0.117f, 0.138f}, {4.828f, 3.122f, 2.147f}},
    {"copper", {0.200f, 0.924f, 1.102f}, {3.912f, 2.452f, 2.142f}},
    {"aluminium", {1.657f, 0.880f, 0.521f}, {9.224f, 6.270f, 4.837f}},
};

/** How much more often than its share of the reflected energy a lobe of GGX roughness `alpha`
 *  is chosen for a BSDF sample: 3x for a mirror, falling linearly to 1x at alpha 0.1. Light
 *  sampling carries most of what a wide lobe reflects of a small bright light (MIS gives it to
 *  the light's samples), but a lobe narrower than the light sees it almost only through its own
 *  BSDF samples: the sun's highlight in a clear coat is lit by the few samples that pick the
 *  coat, and its pixels' variance goes as 1 / (the coat's share). Measured on a clear-coated car
 *  under a sun (tests/bench/cycles_time_to_quality.py's, mean over seeds): the highlight's error
 *  2.1x lower at 64 spp, 1.7x at 256; the price, where no small light shines (a coated sphere
 *  under a constant sky alone), 13% more error in the wide lobes. (4x gave 2.3x and 21%, 2x
 *  1.5x and 6%.) Selection changes no expectation: sample() and pdf() use the same shares. */
inline float sharp_lobe_weight(float alpha) {
    constexpr float kMirror = 3.0f, kWide = 0.1f;
    return 1.0f + (kMirror - 1.0f) * std::max(0.0f, 1.0f - alpha / kWide);
}

/** Cosine-weighted hemisphere direction (concentric disk map, Shirley and Chiu 1997). */
inline V3 cosine_hemisphere(float u0, float u1) {
    const float a = 2.0f * u0 - 1.0f, b = 2.0f * u1 - 1.0f;
    float r = 0.0f, phi = 0.0f;
    if (a != 0.0f || b != 0.0f) {
        if (std::fabs(a) > std::fabs(b)) {
            r = a;
            phi = (kPi / 4.0f) * (b / a);
        } else {
            r = b;
            phi = kPi / 2.0f - (kPi / 4.0f) * (a / b);
        }
    }
    const float x = r * std::cos(phi), y = r * std::sin(phi);
    return {x, y, std::sqrt(std::max(0.0f, 1.0f - x * x - y * y))};
}

}  // namespace spangle::mf
