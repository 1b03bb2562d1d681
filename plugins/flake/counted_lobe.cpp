#include "counted_lobe.h"

#include <algorithm>
#include <cmath>

namespace spangle::flake {

void DirectionGrid::init(float alpha_, float gamma_rad) {
    alpha = alpha_;
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
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

float sparse_count(const DirectionGrid& grid, float cos_o) {
    return kDenseLit * grid.alpha * grid.alpha * std::max(cos_o, 0.0f) /
           std::max(grid.sin2_half, 1e-12f);
}

void add_stand_ins(CountedFootprint& cf, const DirectionGrid& grid, const ColorTable& colors,
                   const FresnelTable& fresnel, const FilmTables& film, V3 wo,
                   std::vector<CacheEntry>& out) {
    cf.smooth = 0.0f;
    // The footprint's stand-ins: as many as a sparse footprint would light every direction with
    // (at least kMinStandIns, at most kMaxStandIns; the glints' grain needs no more), shared
    // among its aggregates by their counts. A footprint whose aggregates hold fewer flakes has
    // them all as stand-ins. Shared per footprint, not given per aggregate: a footprint over
    // four cells would otherwise hold four times the stand-ins of its neighbour inside one cell
    // (finer grain in a pattern of the cell grid, and four times the cost).
    const auto cap =
        static_cast<uint32_t>(std::clamp(sparse_count(grid, wo.z), static_cast<float>(kMinStandIns),
                                         static_cast<float>(kMaxStandIns)));
    const uint32_t total = cf.aggregated;  // the sum of the aggregates' counts
    for (uint32_t a = 0; a < cf.n_agg; ++a) {
        const uint32_t k = cf.agg[a].count;
        const uint32_t stand_ins =
            total <= cap
                ? k
                : std::min(k, std::max<uint32_t>(
                                  1, static_cast<uint32_t>(std::ceil(static_cast<double>(cap) * k /
                                                                     static_cast<double>(total)))));
        if (stand_ins == 0) continue;
        // beta = sqrt(K / k) of the aggregate's weight is in its K stand-ins, sqrt(k / K) each.
        const float scale = std::sqrt(static_cast<float>(k) / static_cast<float>(stand_ins));
        cf.smooth += static_cast<float>(k) - scale * static_cast<float>(stand_ins);
        const uint64_t root = mix(cf.agg[a].key, 0xd1ec);
        for (uint32_t q = 0; q < stand_ins; ++q) {
            const uint64_t h = mix(root, 0x5eed0000u + q);
            float s, t;
            unit2(h, s, t);
            const V3 m = flake_normal(grid.alpha, s, t);
            const uint64_t id = mix(h, 0xc0);
            const float* col = colors.pick(static_cast<float>(id >> 40) * 0x1p-24f, id);
            CacheEntry e;
            if (!make_entry(wo, m, col, film.pick(id, fresnel), e)) continue;
            for (float& x : e.rgb) x *= scale;
            e.lum *= scale;
            e.w *= scale;
            out.push_back(e);
        }
    }
    cf.smooth = std::max(cf.smooth, 0.0f);
}

}  // namespace spangle::flake
