#pragma once
// The stochastic mirror-flake model of Atanasov and Koylazov (SIGGRAPH 2016 Talks), as specified
// in ../shared/FLAKES.md: flakes are pure functions of (seed, uv tile, quad-tree node, index),
// counted inside a pixel footprint by a quad-tree with counter-based multinomial splits, and
// turned into a reflection cache of mirror directions. Plain C++ (no ABI types) so that tests can
// reach every piece; flake.cpp wraps it behind the material ABI.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "../common/microfacet.h"

namespace spangle::flake {

using mf::V3;

/** Counter-based hash of two words (a 64-bit finaliser with full avalanche). Flakes are pure
 *  functions of these hashes. The engine has its own (core/hash.h): a plugin includes nothing of
 *  the engine but plugin.h, and calling the host's hash2 through a function pointer per flake
 *  would cost more than the hash. */
inline uint64_t mf_hash(uint64_t a, uint64_t b) {
    uint64_t x = (a + 0x9e3779b97f4a7c15ull) * 0xbf58476d1ce4e5b9ull ^ (b + 0x632be59bd9b4e019ull);
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    x ^= x >> 31;
    return x;
}

/** Uniform double in [0, 1) from the top 53 bits. */
inline double mf_unit(uint64_t h) {
    return static_cast<double>(h >> 11) * 0x1p-53;
}

/** The footprint parallelogram P = c + s a + t b, s, t in [-1/2, 1/2], in uv. */
struct Footprint {
    double cu = 0, cv = 0;  ///< centre
    double ax = 0, ay = 0;  ///< axis a = (du/dx, dv/dx) x footprint_scale
    double bx = 0, by = 0;  ///< axis b = (du/dy, dv/dy) x footprint_scale
    double i00 = 0, i01 = 0, i10 = 0,
           i11 = 0;  ///< inverse of [a b]: uv offset -> (s, t); 0 if singular
    double area() const { return ax * by - ay * bx < 0 ? -(ax * by - ay * bx) : ax * by - ay * bx; }
};

/** Footprint from uv derivatives, scaled and with the ratio of its principal axes clamped to
 *  max_ratio (widening the minor axis, keeping the centre): this bounds skew and needles alike. */
Footprint make_footprint(double u, double v, double dudx, double dvdx, double dudy, double dvdy,
                         double scale, double max_ratio = 4.0);

/** One flake: where it is and which way it faces. */
struct Flake {
    double u = 0, v = 0;  ///< position in uv (absolute, tile included)
    V3 m;                 ///< normal, local shading frame
    float color_u = 0;    ///< uniform number that picks its colour-table entry
};

/** Settings of the flake field (everything that decides which flakes exist). */
struct FieldParams {
    uint64_t seed = 0;           ///< material seed
    double flakes_per_tile = 0;  ///< N: expected count in one uv unit square
    float alpha = 0.1f;          ///< GGX roughness of the flake normal distribution
    int leaf_size = 16;          ///< nodes with at most this many flakes are leaves
    int max_depth = 12;          ///< deepest level of the quad-tree
    int exact_below = 128;       ///< binomials with n below this are sampled exactly
};

/** Deterministic binomial sample B(n, p) from two uniforms: exact inversion when n < exact_below,
 *  otherwise the normal approximation rounded and clamped to [0, n]. */
uint32_t binomial(uint32_t n, double p, double u0, double u1, int exact_below);

/** Splits n flakes among a node's four children: n0 ~ B(n, 1/4), n1 ~ B(n - n0, 1/3),
 *  n2 ~ B(n - n0 - n1, 1/2), n3 = the rest; random numbers from the node's key. */
void split_counts(uint64_t node_key, uint32_t n, int exact_below, uint32_t out[4]);

/** split_counts memoised per thread (same results, less time). */
void split_counts_cached(uint64_t node_key, uint32_t n, int exact_below, uint32_t out[4]);

/** Key of a quad-tree node: a pure function of seed, tile, depth and cell. */
uint64_t node_key(uint64_t tile_key, int depth, uint32_t ix, uint32_t iy);

/** Key of a uv tile. */
uint64_t tile_key(uint64_t seed, int64_t tx, int64_t ty);

/** Enumerates the flakes inside P, calling visit(const Flake&) for each, stopping after
 *  max_flakes of them. Returns the number visited (at most max_flakes) and sets `truncated`
 *  when more existed. Visits at most 64 uv tiles; a footprint spanning more sets `truncated`. */
template <class Visit>
uint32_t for_each_flake(const FieldParams& fp, const Footprint& p, uint32_t max_flakes,
                        bool& truncated, Visit&& visit);

/** Whether (u, v) lies inside P (in P's own coordinates, in double). */
bool inside(const Footprint& p, double u, double v);

/** Whether the cell [x0, x1] x [y0, y1] intersects P (separating axes, in double). */
bool overlaps(const Footprint& p, double x0, double y0, double x1, double y1);

/** Samples a flake normal with density D(m) (m.z) for GGX roughness alpha. */
V3 sample_flake_normal(float alpha, float u0, float u1);

/** One entry of a reflection cache. */
struct CacheEntry {
    V3 r;          ///< mirror direction reflect(wo, m), local frame
    float rgb[3];  ///< w_j c_j F_j
    float lum;     ///< luminance of rgb (the sampling weight)
    float w;       ///< w_j = (wo.m_j) / (m_j.n), the flake's projected area towards wo
};

/** The discrete lobe of one shading point: the cache, its weights and a cumulative luminance
 *  table for sampling. The arrays live elsewhere (the host's arena). */
struct DiscreteLobe {
    const CacheEntry* entries = nullptr;
    const float* cdf = nullptr;  ///< cdf[i] = luminance of entries 0..i, unnormalised
    uint32_t count = 0;
    float w_sum = 0;    ///< W = sum of w_j
    float lum_sum = 0;  ///< sum of luminance(w_j c_j F_j) = cdf[count - 1]
};

/** Cone geometry shared by eval, sample and pdf. */
struct Cone {
    float sin2_half = 0;    ///< sin^2(gamma / 2)
    float threshold = 0;    ///< |wi - r|^2 <= 4 sin^2(gamma / 2) means wi is in the cone
    float solid_angle = 0;  ///< sigma = 4 pi sin^2(gamma / 2)
    explicit Cone(float gamma_rad);
    Cone() = default;
};

/** f (RGB, before G1(wi)) and pdf of the discrete lobe at wi. */
void eval_discrete(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float f[3], float& pdf);

/** Samples wi from the discrete lobe: a flake by luminance (u0), then a direction uniform in its
 *  cone (u1, u2). Returns false when the lobe is empty or wi falls below the horizon. */
bool sample_discrete(const DiscreteLobe& lobe, const Cone& cone, float u0, float u1, float u2,
                     V3& wi);

// ------------------------------------------------------------------------------------ template

template <class Visit>
uint32_t for_each_flake(const FieldParams& fp, const Footprint& p, uint32_t max_flakes,
                        bool& truncated, Visit&& visit) {
    truncated = false;
    const double hx = 0.5 * ((p.ax < 0 ? -p.ax : p.ax) + (p.bx < 0 ? -p.bx : p.bx));
    const double hy = 0.5 * ((p.ay < 0 ? -p.ay : p.ay) + (p.by < 0 ? -p.by : p.by));
    const double u0 = p.cu - hx, u1 = p.cu + hx, v0 = p.cv - hy, v1 = p.cv + hy;
    const auto tx0 = static_cast<int64_t>(std::floor(u0)),
               tx1 = static_cast<int64_t>(std::floor(u1));
    const auto ty0 = static_cast<int64_t>(std::floor(v0)),
               ty1 = static_cast<int64_t>(std::floor(v1));
    if ((tx1 - tx0 + 1) * (ty1 - ty0 + 1) > 64) {
        truncated = true;
        return 0;
    }
    const auto root_n = static_cast<uint32_t>(std::min(fp.flakes_per_tile + 0.5, 2147483647.0));
    uint32_t visited = 0;
    struct Node {
        int depth;
        uint32_t ix, iy, n;
    };
    Node stack[4 * 25];
    for (int64_t ty = ty0; ty <= ty1; ++ty)
        for (int64_t tx = tx0; tx <= tx1; ++tx) {
            const uint64_t tk = tile_key(fp.seed, tx, ty);
            // The footprint relative to this tile's origin.
            Footprint local = p;
            local.cu -= static_cast<double>(tx);
            local.cv -= static_cast<double>(ty);
            int top = 0;
            stack[top++] = {0, 0, 0, root_n};
            while (top > 0) {
                const Node node = stack[--top];
                if (node.n == 0) continue;
                const double size = std::ldexp(1.0, -node.depth);
                const double x0 = node.ix * size, y0 = node.iy * size;
                if (!overlaps(local, x0, y0, x0 + size, y0 + size)) continue;
                const uint64_t key = node_key(tk, node.depth, node.ix, node.iy);
                if (static_cast<int>(node.n) <= fp.leaf_size || node.depth >= fp.max_depth) {
                    for (uint32_t i = 0; i < node.n; ++i) {
                        const uint64_t h = mf_hash(key, i);
                        const double fu = x0 + size * mf_unit(mf_hash(h, 0));
                        const double fv = y0 + size * mf_unit(mf_hash(h, 1));
                        if (!inside(local, fu, fv)) continue;
                        if (visited >= max_flakes) {
                            truncated = true;
                            return visited;
                        }
                        Flake f;
                        f.u = fu + static_cast<double>(tx);
                        f.v = fv + static_cast<double>(ty);
                        f.m = sample_flake_normal(fp.alpha,
                                                  static_cast<float>(mf_unit(mf_hash(h, 2))),
                                                  static_cast<float>(mf_unit(mf_hash(h, 3))));
                        f.color_u = static_cast<float>(mf_unit(mf_hash(h, 4)));
                        visit(f);
                        ++visited;
                    }
                    continue;
                }
                uint32_t child[4];
                split_counts_cached(key, node.n, fp.exact_below, child);
                for (uint32_t c = 0; c < 4; ++c)
                    stack[top++] = {node.depth + 1, 2 * node.ix + (c & 1u), 2 * node.iy + (c >> 1),
                                    child[c]};
            }
        }
    return visited;
}

}  // namespace spangle::flake
