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

namespace {

/** Scratch arrays of add_stand_ins, one set per thread, grown as needed: the candidates (virtual
 *  flakes under the footprint's bounding box) as a structure of arrays, so that their hashes,
 *  places and inside tests are one loop of the same arithmetic per candidate, and those kept. */
struct StandInScratch {
    std::vector<uint64_t> key, index, hash;  ///< the candidate's block key, index, own hash
    std::vector<int64_t> bx, by;             ///< its block (x, y) times 2^24
    std::vector<uint8_t> in;                 ///< whether it lies inside the footprint
    std::vector<uint64_t> found;             ///< the hashes kept, per aggregate
    void reserve(std::size_t m) {
        if (key.size() >= m) return;
        const std::size_t n = std::max<std::size_t>(2 * m, 256);
        for (auto* v : {&key, &index, &hash}) v->resize(n);
        bx.resize(n);
        by.resize(n);
        in.resize(n);
    }
};

}  // namespace

void add_stand_ins(CountedFootprint& cf, const Footprint& p, uint32_t stand_ins,
                   const DirectionGrid& grid, const ColorTable& colors, const FresnelTable& fresnel,
                   const FilmTables& film, V3 wo, std::vector<CacheEntry>& out) {
    cf.smooth = 0.0f;
    const double area = p.area();
    // At most four times the average in all (the footprint's aggregates together).
    const uint32_t cap = 4 * stand_ins;
    // Through a plain reference: every use of a thread_local in a shared library calls
    // __tls_get_addr (it was 3% of the instructions of a shaded point).
    thread_local StandInScratch scratch_tls;
    StandInScratch& sc = scratch_tls;
    if (sc.found.size() < cap) sc.found.resize(cap);
    uint64_t* const found = sc.found.data();
    uint32_t found_all = 0;
    // A stand-in's own hash picks its colour and film; with neither table (one colour, no film)
    // it is not needed.
    const bool own = colors.varies() || film.varies();
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
        uint32_t n = 0;
        const uint32_t room = singular(local) ? 0u : std::min(k, cap - found_all);
        if (room > 0) {
            // The candidates, block by block: each block's count, then one loop over all of them
            // (hash, place, inside test: tested without branches, inside_nonsingular).
            const auto whole_n = static_cast<uint32_t>(whole);
            const double frac = per_block - whole;
            sc.reserve(static_cast<std::size_t>((bx1 - bx0 + 1) * (by1 - by0 + 1)) * (whole_n + 1));
            uint64_t* const ckey = sc.key.data();
            uint64_t* const cidx = sc.index.data();
            int64_t* const cbx = sc.bx.data();
            int64_t* const cby = sc.by.data();
            // A block whose corners all lie beyond one edge of P, by more than the rounding of
            // the candidates' own test (margin), holds no candidate inside: it is skipped (on a
            // car's sheared footprints, a third of the candidates were in such blocks). The
            // candidates' test is unchanged, so the stand-ins are the same bit for bit.
            const double xs0 = local.i00 * block, xs1 = local.i01 * block;
            const double ts0 = local.i10 * block, ts1 = local.i11 * block;
            const double s_lo = std::min(xs0, 0.0) + std::min(xs1, 0.0),
                         s_hi = std::max(xs0, 0.0) + std::max(xs1, 0.0);
            const double t_lo = std::min(ts0, 0.0) + std::min(ts1, 0.0),
                         t_hi = std::max(ts0, 0.0) + std::max(ts1, 0.0);
            const double extent = std::fabs(local.cu) + std::fabs(local.cv) + std::fabs(ag.x0) +
                                  std::fabs(ag.y0) + ag.size + 1.0;
            const double margin = 0.5 + 1e-9 +
                                  1e-14 * extent *
                                      (std::fabs(local.i00) + std::fabs(local.i01) +
                                       std::fabs(local.i10) + std::fabs(local.i11));
            // Worth it only where P leaves much of its bounding box empty (sheared, turned): a
            // square aligned with the uv axes leaves no block out, and the test cost 7% there.
            const double box = (std::fabs(local.ax) + std::fabs(local.bx)) *
                               (std::fabs(local.ay) + std::fabs(local.by));
            const bool cull = area < 0.75 * box;
            // (s, t) of the first block's corner, then one block's steps: the rounding of the
            // sums is far inside the margin's constant.
            const double du0 = ag.x0 + bx0 * block - local.cu, dv0 = ag.y0 + by0 * block - local.cv;
            const double s00 = local.i00 * du0 + local.i01 * dv0,
                         t00 = local.i10 * du0 + local.i11 * dv0;
            uint32_t m = 0;
            for (int by = by0; by <= by1; ++by)
                for (int bx = bx0; bx <= bx1; ++bx) {
                    const double s0 = s00 + (bx - bx0) * xs0 + (by - by0) * xs1,
                                 t0 = t00 + (bx - bx0) * ts0 + (by - by0) * ts1;
                    if (cull && ((s0 + s_lo > margin) | (s0 + s_hi < -margin) |
                                 (t0 + t_lo > margin) | (t0 + t_hi < -margin)))
                        continue;
                    const uint64_t bkey =
                        mix(ag.key, 0xb10c0000u + static_cast<uint64_t>(by * kStandInBlocks + bx));
                    const uint32_t v = whole_n + (unit(mix(bkey, 0xd17)) < frac ? 1u : 0u);
                    // whole_n + 1 slots always (a loop of one length: the block's count was a
                    // coin toss, and a loop of its length was mispredicted on every other block),
                    // of which the first v count.
                    for (uint32_t i = 0; i <= whole_n; ++i) {
                        ckey[m + i] = bkey;
                        cidx[m + i] = i;
                        cbx[m + i] = static_cast<int64_t>(bx) << 24;
                        cby[m + i] = static_cast<int64_t>(by) << 24;
                    }
                    m += v;
                }
            uint64_t* const ch = sc.hash.data();
            uint8_t* const cin = sc.in.data();
            const double x0 = ag.x0, y0 = ag.y0;
            uint32_t n_in = 0;
            for (uint32_t c = 0; c < m; ++c) {
                const uint64_t h = mix(ckey[c], cidx[c]);
                ch[c] = h;
                // The place in blocks, block + (24 bits of the hash) / 2^24 (unit2's numbers),
                // exact in double: computed from the integer at once.
                const double x =
                    static_cast<double>(cbx[c] + static_cast<int64_t>(h >> 40)) * 0x1p-24;
                const double y =
                    static_cast<double>(cby[c] + static_cast<int64_t>((h >> 16) & 0xffffffu)) *
                    0x1p-24;
                const bool in = inside_nonsingular(local, x0 + x * block, y0 + y * block);
                cin[c] = in ? 1 : 0;
                n_in += in ? 1u : 0u;
            }
            if (n_in < room) {
                // All of them, in order.
                for (uint32_t c = 0; c < m; ++c) {
                    found[n] = ch[c];
                    n += cin[c];
                }
            } else {
                // They outnumber its k flakes (or the room left): those of the smallest hashes
                // (a priority of their own: two overlapping footprints keep the same ones among
                // those they share), in a max-heap once full.
                for (uint32_t c = 0; c < m; ++c) {
                    if (!cin[c]) continue;
                    const uint64_t h = ch[c];
                    if (n < room) {
                        found[n++] = h;
                        if (n == room) std::make_heap(found, found + n);
                    } else if (h < found[0]) {
                        std::pop_heap(found, found + n);
                        found[n - 1] = h;
                        std::push_heap(found, found + n);
                    }
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
            const float* col = colors.single;
            const FresnelTable* fr = &fresnel;
            if (own) {
                const uint64_t id = mix(h, 0xc0);
                col = colors.pick(static_cast<float>(id >> 40) * 0x1p-24f, id);
                fr = &film.pick(id, fresnel);
            }
            batch.add(wo, grid.alpha, s, t, col, fr, scale, out);
        }
    }
    flush_entries(wo, grid.alpha, batch, out);
    cf.smooth = std::max(cf.smooth, 0.0f);
}

}  // namespace spangle::flake
