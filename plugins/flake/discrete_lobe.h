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

#include <algorithm>
#include <cstdint>
#include <vector>

#include "field.h"
#include "palette.h"

namespace spangle::flake {

class TableCache;

/** One entry of a reflection cache. */
struct CacheEntry {
    V3 r;          ///< mirror direction reflect(wo, m), local frame
    float rgb[3];  ///< w_j c_j F_j (or a weight times a mean, for the counted lobe's aggregates)
    float lum;     ///< luminance of rgb (the sampling weight)
    float w;       ///< w_j, the flake's projected area towards wo
};

/** Flakes waiting for their cache entries, as a structure of arrays so that their normals and
 *  mirror directions are computed many at a time (the compiler makes vector code of those
 *  loops): each flake's point of the unit square of normals (flake_normal), colour, Fresnel
 *  table and scale. */
struct EntryBatch {
    static constexpr uint32_t kSize = 64;
    uint32_t n = 0;
    float s[kSize], t[kSize], scale[kSize];
    const float* col[kSize];
    const FresnelTable* fresnel[kSize];
    bool marked[kSize];
    uint32_t entered_marked = 0;  ///< flakes flushed with an entry that were marked (add's `mark`)
    /** Queues a flake; flushes (into out) first when the batch is full. */
    inline void add(V3 wo, float alpha, float s_, float t_, const float* col_,
                    const FresnelTable* fr, float scale_, std::vector<CacheEntry>& out,
                    bool mark = false);
};

/** Appends to `out`, in order, the cache entries of the batch's flakes seen from wo, and empties
 *  the batch. A flake of normal m = flake_normal(alpha, s, t) and colour c has the entry
 *  r = reflect(wo, m), w = (wo.m) / m.z, rgb = w c F(wo.m), lum its luminance, each times its
 *  scale (a stand-in's share, a facet's cover); a flake facing away from wo or reflecting it under
 *  the horizon has none (it is skipped). b.entered_marked counts the marked ones among those
 *  with an entry. */
void flush_entries(V3 wo, float alpha, EntryBatch& b, std::vector<CacheEntry>& out);

inline void EntryBatch::add(V3 wo, float alpha, float s_, float t_, const float* col_,
                            const FresnelTable* fr, float scale_, std::vector<CacheEntry>& out,
                            bool mark) {
    if (n == kSize) flush_entries(wo, alpha, *this, out);
    s[n] = s_;
    t[n] = t_;
    col[n] = col_;
    fresnel[n] = fr;
    scale[n] = scale_;
    marked[n] = mark;
    ++n;
}

/** The chance that a flake whose normal is drawn from D(m)(m.n) (GGX of roughness alpha) enters
 *  the reflection cache of a view of cos(theta_o) = cos_o: that it reflects wo above the
 *  horizon (which implies that it faces wo). A flake tilted by theta at azimuth phi from wo's
 *  plane does while theta < pi/4 + delta/2, tan(delta) = sin_o cos(phi) / cos_o, and GGX's
 *  tan(theta) = alpha rho / sqrt(1 - rho^2) for rho uniform in the unit disk, so
 *  P = 1/(2 pi) integral over phi of T^2 / (alpha^2 + T^2), T = tan(pi/4 + delta/2):
 *  1 / (1 + alpha^2) head-on, 1/2 at grazing. Trapezoid rule in phi (periodic: it converges
 *  fast). */
double cache_share_exact(float alpha, float cos_o);

/** Linear interpolation at x (clamped to [0, 1]) of n nodes tabulated at x = i / (n - 1). */
inline float interpolate_nodes(const float* node, int n, float x) {
    const float s = std::clamp(x, 0.0f, 1.0f) * static_cast<float>(n - 1);
    const int i = std::min(static_cast<int>(s), n - 2);
    const float f = s - static_cast<float>(i);
    return node[i] + f * (node[i + 1] - node[i]);
}

/** cache_share_exact() of one material, tabulated over cos_o and interpolated. */
struct CacheShare {
    static constexpr int kNodes = 129;
    float at_node[kNodes] = {};  ///< at cos_o = i / (kNodes - 1)
    void init(float alpha);
    float at(float cos_o) const;
};

/** How a footprint of few flakes is scaled so that footprints average to the far look. A
 *  footprint's lobe is normalised by its own W, so it reflects sum w_j a_j / sum w_j of its
 *  flakes' albedos a_j (F(wo.m_j), times G1 at the mirror direction with shadowing): one flake
 *  reflects its own albedo, and the plain mean over flakes is E[a], where the far look (and a
 *  footprint of many flakes) reflects E[w a] / E[w]. Where a depends on the tilt the two differ:
 *  dielectric flakes (Fresnel rising at grazing incidence, where w is small) read 1.3x the far
 *  look at lambda 0.5. With K flakes in the cache (drawn independently from the flakes that enter
 *  it), E[sum w a / sum w] = K integral over t > 0 of M(t) L(t)^(K-1) dt, L(t) = E[e^-tw],
 *  M(t) = E[w a e^-tw] (from 1/x = integral of e^-tx): tabulated per material over cos_o for K up
 *  to kMaxK by quadrature over the flake normals (log-spaced bins in w, the trapezoid rule in
 *  log t), beyond it E[w a] / E[w] + b / K. The scale is far / E[...] per channel (colours are
 *  drawn independently of the normal and cancel; so are a film's thicknesses, whose mean Fresnel
 *  the material passes); a scale above 1 is cut to what keeps the footprint's albedo at most 1
 *  (apply()), so no footprint reflects more than it receives. */
struct SparseAlbedo {
    static constexpr int kNodes = 65;  ///< cos_o = i / (kNodes - 1), the first at 1e-3
    static constexpr int kMaxK = 32;
    /** scale[i][k - 1][c]: K = k flakes at node i; tail[i][c]: b / far for K > kMaxK. */
    float scale[kNodes][kMaxK][3] = {};
    float tail[kNodes][3] = {};
    bool flat = true;  ///< every scale is 1: flakes reflect alike whatever their tilt
    /** For flakes of GGX roughness `roughness`, cone half-angle gamma_rad, Fresnel `fresnel`,
     *  with Smith shadowing G1(wi) or without. */
    void init(float roughness, float gamma_rad, const FresnelTable& fresnel, bool with_shadowing,
              const TableCache* cache = nullptr);
    /** The scale of a footprint of k flakes in the cache seen at cos_o. */
    void at(float cos_o, uint32_t k, float s[3]) const;
    /** Scales the entries [first, end) of a cache of k flakes (k >= its entries: the counted
     *  cells' flakes that enter the cache count too). A scale above 1 is kept to what leaves the
     *  footprint's albedo at most 1: the entries' rgb times G1 at each cone's direction nearest
     *  the normal (G1's largest over the cone), over their weight. A scale within 0.1% of 1 is
     *  not applied. */
    void apply(float cos_o, uint32_t k, CacheEntry* first, CacheEntry* end) const;
    /** Fills node i of the table (alpha and shadowing set). */
    void build_node(int i, const FresnelTable& fresnel);
    /** What apply() bounds a raise with: the roughness and cone of G1 (with shadowing). */
    float alpha = 0, cos_gamma = 1, sin_gamma = 0;
    bool shadowing = false;
};

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
