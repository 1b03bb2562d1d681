#include "counted_lobe.h"

#include <algorithm>
#include <cmath>

namespace spangle::flake {

/** The coarsest leaf level: 64 leaves. The modulation of a dense aggregate is the count of its
 *  leaves near wi against its expectation; with a cone wide against the flake lobe the level
 *  chosen by the cone's size was 1 (4 leaves, whose counts add up to k), and the modulation
 *  barely varied: a counted lobe 4-10x smoother between footprints than real flakes (gamma 6,
 *  alpha 0.1: CV 0.4-0.8% against 1.9-3.9%); at 3 it varies as theirs does. */
constexpr int kMinDepth = 3;

void DirectionGrid::init(float alpha_, float gamma_rad) {
    alpha = alpha_;
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
    // The cone's preimage holds about kappa^2 of the square of normals at the highlight
    // (kappa = tan(gamma/2) / alpha); leaves of half of that: 4^-depth = kappa^2 / 2.
    const float kappa = std::tan(0.5f * gamma_rad) / alpha;
    depth = std::clamp(static_cast<int>(std::lround(0.5f + std::log2(1.0f / kappa))), kMinDepth, 7);
    weight_level = std::min(kWeightLevel, depth);
    const int nodes = 1 << weight_level;
    weight_normals.clear();
    for (int j = 0; j < nodes; ++j)
        for (int i = 0; i < nodes; ++i)
            for (int b = 0; b < kWeightSide; ++b)
                for (int a = 0; a < kWeightSide; ++a)
                    weight_normals.push_back(
                        flake_normal(alpha,
                                     (static_cast<float>(kWeightSide * i + a) + 0.5f) /
                                         static_cast<float>(kWeightSide * nodes),
                                     (static_cast<float>(kWeightSide * j + b) + 0.5f) /
                                         static_cast<float>(kWeightSide * nodes)));
    const int side = 1 << depth;
    centres.resize(static_cast<std::size_t>(side) * side);
    for (int j = 0; j < side; ++j)
        for (int i = 0; i < side; ++i)
            centres[static_cast<std::size_t>(j) * side + i] =
                flake_normal(alpha, (static_cast<float>(i) + 0.5f) / static_cast<float>(side),
                             (static_cast<float>(j) + 0.5f) / static_cast<float>(side));
}

uint64_t place_key(uint64_t cell_key, const Footprint& local, double x0, double y0, double size) {
    // Grid spacing: the largest power-of-two fraction of the cell not above half the footprint's
    // half extent (at most 2^16 per side). Where the footprint is clipped by the cell's edge, two
    // neighbours' parts of the cell are centred closer than the footprints are: a grid as coarse
    // as the footprint put a sixth of such pairs in one place.
    const double half = std::max(local.half_width(), local.half_height());
    int q = 0;
    while (q < 16 && size * std::ldexp(1.0, -(q + 1)) >= 0.5 * half) ++q;
    const double step = size * std::ldexp(1.0, -q);
    // The centre of the part of the cell under the footprint's bounding box (a footprint whose
    // centre lies outside the cell is placed by the part it covers).
    const auto cell = [&](double c, double h, double origin) {
        const double lo = std::max(c - h, origin), hi = std::min(c + h, origin + size);
        return static_cast<uint64_t>(std::clamp(std::floor((0.5 * (lo + hi) - origin) / step), 0.0,
                                                std::ldexp(1.0, q) - 1.0));
    };
    return mix(
        mix(cell_key, 0x9a11 + static_cast<uint64_t>(q)),
        (cell(local.cu, local.half_width(), x0) << 20) | cell(local.cv, local.half_height(), y0));
}

int footprint_level(const FieldParams& fp, const Footprint& p) {
    const double s = 2.0 * std::max(p.half_width(), p.half_height());
    if (!(s > 0.0) || !std::isfinite(s)) return fp.max_depth;
    if (s >= 1.0) return 0;
    return std::clamp(static_cast<int>(std::floor(-std::log2(s))), 0, fp.max_depth);
}

NodeRef CellResolver::resolve(int64_t tx, int64_t ty, int depth, uint32_t ix, uint32_t iy) {
    if (levels_ == 0 || tx != tx_ || ty != ty_) {
        tx_ = tx;
        ty_ = ty;
        tile_ = tile_key(fp_.seed, tx, ty);
        path_[0] = {0, 0, 0, root_count(fp_)};
        levels_ = 1;
    }
    // The deepest kept node that is an ancestor of the cell (or the cell itself).
    int l = 0;
    while (l + 1 < levels_ && path_[l + 1].depth <= depth &&
           path_[l + 1].ix == (ix >> (depth - path_[l + 1].depth)) &&
           path_[l + 1].iy == (iy >> (depth - path_[l + 1].depth)))
        ++l;
    NodeRef node = path_[l];
    while (node.depth < depth && node.n > 0) {
        if (static_cast<int>(node.n) <= fp_.leaf_size || node.depth >= fp_.max_depth) break;
        const int shift = depth - node.depth - 1;
        uint32_t c[4];
        split_counts_cached(node_key(tile_, node.depth, node.ix, node.iy), node.n, fp_.exact_below,
                            c);
        const uint32_t qx = (ix >> shift) & 1u, qy = (iy >> shift) & 1u;
        node = {node.depth + 1, 2 * node.ix + qx, 2 * node.iy + qy, c[qx | (qy << 1)]};
        ++l;
        if (l < 32) path_[l] = node;
    }
    levels_ = std::min(l + 1, 32);
    return node;
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
    if (colors.cdf.empty() && colors.varied.empty()) {
        for (int c = 0; c < 3; ++c) out[c] = static_cast<float>(n) * colors.single[c];
        return;
    }
    const uint32_t drawn = std::min(n, kDrawn);
    const auto rest = static_cast<float>(n - drawn);
    for (int c = 0; c < 3; ++c) out[c] = rest * colors.mean[c];
    for (uint32_t i = 0; i < drawn; ++i) {
        const uint64_t id = mix(leaf_key, i);
        const float* col = colors.pick(static_cast<float>(id >> 40) * 0x1p-24f, id);
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

/** The split of a node of the direction tree down to the grid's leaves: a multinomial, the grain
 *  of real flakes (the aggregate's weight follows its realised spread, see realised_weight, so
 *  that its energy does not). Sparse nodes (under 16 flakes) are stratified: a hard-core spread of
 *  few flakes over the broad directions keeps the energy close where it would otherwise
 *  fluctuate most. Virtual flakes are statistical stand-ins: exact splits only where they are one
 *  hash. */
void split_direction_node(uint64_t key, uint32_t n, int exact_below, uint32_t c[4]) {
    if (n < 16)
        split_stratified(key, n, c);
    else
        split_counts_cached(key, n, std::min(exact_below, kExactVirtual), c);
}

/** The key of the direction tree's root of aggregate a; a child's key is its parent's hashed with
 *  the child index, a pure function of the path. */
uint64_t direction_root(const Aggregate& a) {
    return mix(a.key, 0xd1ec);
}

/** Descends aggregate a's direction tree level by level down to `depth` (at least the grid's),
 *  through the nodes over the cells [i0, i1] x [j0, j1] of that level only, calling
 *  leaf(i, j, n, key) for each non-empty cell there. Levels below the grid's split by exact
 *  multinomials: the grain of real flakes at the scale of their cones. */
template <class Leaf>
void visit_leaves(const Aggregate& a, const DirectionGrid& grid, int exact_below, int depth, int i0,
                  int i1, int j0, int j1, Leaf&& leaf) {
    constexpr int kMax = 4096;
    thread_local uint32_t ni[2][kMax], nj[2][kMax], nn[2][kMax];
    thread_local uint64_t nk[2][kMax];
    int count = 1, cur = 0;
    ni[0][0] = nj[0][0] = 0;
    nn[0][0] = a.count;
    nk[0][0] = direction_root(a);
    for (int level = 0; level < depth; ++level) {
        const int shift = depth - level - 1;
        int next = 0;
        for (int k = 0; k < count; ++k) {
            uint32_t c[4];
            if (level < grid.depth)
                split_direction_node(nk[cur][k], nn[cur][k], exact_below, c);
            else
                split_counts_cached(nk[cur][k], nn[cur][k], std::min(exact_below, kExactVirtual),
                                    c);
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
    for (int k = 0; k < count; ++k)
        leaf(static_cast<int>(ni[cur][k]), static_cast<int>(nj[cur][k]), nn[cur][k], nk[cur][k]);
}

/** Levels below the grid's at which sparse aggregates make their virtual flakes: one. The grid's
 *  leaves hold on average k 4^-depth flakes, and a sparse aggregate (k p1 < 16 at the lobe's peak,
 *  see mark_sparse) has k 4^-depth < 8 cos(theta_o), so that the cells one level below hold a
 *  handful each (every one is made, at most kMaxVirtual, uniform within its cell: the flake
 *  distribution exactly), and the cells visited for a direction are few (measured: one level
 *  costs the least of zero to three). */
constexpr int kVirtualLevels = 1;

/** A cell's flakes as individual virtual flakes: positions uniform in the cell (hashed from its
 *  key), so their normals follow the flake distribution exactly within it. At most kMaxVirtual
 *  are made; beyond that each stands for n / kMaxVirtual flakes. Adds w c F of those whose cone
 *  holds wi to `sum`. */
constexpr uint32_t kMaxVirtual = 32;
V3 virtual_normal(const DirectionGrid& grid, int depth, int i, int j, uint64_t key, uint32_t q,
                  uint64_t& h);
float virtual_flakes(const DirectionGrid& grid, const ColorTable& colors,
                     const FresnelTable& fresnel, const FilmTables& film, V3 wo, V3 wi, int depth,
                     int i, int j, uint32_t n, uint64_t key, float sum[3]) {
    float lit = 0.0f;
    const uint32_t made = std::min(n, kMaxVirtual);
    const float weight = static_cast<float>(n) / static_cast<float>(made);
    const float thr = 4.0f * grid.sin2_half;
    for (uint32_t q = 0; q < made; ++q) {
        uint64_t h;
        const V3 m = virtual_normal(grid, depth, i, j, key, q, h);
        const float cos_om = mf::dot(wo, m);
        if (cos_om <= 0.0f) continue;
        const V3 r = mf::reflect(wo, m);
        if (r.z <= 0.0f) continue;
        const V3 d = wi - r;
        if (mf::dot(d, d) > thr) continue;
        CacheEntry e;
        const uint64_t id = mix(h, 0xc0);
        const float* col = colors.pick(static_cast<float>(id >> 40) * 0x1p-24f, id);
        if (!make_entry(wo, m, col, film.pick(id, fresnel), e)) continue;
        for (int c = 0; c < 3; ++c) sum[c] += weight * e.rgb[c];
        lit += weight;
    }
    return lit;
}

/** The normal of virtual flake q of cell (i, j) at `depth` with key `key` (as virtual_flakes
 *  makes it), and the hash its colour comes from. */
V3 virtual_normal(const DirectionGrid& grid, int depth, int i, int j, uint64_t key, uint32_t q,
                  uint64_t& h) {
    h = mix(key, 0x5eed0000u + q);
    float a, b;
    unit2(h, a, b);
    const auto inv_side = static_cast<float>(pow2_neg(depth));
    return flake_normal(grid.alpha, (static_cast<float>(i) + a) * inv_side,
                        (static_cast<float>(j) + b) * inv_side);
}

}  // namespace

void node_weights(const DirectionGrid& grid, V3 wo, float out[DirectionGrid::kWeightNodes]) {
    const int nodes = 1 << (2 * grid.weight_level);
    constexpr int kPer = DirectionGrid::kWeightSide * DirectionGrid::kWeightSide;
    for (int n = 0; n < nodes; ++n) {
        float sum = 0.0f;
        for (int s = 0; s < kPer; ++s) {
            const V3 m = grid.weight_normals[static_cast<std::size_t>(kPer * n + s)];
            const float c = mf::dot(wo, m);
            if (c > 0.0f && 2.0f * c * m.z - wo.z > 0.0f) sum += c / m.z;
        }
        out[n] = sum * (1.0f / kPer);
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
                split_direction_node(k, n[j * w + i], exact_below, c);
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

void aggregate_lobe(const CountedFootprint& cf, const DirectionGrid& grid, const ColorTable& colors,
                    const FresnelTable& fresnel, const FilmTables& film, V3 wo, V3 wi,
                    int exact_below, float virt[3], float mod[3], float& lit) {
    virt[0] = virt[1] = virt[2] = mod[0] = mod[1] = mod[2] = lit = 0.0f;
    if (cf.n_agg == 0 || !(wi.z > 0.0f) || !(wo.z > 0.0f)) return;
    V3 h = wo + wi;
    if (!(h.z > 0.0f)) return;
    h = mf::normalize(h);
    const float cos_oh = mf::dot(wo, h);
    if (!(cos_oh > 0.0f)) return;
    // Which aggregates light wi densely: the expected count of one aggregate's flakes whose cone
    // holds wi is k times the chance p1 that one flake's does (the unblurred density of mirror
    // directions times the cone's solid angle). It depends on the expectation only, never on the
    // realisation, so either treatment stays unbiased.
    const float thr = 4.0f * grid.sin2_half;
    const float p1 = mf::kPi * thr * mf::ggx_d(h, grid.alpha, grid.alpha) * h.z / (4.0f * cos_oh);
    bool dense[kMaxAggregates], any_dense = false, any_sparse = false;
    for (uint32_t a = 0; a < cf.n_agg; ++a) {
        dense[a] = !cf.agg[a].sparse && static_cast<float>(cf.agg[a].count) * p1 >= kDenseLit;
        any_dense = any_dense || dense[a];
        any_sparse = any_sparse || !dense[a];
    }
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
    // Leaf centres move almost linearly with the leaf index near wi: skip those the linear map
    // puts well beyond the reach (by 1.5x, to absorb the map's curvature), test the rest exactly.
    const V3 ex = rx - r0, ey = ry - r0, d0 = wi - r0;
    const float sx = ci + 1 < side ? 1.0f : -1.0f, sy = cj + 1 < side ? 1.0f : -1.0f;
    const auto guess2 = [&](int i, int j) {
        const V3 g =
            d0 - ex * (sx * static_cast<float>(i - ci)) - ey * (sy * static_cast<float>(j - cj));
        return mf::dot(g, g);
    };

    if (any_sparse) {
        // Sparse: the flakes themselves, from the cells of the square of normals that the cone's
        // preimage can reach. A normal m = h + dm lights wi when reflect(wo, m) is within the
        // cone's chord c of wi; to first order |d reflect|^2 = 4 ((wo.dm)^2 + (wo.h)^2 |dm|^2),
        // so the preimage is an ellipse around h with semi-axes c / 2 towards wo's azimuth and
        // c / (2 wo.h) across it (a fifth more each, for the second order). The square's cells
        // under its image are bounded by the image of its rim.
        const float c = std::sqrt(thr);
        V3 e1 = wo - h * cos_oh;  // in the plane of wo and h, orthogonal to h
        const float e1_len = std::sqrt(std::max(0.0f, mf::dot(e1, e1)));
        if (e1_len > 1e-6f) {
            e1 = e1 * (1.0f / e1_len);
        } else {
            const V3 any = std::fabs(h.x) < 0.9f ? V3{1, 0, 0} : V3{0, 1, 0};
            e1 = mf::normalize(any - h * mf::dot(any, h));
        }
        const V3 e2 = mf::cross(h, e1);
        const float a1 = std::min(1.5f, 0.6f * c), a2 = std::min(1.5f, 0.6f * c / cos_oh);
        float s0 = s, s1 = s, t0 = t, t1 = t;
        constexpr int kRim = 8;
        for (int k = 0; k < kRim; ++k) {
            const float phi = 2.0f * mf::kPi * static_cast<float>(k) / kRim;
            V3 m = h + e1 * (a1 * std::cos(phi)) + e2 * (a2 * std::sin(phi));
            m.z = std::max(m.z, 1e-3f);  // normals past the horizon: the square's edge
            m = mf::normalize(m);
            float ms, mt;
            flake_square(grid.alpha, m, ms, mt);
            s0 = std::min(s0, ms);
            s1 = std::max(s1, ms);
            t0 = std::min(t0, mt);
            t1 = std::max(t1, mt);
        }
        // A margin for the rim between its samples (45 degrees apart): 10% of the box and a cell.
        const int depth = std::min(grid.depth + kVirtualLevels, 15);
        const auto cells = static_cast<float>(1 << depth);
        const float ms = 0.1f * (s1 - s0) + 1.0f / cells, mt = 0.1f * (t1 - t0) + 1.0f / cells;
        const auto index = [&](float x) {
            return std::clamp(static_cast<int>(std::floor(x * cells)), 0, (1 << depth) - 1);
        };
        const int i0 = index(s0 - ms), i1 = index(s1 + ms), j0 = index(t0 - mt),
                  j1 = index(t1 + mt);
        for (uint32_t a = 0; a < cf.n_agg; ++a) {
            if (dense[a]) continue;
            visit_leaves(cf.agg[a], grid, exact_below, depth, i0, i1, j0, j1,
                         [&](int i, int j, uint32_t n, uint64_t key) {
                             const float w = virtual_flakes(grid, colors, fresnel, film, wo, wi,
                                                            depth, i, j, n, key, virt);
                             if (cf.agg[a].sparse) lit += w;
                         });
        }
    }
    if (!any_dense) return;

    // Dense: the smooth lobe times the modulation M. Tent radius: the cone widened by a leaf, and
    // at least past the centre of the leaf holding wi's half vector, so that some leaf always
    // lights wi. Any radius that depends only on wi keeps E[M] = 1.
    const float radius2 = thr + std::max(leaf2, 2.0f * mf::dot(d0, d0));
    const int b = std::clamp(
        static_cast<int>(std::ceil(std::sqrt(radius2 / std::max(leaf2, 1e-30f)))) + 1, 1, 4);
    float tau_grid[kBox * kBox] = {};
    float expected = 0.0f;   // sum of tau over the leaves: the count's expectation / (k 4^-depth)
    float expected2 = 0.0f;  // sum of tau^2: the count's variance / (k 4^-depth)
    int i0 = side, i1 = -1, j0 = side, j1 = -1;
    const int bi0 = std::max(0, ci - b), bj0 = std::max(0, cj - b);
    for (int j = bj0; j <= std::min(side - 1, cj + b); ++j)
        for (int i = bi0; i <= std::min(side - 1, ci + b); ++i) {
            if (guess2(i, j) > 2.25f * radius2) continue;
            const V3 d = wi - centre(i, j);
            const float tau = 1.0f - mf::dot(d, d) / radius2;
            if (tau <= 0.0f) continue;
            tau_grid[(j - bj0) * kBox + (i - bi0)] = tau;
            expected += tau;
            expected2 += tau * tau;
            i0 = std::min(i0, i);
            i1 = std::max(i1, i);
            j0 = std::min(j0, j);
            j1 = std::max(j1, j);
        }
    if (!(expected > 0.0f)) return;
    float sum[3] = {0, 0, 0};
    for (uint32_t a = 0; a < cf.n_agg; ++a) {
        if (!dense[a]) continue;
        visit_leaves(cf.agg[a], grid, exact_below, grid.depth, i0, i1, j0, j1,
                     [&](int i, int j, uint32_t n, uint64_t key) {
                         const float w = tau_grid[(j - bj0) * kBox + (i - bi0)];
                         if (w <= 0.0f) return;
                         float col[3];
                         leaf_colours(key, n, colors, col);
                         for (int c = 0; c < 3; ++c) sum[c] += w * col[c];
                     });
    }
    // sum_a k_a M_a = sum_a (tau-weighted colour sum of a) / (sum tau 4^-depth).
    const float leaf_share = std::ldexp(1.0f, -2 * grid.depth);
    const float k = 1.0f / (expected * leaf_share);
    // The tent spans more directions than one cone, so M varies less from footprint to footprint
    // than the count of flakes whose cone holds wi (relative variance 1 / (k p1)): by the ratio
    // sum(tau)^2 4^-depth / (p1 sum(tau^2)) in variance (about 3 at the default material, where
    // the counted lobe varied 0.55 times as much as real flakes' beyond lambda 3000). The
    // deviation of M from its mean is scaled back by its square root: E[M] = 1 stays, and so
    // does every mean; a scaled M below 0 is cut there.
    const float ratio = expected * expected * leaf_share / std::max(p1 * expected2, 1e-30f);
    const float spread = std::sqrt(std::clamp(ratio, 1.0f, 16.0f));
    float dense_count = 0.0f;
    for (uint32_t a = 0; a < cf.n_agg; ++a)
        if (dense[a]) dense_count += static_cast<float>(cf.agg[a].count);
    for (int c = 0; c < 3; ++c) {
        const float mean = dense_count * colors.mean[c];
        mod[c] = std::max(0.0f, mean + spread * (sum[c] * k - mean));
    }
}

void mark_sparse(CountedFootprint& cf, const DirectionGrid& grid, float cos_o) {
    const float p1_max =
        4.0f * grid.sin2_half / (4.0f * grid.alpha * grid.alpha * std::max(cos_o, 1e-6f));
    cf.dense = 0;
    for (uint32_t a = 0; a < cf.n_agg; ++a) {
        cf.agg[a].sparse = static_cast<float>(cf.agg[a].count) * p1_max < kDenseLit;
        if (!cf.agg[a].sparse) cf.dense += cf.agg[a].count;
    }
}

bool sample_aggregate(const Aggregate& a, const DirectionGrid& grid, int exact_below, V3 wo,
                      float u, float u0, float u1, V3& wi) {
    // Down the direction tree by the counts: each flake as likely as any other.
    const int depth = std::min(grid.depth + kVirtualLevels, 15);
    uint32_t n = a.count, i = 0, j = 0;
    uint64_t key = direction_root(a);
    if (n == 0) return false;
    for (int level = 0; level < depth; ++level) {
        uint32_t c[4];
        if (level < grid.depth)
            split_direction_node(key, n, exact_below, c);
        else
            split_counts_cached(key, n, std::min(exact_below, kExactVirtual), c);
        const float x = u * static_cast<float>(n);
        uint32_t q = 0;
        float below = 0.0f;
        while (q < 3 && x >= below + static_cast<float>(c[q])) below += static_cast<float>(c[q++]);
        while (c[q] == 0) --q;  // rounding at the top end: the last non-empty child
        u = std::clamp((x - below) / static_cast<float>(c[q]), 0.0f, 0x1.fffffep-1f);
        i = 2 * i + (q & 1u);
        j = 2 * j + (q >> 1);
        key = mix(key, 1 + q);
        n = c[q];
    }
    const uint32_t made = std::min(n, kMaxVirtual);
    const uint32_t q = std::min(static_cast<uint32_t>(u * static_cast<float>(made)), made - 1);
    uint64_t h;
    const V3 m = virtual_normal(grid, depth, static_cast<int>(i), static_cast<int>(j), key, q, h);
    if (!(mf::dot(wo, m) > 0.0f)) return false;
    const V3 r = mf::reflect(wo, m);
    if (!(r.z > 0.0f)) return false;
    wi = sample_cone(r, grid.sin2_half, u0, u1);
    return wi.z > 0.0f;
}

}  // namespace spangle::flake
