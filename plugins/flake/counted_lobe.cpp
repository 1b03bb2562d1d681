#include "counted_lobe.h"

#include <algorithm>
#include <cmath>

namespace spangle::flake {

void DirectionGrid::init(float alpha_, float gamma_rad) {
    alpha = alpha_;
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
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

uint32_t exact_limit(uint32_t exact_flakes, const DirectionGrid& grid, float cos_o) {
    const auto alpha = static_cast<double>(grid.alpha);
    const double sparse = static_cast<double>(kDenseLit) * alpha * alpha *
                          std::max(static_cast<double>(cos_o), 0.0) /
                          std::max(static_cast<double>(grid.sin2_half), 1e-12);
    return std::max(exact_flakes, static_cast<uint32_t>(std::min(sparse, kSparseExactCap)));
}

void add_stand_ins(CountedFootprint& cf, const Footprint& p, uint32_t stand_ins,
                   const DirectionGrid& grid, const ColorTable& colors, const FresnelTable& fresnel,
                   const FilmTables& film, V3 wo, std::vector<CacheEntry>& out) {
    cf.smooth = 0.0f;
    const double area = p.area();
    // At most four times the average in all (the footprint's aggregates together).
    const uint32_t cap = 4 * stand_ins;
    thread_local std::vector<uint64_t> found_tls;
    found_tls.resize(cap);
    // The buffer through a plain pointer: every use of a thread_local in a shared library calls
    // __tls_get_addr (it was 3% of the instructions of a shaded point).
    uint64_t* const found = found_tls.data();
    uint32_t found_all = 0;
    EntryBatch batch;
    for (uint32_t a = 0; a < cf.n_agg; ++a) {
        const Aggregate& ag = cf.agg[a];
        const uint32_t k = ag.count;
        // The cell's virtual flakes: per_block per block on average, stand_ins per footprint
        // area. A block holds floor(per_block) of them, and one more when its own hash falls
        // under the fraction: exactly stand_ins per footprint area in expectation, and a block's
        // flakes only gain members as footprints shrink (rounded, the count per footprint ran in
        // a sawtooth from 54 to 76 as the footprint's size changed).
        const double block = ag.size / kStandInBlocks;
        const double per_block =
            area > 0.0 ? std::min(stand_ins * block * block / area, static_cast<double>(stand_ins))
                       : 0.0;
        const double whole = std::floor(per_block);
        Footprint local = p;
        local.cu -= static_cast<double>(ag.tx);
        local.cv -= static_cast<double>(ag.ty);
        // Blocks under the footprint's own bounding box (not widened by a facet's reach: the
        // virtual flakes are points); a centre that is not finite gives one block, none of whose
        // flakes lies inside.
        const auto range = [&](double c, double h, double origin, int& lo, int& hi) {
            const auto index = [&](double x) {
                const double f = std::floor((x - origin) / block);
                return f >= 0.0
                           ? (f < kStandInBlocks - 1 ? static_cast<int>(f) : kStandInBlocks - 1)
                           : 0;  // NaN too
            };
            lo = index(c - h);
            hi = index(c + h);
        };
        int bx0, bx1, by0, by1;
        range(local.cu, 0.5 * (std::fabs(local.ax) + std::fabs(local.bx)), ag.x0, bx0, bx1);
        range(local.cv, 0.5 * (std::fabs(local.ay) + std::fabs(local.by)), ag.y0, by0, by1);
        // The virtual flakes inside the footprint; where they outnumber its k flakes (or the room
        // left), those of the smallest hashes (a priority of their own: two overlapping footprints
        // keep the same ones among those they share), in a max-heap once full.
        // (Tested without branches, inside_nonsingular: a singular footprint holds none.)
        uint32_t n = 0;
        const uint32_t room = singular(local) ? 0u : std::min(k, cap - found_all);
        for (int by = by0; by <= by1 && room > 0; ++by)
            for (int bx = bx0; bx <= bx1; ++bx) {
                const uint64_t bkey =
                    mix(ag.key, 0xb10c0000u + static_cast<uint64_t>(by * kStandInBlocks + bx));
                const auto v = static_cast<uint32_t>(whole) +
                               (unit(mix(bkey, 0xd17)) < per_block - whole ? 1u : 0u);
                for (uint32_t i = 0; i < v; ++i) {
                    const uint64_t h = mix(bkey, i);
                    float fx, fy;  // 24 bits each: a block's width / 2^24 apart
                    unit2(h, fx, fy);
                    const bool in =
                        inside_nonsingular(local, ag.x0 + (bx + static_cast<double>(fx)) * block,
                                           ag.y0 + (by + static_cast<double>(fy)) * block);
                    if (n < room) {
                        // Written always, kept when inside.
                        found[n] = h;
                        n += in ? 1u : 0u;
                        if (n == room) std::make_heap(found, found + n);
                    } else if (in && h < found[0]) {
                        std::pop_heap(found, found + n);
                        found[n - 1] = h;
                        std::push_heap(found, found + n);
                    }
                }
            }
        found_all += n;
        if (n == 0) {
            cf.smooth += static_cast<float>(k);
            continue;
        }
        // beta = sqrt(K / k) of the aggregate's weight is in its K stand-ins, sqrt(k / K) each.
        const float scale = std::sqrt(static_cast<float>(k) / static_cast<float>(n));
        cf.smooth += static_cast<float>(k) - scale * static_cast<float>(n);
        for (uint32_t q = 0; q < n; ++q) {
            const uint64_t h = mix(found[q], 0x5eed);
            float s, t;
            unit2(h, s, t);
            const uint64_t id = mix(h, 0xc0);
            const float* col = colors.pick(static_cast<float>(id >> 40) * 0x1p-24f, id);
            batch.add(wo, grid.alpha, s, t, col, &film.pick(id, fresnel), scale, out);
        }
    }
    flush_entries(wo, grid.alpha, batch, out);
    cf.smooth = std::max(cf.smooth, 0.0f);
}

}  // namespace spangle::flake
