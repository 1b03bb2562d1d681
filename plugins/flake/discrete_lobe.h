#pragma once
// The discrete flake lobe of one shading point (Atanasov and Koylazov 2016): a reflection cache of
// the flakes in the footprint, each a mirror reflecting wo into a cone of half-angle gamma around
// r_j = reflect(wo, m_j), weighted by its projected area towards wo, w_j = (wo.m_j) / (m_j.n):
//
//     f(wo, wi) = sum over j with wi in cone_j of w_j c_j F_j / (W sigma cos(theta_i))
//
// (times G1(wi) when shadowing is on), W = sum of w_j, sigma = 4 pi sin^2(gamma/2). Normalising
// by the actual W makes each footprint reflect exactly the mean F c of its flakes. Flakes facing
// away from wo or reflecting under the horizon are skipped. Sampling picks a flake by luminance
// (binary search in a cumulative table), then a direction uniform in its cone.

#include <cstdint>

#include "field.h"
#include "palette.h"

namespace spangle::flake {

/** One entry of a reflection cache. */
struct CacheEntry {
    V3 r;          ///< mirror direction reflect(wo, m), local frame
    float rgb[3];  ///< w_j c_j F_j (or a weight times a mean, for the counted lobe's aggregates)
    float lum;     ///< luminance of rgb (the sampling weight)
    float w;       ///< w_j, the flake's projected area towards wo
};

/** The cache entry of a flake of normal m seen from wo with colour col, its rgb, lum and w then
 *  multiplied by `scale` (a stand-in's share, a facet's cover); false when the flake faces away
 *  from wo or reflects under the horizon (it is skipped). Write e where it is to stay (in the
 *  cache itself): copied right after these scalar stores, it stalled on store forwarding. */
bool make_entry(V3 wo, V3 m, const float col[3], const FresnelTable& fresnel, CacheEntry& e,
                float scale = 1.0f);

/** The discrete lobe of one shading point: the cache, its weights and a cumulative luminance
 *  table for sampling. The arrays live in the host's per-batch arena. */
struct DiscreteLobe {
    const CacheEntry* entries = nullptr;
    const float* cdf = nullptr;  ///< cdf[i] = luminance of entries 0..i, unnormalised
    uint32_t count = 0;
    float w_sum = 0;    ///< W = sum of w_j
    float lum_sum = 0;  ///< cdf[count - 1]
};

/** Cone geometry shared by eval, sample and pdf. */
struct Cone {
    float sin2_half = 0;    ///< sin^2(gamma / 2)
    float threshold = 0;    ///< |wi - r|^2 <= 4 sin^2(gamma / 2) means wi is in the cone
    float solid_angle = 0;  ///< sigma = 4 pi sin^2(gamma / 2)
    explicit Cone(float gamma_rad);
    Cone() = default;
};

/** Sum of rgb and of lum over the cache entries whose cone holds wi. */
void cone_sums(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float rgb[3], float& lum);

/** f (RGB, before G1(wi)) and pdf of the discrete lobe at wi, normalised by `norm` (W for the
 *  enumerated lobe) and the cache's own luminance for the pdf. */
void eval_discrete(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float norm, float f[3],
                   float& pdf);

/** Samples wi from the cache: an entry by luminance (u0), then a direction uniform in its cone
 *  (u1, u2). False when the cache is empty or wi falls under the horizon. */
bool sample_discrete(const DiscreteLobe& lobe, const Cone& cone, float u0, float u1, float u2,
                     V3& wi);

/** A direction uniform in the cone of half-angle gamma (sin^2(gamma/2) given) around unit r. */
V3 sample_cone(V3 r, float sin2_half, float c0, float c1);

}  // namespace spangle::flake
