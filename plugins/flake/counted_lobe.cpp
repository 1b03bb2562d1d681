#include "counted_lobe.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace spangle::flake {

void DirectionGrid::init(float alpha_, float gamma_rad, bool with_lit) {
    alpha = alpha_;
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
    for (int i = 0; with_lit && i < kLitNodes; ++i) {
        const float x = static_cast<float>(i) / static_cast<float>(kLitNodes - 1);
        lit[i] = static_cast<float>(lit_share_exact(alpha, sin2_half, x * x));
    }
}

float DirectionGrid::lit_share(float cos_o) const {
    return interpolate_nodes(lit, kLitNodes, std::sqrt(std::clamp(cos_o, 0.0f, 1.0f)));
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
        path_[0] = {0, 0, 0, residual_count(fp_)};
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
    NodeRef node{0, 0, 0, residual_count(fp)};
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

double lit_share_exact(float alpha, float sin2_half, float cos_o) {
    // The flakes as N normals of the unit square's midpoint grid (density D(m) (m.n)), seen from
    // wo: their mirror directions and weights, those that reflect above the horizon.
    // As many as give the median direction some 16 other flakes' cones at the head-on estimate
    // sin^2(gamma / 2) / (3 alpha^2) of p, or at p = 1/128, below which a footprint of
    // kSparseEnumerate flakes is sparse whatever p is (narrow cones: 48 x 48; wide ones need
    // fewer).
    const double guess = static_cast<double>(sin2_half) /
                         (3.0 * static_cast<double>(alpha) * static_cast<double>(alpha));
    const int side = std::clamp(
        static_cast<int>(std::ceil(std::sqrt(16.0 / std::max(guess, 1.0 / 128.0)))), 24, 48);
    constexpr int kQueries = 256;
    // No cone (gamma 0, which the host refuses): no direction is lit by a flake's cone.
    if (!(sin2_half > 0.0f) || !std::isfinite(sin2_half)) return 0.0;
    const float c = std::clamp(cos_o, 1e-4f, 1.0f);
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - c * c)), 0.0f, c};
    struct Lit {
        float x, y, z, w;
        float g;      ///< G1 of r: the lobe's masking of the direction
        int64_t row;  ///< the strip of y (a chord high) it lies in
    };
    std::vector<Lit> lit;
    lit.reserve(static_cast<std::size_t>(side * side));
    double w_all = 0.0;
    const auto fs = static_cast<float>(side);
    for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j) {
            const V3 m = flake_normal(alpha, (static_cast<float>(i) + 0.5f) / fs,
                                      (static_cast<float>(j) + 0.5f) / fs);
            const float wom = mf::dot(wo, m);
            if (!(wom > 0.0f) || !(m.z > 0.0f)) continue;
            const V3 r = mf::reflect(wo, m);
            if (!(r.z > 0.0f)) continue;
            // (Directions drawn as the lobe reflects: by w and by the masking of r.)
            const float g = mf::ggx_g1(r, alpha, alpha);
            lit.push_back({r.x, r.y, r.z, wom / m.z, g, 0});
            w_all += static_cast<double>(wom / m.z * g);
        }
    if (lit.size() < 2 || !(w_all > 0.0)) return 0.0;
    // Sorted by strips of y a chord high, then x: the flakes whose cone may hold a direction lie
    // in a window of x in its strip and the two beside it.
    const float chord2 = 4.0f * sin2_half, chord = std::sqrt(chord2);
    // (|y| <= 1 and chord > 0, but a subnormal chord gives an infinite ratio: clamped.)
    for (Lit& l : lit)
        l.row = static_cast<int64_t>(std::floor(
            std::clamp(static_cast<double>(l.y) / static_cast<double>(chord), -1e15, 1e15)));
    const auto before = [](const Lit& a, const Lit& b) {
        return a.row < b.row || (a.row == b.row && a.x < b.x);
    };
    std::sort(lit.begin(), lit.end(), before);
    // Directions drawn by the lobe itself: the mirror directions of flakes at evenly spaced
    // points of the cumulative weight (a heavy flake may stand for several).
    std::vector<double> cvs;  // per direction, of the N flakes (infinite: no other flake's cone)
    cvs.reserve(kQueries);
    double acc = 0.0;
    int q = 0;
    for (std::size_t i = 0; i < lit.size() && q < kQueries; ++i) {
        acc += static_cast<double>(lit[i].w * lit[i].g);
        int strata = 0;
        while (q < kQueries && acc >= (static_cast<double>(q) + 0.5) / kQueries * w_all) {
            ++q;
            ++strata;
        }
        if (strata == 0) continue;
        const Lit& d = lit[i];
        double a = 0.0, b = 0.0;
        for (int64_t row = d.row - 1; row <= d.row + 1; ++row) {
            const Lit first{d.x - chord, 0.0f, 0.0f, 0.0f, 0.0f, row};
            for (auto it = std::lower_bound(lit.begin(), lit.end(), first, before);
                 it != lit.end() && it->row == row && it->x <= d.x + chord; ++it) {
                if (&*it == &d) continue;
                const float dx = it->x - d.x, dy = it->y - d.y, dz = it->z - d.z;
                if (dx * dx + dy * dy + dz * dz > chord2) continue;
                a += static_cast<double>(it->w);
                b += static_cast<double>(it->w) * static_cast<double>(it->w);
            }
        }
        const double cv = a > 0.0 ? std::sqrt(b) / a : std::numeric_limits<double>::infinity();
        cvs.insert(cvs.end(), static_cast<std::size_t>(strata), cv);
    }
    if (cvs.empty()) return 0.0;
    // The median direction's (the mean is the tails': GGX's heavy tails hold directions that
    // next to no flake reaches, and its estimate fell without end as N grew).
    const auto mid = cvs.begin() + static_cast<std::ptrdiff_t>(cvs.size() / 2);
    std::nth_element(cvs.begin(), mid, cvs.end());
    if (!std::isfinite(*mid)) return 0.0;  // p below what N resolves
    // cv of one flake's worth: sqrt(N b) / (N a) per direction, over N = the grid's flakes.
    const double cv1 = *mid * static_cast<double>(side);
    return 1.0 / (cv1 * cv1);
}

