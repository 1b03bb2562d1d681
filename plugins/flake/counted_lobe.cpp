#include "counted_lobe.h"

#include <algorithm>
#include <cmath>

namespace spangle::flake {

void DirectionGrid::init(float alpha_, float gamma_rad) {
    alpha = alpha_;
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
    // The cone's preimage holds about kappa^2 of the square of normals at the highlight
    // (kappa = tan(gamma/2) / alpha); leaves of half of that: 4^-depth = kappa^2 / 2.
    const float kappa = std::tan(0.5f * gamma_rad) / alpha;
    depth = std::clamp(static_cast<int>(std::lround(0.5f + std::log2(1.0f / kappa))), 1, 7);
    weight_level = std::min(kWeightLevel, depth);
    const int nodes = 1 << weight_level;
    weight_normals.clear();
    for (int j = 0; j < nodes; ++j)
        for (int i = 0; i < nodes; ++i)
            for (int b = 0; b < 4; ++b)
                for (int a = 0; a < 4; ++a)
                    weight_normals.push_back(flake_normal(
                        alpha,
                        (static_cast<float>(4 * i + a) + 0.5f) / static_cast<float>(4 * nodes),
                        (static_cast<float>(4 * j + b) + 0.5f) / static_cast<float>(4 * nodes)));
    const int side = 1 << depth;
    centres.resize(static_cast<std::size_t>(side) * side);
    for (int j = 0; j < side; ++j)
        for (int i = 0; i < side; ++i)
            centres[static_cast<std::size_t>(j) * side + i] =
                flake_normal(alpha, (static_cast<float>(i) + 0.5f) / static_cast<float>(side),
                             (static_cast<float>(j) + 0.5f) / static_cast<float>(side));
}

int footprint_level(const FieldParams& fp, const Footprint& p) {
    const double s = 2.0 * std::max(p.half_width(), p.half_height());
    if (!(s > 0.0) || !std::isfinite(s)) return fp.max_depth;
    if (s >= 1.0) return 0;
    return std::clamp(static_cast<int>(std::floor(-std::log2(s))), 0, fp.max_depth);
}

NodeRef resolve_cell(const FieldParams& fp, int64_t tx, int64_t ty, int depth, uint32_t ix,
                     uint32_t iy) {
    const uint64_t tk = tile_key(fp.seed, tx, ty);
    NodeRef node{0, 0, 0, root_count(fp)};
    while (node.depth < depth && node.n > 0) {
        // A leaf of the tree holds its flakes itself: a cell inside it is not split further.
        if (static_cast<int>(node.n) <= fp.leaf_size || node.depth >= fp.max_depth) return node;
        const int shift = depth - node.depth - 1;
        uint32_t c[4];
        split_counts_cached(node_key(tk, node.depth, node.ix, node.iy), node.n, fp.exact_below, c);
        const uint32_t qx = (ix >> shift) & 1u, qy = (iy >> shift) & 1u;
        node = {node.depth + 1, 2 * node.ix + qx, 2 * node.iy + qy, c[qx | (qy << 1)]};
    }
    return node;
}

namespace {

/** Side of the square of leaves around wi's leaf that the tent can reach (2 x 4 + 1). */
constexpr int kBox = 9;
/** Splits of virtual flakes are exact multinomials below this count, normal approximations
 *  above (one hash either way). */
constexpr int kExactVirtual = 32;

/** The colour sum of a leaf's n flakes: the first kDrawn drawn from the table by hash, the rest
 *  at its mean. */
constexpr uint32_t kDrawn = 8;
void leaf_colours(uint64_t leaf_key, uint32_t n, const ColorTable& colors, float out[3]) {
    if (colors.cdf.empty()) {
        for (int c = 0; c < 3; ++c) out[c] = static_cast<float>(n) * colors.single[c];
        return;
    }
    const uint32_t drawn = std::min(n, kDrawn);
    const auto rest = static_cast<float>(n - drawn);
    for (int c = 0; c < 3; ++c) out[c] = rest * colors.mean[c];
    for (uint32_t i = 0; i < drawn; ++i) {
        const float* col = colors.pick(static_cast<float>(mix(leaf_key, i) >> 40) * 0x1p-24f);
        for (int c = 0; c < 3; ++c) out[c] += col[c];
    }
}

/** A stratified split of n among four children: each gets floor(n / 4), the remaining n mod 4
 *  go to distinct children in an order hashed from the key. Unbiased (each child expects n / 4),
 *  and adding a flake to n adds it to exactly one child. */
void split_stratified(uint64_t key, uint32_t n, uint32_t out[4]) {
    static const uint8_t kPerms[24][4] = {
        {0, 1, 2, 3}, {0, 1, 3, 2}, {0, 2, 1, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {0, 3, 2, 1},
        {1, 0, 2, 3}, {1, 0, 3, 2}, {1, 2, 0, 3}, {1, 2, 3, 0}, {1, 3, 0, 2}, {1, 3, 2, 0},
        {2, 0, 1, 3}, {2, 0, 3, 1}, {2, 1, 0, 3}, {2, 1, 3, 0}, {2, 3, 0, 1}, {2, 3, 1, 0},
        {3, 0, 1, 2}, {3, 0, 2, 1}, {3, 1, 0, 2}, {3, 1, 2, 0}, {3, 2, 0, 1}, {3, 2, 1, 0}};
    const uint8_t* perm = kPerms[mix(key, 0x57) % 24];
    for (int c = 0; c < 4; ++c) out[c] = n / 4;
    for (uint32_t r = 0; r < n % 4; ++r) ++out[perm[r]];
}

/** The split of a node of the direction tree at `level`: upper levels stratified, so that the
 *  aggregate's flakes spread evenly over the broad directions; the rest a multinomial, the local
 *  grain of real flakes. Sparse nodes (under 16 flakes) are stratified too: a hard-core spread of
 *  few flakes is as grainy as a Poisson one, and keeps the energy exact where it would otherwise
 *  fluctuate most. Virtual flakes are statistical stand-ins: exact splits only where they are one
 *  hash. */
void split_direction_node(int level, uint64_t key, uint32_t n, int exact_below, uint32_t c[4]) {
    if (level == 0 || n < 16)
        split_stratified(key, n, c);
    else
        split_counts_cached(key, n, std::min(exact_below, kExactVirtual), c);
}

/** The key of the direction tree's root of aggregate a; a child's key is its parent's hashed with
 *  the child index, a pure function of the path. */
uint64_t direction_root(const Aggregate& a) {
    return mix(a.key, 0xd1ec);
}

/** Tent-weighted colour sum of aggregate a's flakes in the leaves around wi (weights `tau`, a
 *  kBox-wide grid whose first entry is leaf (i0, j0)), descending its direction tree level by
 *  level through the nodes over [i0, i1] x [j0, j1] only. */
void weighted_colours(const Aggregate& a, const DirectionGrid& grid, const ColorTable& colors,
                      int exact_below, const float* tau, int i0, int i1, int j0, int j1,
                      float sum[3]) {
    constexpr int kMax = 4 * kBox * kBox;
    uint32_t ni[2][kMax], nj[2][kMax], nn[2][kMax];
    uint64_t nk[2][kMax];
    int count = 1, cur = 0;
    ni[0][0] = nj[0][0] = 0;
    nn[0][0] = a.count;
    nk[0][0] = direction_root(a);
    for (int level = 0; level < grid.depth; ++level) {
        const int shift = grid.depth - level - 1;
        int next = 0;
        for (int k = 0; k < count; ++k) {
            uint32_t c[4];
            split_direction_node(level, nk[cur][k], nn[cur][k], exact_below, c);
            for (uint32_t q = 0; q < 4; ++q) {
                if (c[q] == 0) continue;
                const uint32_t ci = 2 * ni[cur][k] + (q & 1u), cj = 2 * nj[cur][k] + (q >> 1);
                const auto lo_i = static_cast<int>(ci << shift),
                           lo_j = static_cast<int>(cj << shift);
                if (lo_i + (1 << shift) - 1 < i0 || lo_i > i1 || lo_j + (1 << shift) - 1 < j0 ||
                    lo_j > j1 || next >= kMax)
                    continue;
                ni[1 - cur][next] = ci;
                nj[1 - cur][next] = cj;
                nn[1 - cur][next] = c[q];
                nk[1 - cur][next] = mix(nk[cur][k], 1 + q);
                ++next;
            }
        }
        cur = 1 - cur;
        count = next;
    }
    for (int k = 0; k < count; ++k) {
        const float w =
            tau[(static_cast<int>(nj[cur][k]) - j0) * kBox + (static_cast<int>(ni[cur][k]) - i0)];
        if (w <= 0.0f) continue;
        float col[3];
        leaf_colours(nk[cur][k], nn[cur][k], colors, col);
        for (int c = 0; c < 3; ++c) sum[c] += w * col[c];
    }
}

}  // namespace

void node_weights(const DirectionGrid& grid, V3 wo, float out[DirectionGrid::kWeightNodes]) {
    const int nodes = 1 << (2 * grid.weight_level);
    for (int n = 0; n < nodes; ++n) {
        float sum = 0.0f;
        for (int s = 0; s < 16; ++s) {
            const V3 m = grid.weight_normals[static_cast<std::size_t>(16 * n + s)];
            const float c = mf::dot(wo, m);
            if (c > 0.0f && 2.0f * c * m.z - wo.z > 0.0f) sum += c / m.z;
        }
        out[n] = sum * (1.0f / 16.0f);
    }
}

float realised_weight(const Aggregate& a, const DirectionGrid& grid,
                      const float node_w[DirectionGrid::kWeightNodes], int exact_below) {
    // Breadth-first to weight_level (at most 1 + 4 + 16 nodes), in the row-major order of the
    // level's nodes.
    const int levels = grid.weight_level, side = 1 << levels;
    uint32_t n[DirectionGrid::kWeightNodes] = {a.count};
    uint64_t key[DirectionGrid::kWeightNodes] = {direction_root(a)};
    for (int level = 0; level < levels; ++level) {
        const int w = 1 << level;
        uint32_t n2[DirectionGrid::kWeightNodes];
        uint64_t key2[DirectionGrid::kWeightNodes];
        for (int j = 0; j < w; ++j)
            for (int i = 0; i < w; ++i) {
                uint32_t c[4];
                const uint64_t k = key[j * w + i];
                split_direction_node(level, k, n[j * w + i], exact_below, c);
                for (uint32_t q = 0; q < 4; ++q) {
                    const int ci = 2 * i + static_cast<int>(q & 1u),
                              cj = 2 * j + static_cast<int>(q >> 1);
                    n2[cj * 2 * w + ci] = c[q];
                    key2[cj * 2 * w + ci] = mix(k, 1 + q);
                }
            }
        std::copy(n2, n2 + 4 * w * w, n);
        std::copy(key2, key2 + 4 * w * w, key);
    }
    float realised = 0.0f, expected = 0.0f;
    for (int i = 0; i < side * side; ++i) {
        realised += static_cast<float>(n[i]) * node_w[i];
        expected += node_w[i];
    }
    expected *= static_cast<float>(a.count) / static_cast<float>(side * side);
    return expected > 0.0f ? realised / expected : 1.0f;
}

void aggregate_modulation(const CountedFootprint& cf, const DirectionGrid& grid,
                          const ColorTable& colors, V3 wo, V3 wi, int exact_below, float out[3]) {
    out[0] = out[1] = out[2] = 0.0f;
    if (cf.n_agg == 0 || !(wi.z > 0.0f) || !(wo.z > 0.0f)) return;
    V3 h = wo + wi;
    if (!(h.z > 0.0f)) return;
    h = mf::normalize(h);
    float s, t;
    flake_square(grid.alpha, h, s, t);
    const int side = 1 << grid.depth;
    const int ci = std::clamp(static_cast<int>(s * static_cast<float>(side)), 0, side - 1);
    const int cj = std::clamp(static_cast<int>(t * static_cast<float>(side)), 0, side - 1);
    const auto centre = [&](int i, int j) {
        return mf::reflect(wo, grid.centres[static_cast<std::size_t>(j) * side + i]);
    };
    // The local size of a leaf in reflected directions (chord), from its neighbours.
    const V3 r0 = centre(ci, cj);
    const V3 rx = centre(ci + (ci + 1 < side ? 1 : -1), cj);
    const V3 ry = centre(ci, cj + (cj + 1 < side ? 1 : -1));
    const float leaf2 = std::max(mf::dot(rx - r0, rx - r0), mf::dot(ry - r0, ry - r0));
    // Tent radius: the cone widened by a leaf, and at least past the centre of the leaf holding
    // wi's half vector (leaves are large where the square maps to the distribution's tail), so
    // that some leaf always lights wi. Any radius that depends only on wi keeps E[M] = 1.
    const V3 d_own = wi - r0;
    const float radius2 = 4.0f * grid.sin2_half + std::max(leaf2, 2.0f * mf::dot(d_own, d_own));
    const int b = std::clamp(
        static_cast<int>(std::ceil(std::sqrt(radius2 / std::max(leaf2, 1e-30f)))) + 1, 1, 4);
    float tau_grid[kBox * kBox];
    int n_near = 0;
    float expected = 0.0f;  // sum of tau over the leaves: the count's expectation / (k 4^-depth)
    int i0 = side, i1 = -1, j0 = side, j1 = -1;
    // Leaf centres move almost linearly with the leaf index near wi: skip those the linear map
    // puts well beyond the tent (by 1.5x, to absorb the map's curvature), test the rest exactly.
    const V3 ex = rx - r0, ey = ry - r0;
    const float sx = ci + 1 < side ? 1.0f : -1.0f, sy = cj + 1 < side ? 1.0f : -1.0f;
    const V3 d0 = wi - r0;
    const int bi0 = std::max(0, ci - b), bj0 = std::max(0, cj - b);
    std::fill(tau_grid, tau_grid + kBox * kBox, 0.0f);
    for (int j = bj0; j <= std::min(side - 1, cj + b); ++j)
        for (int i = bi0; i <= std::min(side - 1, ci + b); ++i) {
            const V3 guess = d0 - ex * (sx * static_cast<float>(i - ci)) -
                             ey * (sy * static_cast<float>(j - cj));
            if (mf::dot(guess, guess) > 2.25f * radius2) continue;
            const V3 d = wi - centre(i, j);
            const float tau = 1.0f - mf::dot(d, d) / radius2;
            if (tau <= 0.0f) continue;
            tau_grid[(j - bj0) * kBox + (i - bi0)] = tau;
            ++n_near;
            expected += tau;
            i0 = std::min(i0, i);
            i1 = std::max(i1, i);
            j0 = std::min(j0, j);
            j1 = std::max(j1, j);
        }
    if (n_near == 0 || !(expected > 0.0f)) return;
    float sum[3] = {0, 0, 0};
    // The tau grid is indexed from (bi0, bj0); the descent only visits leaves in [i0, i1] x [j0,
    // j1].
    const float* tau0 = tau_grid + (j0 - bj0) * kBox + (i0 - bi0);
    for (uint32_t a = 0; a < cf.n_agg; ++a)
        weighted_colours(cf.agg[a], grid, colors, exact_below, tau0, i0, i1, j0, j1, sum);
    // sum_a k_a M_a = sum_a (tau-weighted colour sum of a) / (sum tau 4^-depth).
    const float k = 1.0f / (expected * std::ldexp(1.0f, -2 * grid.depth));
    for (int c = 0; c < 3; ++c) out[c] = sum[c] * k;
}

}  // namespace spangle::flake