namespace {

/** 1 where x <= 0, 0 where x >= 1, a smoothstep between (1 for NaN). */
double fall(double x) {
    if (!(x > 0.0)) return 1.0;
    if (x >= 1.0) return 0.0;
    return 1.0 - x * x * (3.0 - 2.0 * x);
}

}  // namespace

float sparse_share(float sparse_flakes, const DirectionGrid& grid, float cos_o, double lambda,
                   float t) {
    if (!(sparse_flakes > 0.0f) || !(lambda >= 0.0) || !(t < 0.5f)) return 0.0f;
    // Flakes per direction (0 where p is below what lit_share_exact resolves: sparse), and the
    // count, each against its bound: 1 at it, fading from 1/2 (log2 ratio + 1 from 0 to 1).
    const double lit =
        lambda * static_cast<double>(grid.lit_share(cos_o)) / static_cast<double>(sparse_flakes);
    // (A ratio that is not a number: counted.)
    const auto below = [](double ratio) {
        return !(ratio >= 0.0) ? 0.0 : ratio > 0.0 ? fall(std::log2(ratio) + 1.0) : 1.0;
    };
    const double share =
        below(lit) * below(lambda / kSparseEnumerate) * fall((static_cast<double>(t) - 0.1) / 0.4);
    return static_cast<float>(share);
}

namespace {

/** Classes more than this many below the densest one a footprint takes are left out: they hold
 *  4^-(kClassSpan + 1) / (1 - 1/4) of the density below class top, between 0.3% and 1.3% of a
 *  footprint's stand-ins, which a footprint half as wide (one class up) no longer keeps; each
 *  would test about a block's worth along the footprint's edges for fewer than one inside. (Two
 *  dropped a fifth of them at every halving.) */
constexpr int kClassSpan = 4;
/** The densest class stand-ins take (blocks 2^-(kMaxClass + 3) of a tile wide). */
constexpr int kMaxClass = 25;

/** Scratch of add_stand_ins, one per thread, grown as needed: the candidates inside P (a
 *  structure of arrays) and those kept. */
struct StandInScratch {
    std::vector<uint64_t> hash;       ///< a candidate's own hash
    std::vector<double> x, y;         ///< its place in the tile
    std::vector<uint64_t> kept_hash;  ///< those inside an aggregate's cell: own hash,
    std::vector<uint8_t> kept_agg;    ///< and the aggregate
    std::vector<uint64_t> found;      ///< the hashes kept, per aggregate
    void reserve(std::size_t m) {
        if (hash.size() >= m) return;
        const std::size_t n = std::max<std::size_t>(2 * m, 512);
        hash.resize(n);
        x.resize(n);
        y.resize(n);
    }
};

}  // namespace

void add_stand_ins(CountedFootprint& cf, const FieldParams& fp, const Footprint& p, float keep,
                   uint32_t stand_ins, const DirectionGrid& grid, const ColorTable& colors,
                   const FresnelTable& fresnel, const FilmTables& film, V3 wo,
                   std::vector<CacheEntry>& out) {
    cf.smooth = 0.0f;
    const double area = p.area();
    // At most four times the average in all (the footprint's aggregates together).
    const uint32_t cap = 4 * stand_ins;
    // Through a plain reference: every use of a thread_local in a shared library calls
    // __tls_get_addr (it was 3% of the instructions of a shaded point).
    thread_local StandInScratch scratch_tls;
    StandInScratch& sc = scratch_tls;
    uint32_t n_kept = 0;  // sc.kept_hash[0 .. n_kept - 1]
    // The stand-ins are the field's ranked classes (field.h): class c holds 192 x 4^c flakes per
    // tile (a Poisson count of mean 3 in each block 2^-(c + 3) of a tile wide), the last one
    // perhaps a share of that. A footprint of area A takes the density S / A (S = stand_ins):
    // the classes below `top` whole, and of class `top` the mean `top_mean` per block (the
    // same block's count, by inversion of its own uniform, never falls as the mean grows). As a
    // footprint shrinks (a camera dollies in) the density grows: the smaller footprint's
    // stand-ins are those of the larger one inside it, and more, and its glints stay where they
    // were; and they are real flakes, which the enumeration finds too where a cell becomes few
    // enough to enumerate. A footprint smaller than S / (N / 2) of a tile wants more than the
    // classes hold: it takes them all and virtual classes beyond them, of the same layout
    // (lost where its cell becomes enumerated, but such a footprint holds fewer than 2 S
    // flakes); without them its few flakes were the smooth lobe's haze, not glints.
    const ClassLayout cl = class_layout(fp);
    const auto class_mean = [&](int c) { return c > cl.last ? kClassMean : cl.mean(c); };
    const bool any_area = area > 0.0 && std::isfinite(area) && !singular(p);
    // (Denser by 1 / keep where the view thins the flakes: as many stand-ins survive it.)
    const double density = any_area ? static_cast<double>(stand_ins) /
                                          (area * std::clamp(static_cast<double>(keep), 1e-3, 1.0))
                                    : 0.0;
    int top = 0;
    double below = 0.0;              // density of the classes below top
    double rho = 64.0 * kClassMean;  // class top's, when whole
    while (top < kMaxClass && below + rho * class_mean(top) / kClassMean < density) {
        below += rho * class_mean(top) / kClassMean;
        rho *= 4.0;
        ++top;
    }
    const double top_mean =
        std::min(class_mean(top), kClassMean * std::clamp((density - below) / rho, 0.0, 1.0));
    // Class top's law: the field's own where the footprint takes all of it (the same counts,
    // bit for bit), else that of its share.
    const PoissonCdf top_law =
        top < cl.last && top_mean == kClassMean ? kWholeClass : PoissonCdf(top_mean);
    const int lowest = std::max(0, top - kClassSpan);
    for (uint32_t a = 0; any_area && a < cf.n_agg; ++a) {
        // Each tile's classes once (at its first aggregate).
        const Aggregate& ag = cf.agg[a];
        bool seen = false;
        for (uint32_t b = 0; b < a; ++b)
            seen = seen || (cf.agg[b].tx == ag.tx && cf.agg[b].ty == ag.ty);
        if (seen) continue;
        Footprint local = p;
        local.cu -= static_cast<double>(ag.tx);
        local.cv -= static_cast<double>(ag.ty);
        const double hx = 0.5 * (std::fabs(local.ax) + std::fabs(local.bx)),
                     hy = 0.5 * (std::fabs(local.ay) + std::fabs(local.by));
        // The candidates of every class, block by block, along each row of blocks only those
        // under P's span in that row (a turned or needle-shaped footprint's bounding box holds
        // up to several times the blocks that meet it): their hashes and places, kept where they
        // lie inside P, tested without a branch (a branch on it was mispredicted for half of
        // them) and compacted as they are made.
        uint32_t m = 0;
        const StripSpan span(local);
        for (int c = lowest; c <= top; ++c) {
            const double block = pow2_neg(c + 3);
            const double blocks = 1.0 / block;
            // Blocks under P's bounding box within the tile (a centre that is not finite gives
            // block 0, none of whose flakes lies inside).
            const int64_t bx0 = block_index(local.cu - hx, blocks),
                          bx1 = block_index(local.cu + hx, blocks),
                          by0 = block_index(local.cv - hy, blocks),
                          by1 = block_index(local.cv + hy, blocks);
            // A bound on the work (a needle's bounding box): 64 x 64 blocks.
            const int64_t n_blocks = (bx1 - bx0 + 1) * (by1 - by0 + 1);
            if (n_blocks > 4096) continue;
            const double mean = c < top ? class_mean(c) : top_mean;
            if (!(mean > 0.0)) continue;
            // Below top: the field's whole classes, its last (perhaps partial) one, the virtual
            // ones beyond; top: its own share's law.
            PoissonCdf last_law;
            if (c < top && c == cl.last) last_law = poisson_law(cl.mean(c));
            const PoissonCdf& law = c < top ? (c == cl.last ? last_law : kWholeClass) : top_law;
            const uint64_t ckey = class_key(ag.tile, c);
            // Room for 8 a block (a count above 7 is rare: grown then), through plain pointers
            // (the scratch is a thread_local: each use of it through the vectors called
            // __tls_get_addr).
            sc.reserve(m + static_cast<std::size_t>(n_blocks) * 8);
            std::size_t room = sc.hash.size();
            uint64_t* chash = sc.hash.data();
            double* cx = sc.x.data();
            double* cy = sc.y.data();
            for (int64_t by = by0; by <= by1; ++by) {
                int64_t rx0 = bx0, rx1 = bx1;
                if (!span.row_blocks(by, block, rx0, rx1)) continue;
                for (int64_t bx = rx0; bx <= rx1; ++bx) {
                    const uint64_t bkey = block_key(ckey, bx, by);
                    const uint32_t count = law.count(bkey);
                    if (m + count > room) {
                        sc.reserve(m + count);
                        room = sc.hash.size();
                        chash = sc.hash.data();
                        cx = sc.x.data();
                        cy = sc.y.data();
                    }
                    for (uint32_t i = 0; i < count; ++i) {
                        double x, y;
                        chash[m] = class_flake_position(bkey, i, bx, by, block, x, y);
                        cx[m] = x;
                        cy[m] = y;
                        m += inside_nonsingular(local, x, y) ? 1u : 0u;
                    }
                }
            }
        }
        if (m == 0) continue;
        if (sc.kept_hash.size() < n_kept + m) {
            sc.kept_hash.resize(2 * (n_kept + m));
            sc.kept_agg.resize(2 * (n_kept + m));
        }
        const double* const cx = sc.x.data();
        const double* const cy = sc.y.data();
        const uint64_t* const chash = sc.hash.data();
        // Each inside candidate is kept for the first of this tile's aggregates whose cell holds
        // it (cells of other tiles, or cells the tree enumerates, have their own flakes), found
        // without a branch: whether a candidate lies in a cell is a coin toss along its edges.
        // (At most 4: gather_cells gives a tile at most 2 x 2 cells of the footprint's level.)
        uint32_t local_agg[4];
        double gx0[4], gy0[4], gx1[4], gy1[4];
        uint32_t n_local = 0;
        for (uint32_t b = a; b < cf.n_agg && n_local < 4; ++b) {
            const Aggregate& g = cf.agg[b];
            if (g.tx != ag.tx || g.ty != ag.ty) continue;
            local_agg[n_local] = b;
            gx0[n_local] = g.x0;
            gy0[n_local] = g.y0;
            gx1[n_local] = g.x0 + g.size;
            gy1[n_local++] = g.y0 + g.size;
        }
        uint64_t* const kh = sc.kept_hash.data();
        uint8_t* const ka = sc.kept_agg.data();
        for (uint32_t j = 0; j < m; ++j) {
            const double x = cx[j], y = cy[j];
            uint32_t which = n_local;
            for (uint32_t q = n_local; q-- > 0;) {
                const bool in_cell = (x >= gx0[q]) & (x < gx1[q]) & (y >= gy0[q]) & (y < gy1[q]);
                which = in_cell ? q : which;
            }
            const bool survives = keep >= 1.0f || kept(x + static_cast<double>(ag.tx),
                                                       y + static_cast<double>(ag.ty), keep);
            kh[n_kept] = chash[j];
            ka[n_kept] = static_cast<uint8_t>(local_agg[which < n_local ? which : 0]);
            n_kept += static_cast<uint32_t>((which < n_local) & survives);
        }
    }
    // A stand-in's own hash picks its colour and film; with neither table (one colour, no film)
    // it is not needed.
    const bool own = colors.varies() || film.varies();
    // The kept candidates grouped by aggregate (a counting sort: a scan of all of them per
    // aggregate was a seventh of a counted footprint's time).
    // (One aggregate, most footprints: they are grouped already.)
    uint32_t start[kMaxAggregates + 1] = {};
    uint64_t* grouped = sc.kept_hash.data();
    if (cf.n_agg == 1) {
        start[1] = n_kept;
    } else {
        for (uint32_t j = 0; j < n_kept; ++j) ++start[sc.kept_agg[j] + 1];
        for (uint32_t a = 0; a < kMaxAggregates; ++a) start[a + 1] += start[a];
        if (sc.found.size() < n_kept) sc.found.resize(n_kept);
        grouped = sc.found.data();
        uint32_t pos[kMaxAggregates];
        std::copy(start, start + kMaxAggregates, pos);
        for (uint32_t j = 0; j < n_kept; ++j) grouped[pos[sc.kept_agg[j]]++] = sc.kept_hash[j];
    }
    uint32_t found_all = 0;
    EntryBatch batch;
    FieldParams lazy = fp;
    lazy.lazy_normals = true;
    lazy.flake_ids = own;
    for (uint32_t a = 0; a < cf.n_agg; ++a) {
        const uint32_t k = cf.agg[a].count;
        const uint32_t room = std::min(k, cap - found_all);
        uint64_t* const found = grouped + start[a];
        const uint32_t in_cell = start[a + 1] - start[a];
        // More than its k flakes (or the room left): those of the smallest hashes (a priority
        // of their own: footprints keep the same ones among those they share).
        if (in_cell > room) std::nth_element(found, found + room, found + in_cell);
        const uint32_t n = std::min(in_cell, room);
        found_all += n;
        if (n == 0) {
            cf.smooth += static_cast<float>(k);
            continue;
        }
        // beta = sqrt(K / k) of the aggregate's weight is in its K stand-ins, sqrt(k / K) each.
        const float scale = std::sqrt(static_cast<float>(k) / static_cast<float>(n));
        cf.smooth += static_cast<float>(k) - scale * static_cast<float>(n);
        for (uint32_t q = 0; q < n; ++q) {
            // The very flake the enumeration makes of it.
            Flake f;
            class_flake_finish(lazy, found[q], f);
            const float* col = colors.single;
            const FresnelTable* fr = &fresnel;
            if (own) {
                col = colors.pick(f.color_u, f.id);
                fr = &film.pick(f.id, fresnel);
            }
            batch.add(wo, grid.alpha, f.s, f.t, col, fr, scale, out);
        }
    }
    flush_entries(wo, grid.alpha, batch, out);
    cf.smooth = std::max(cf.smooth, 0.0f);
}

}  // namespace spangle::flake
