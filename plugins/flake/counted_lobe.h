#pragma once
// The counting algorithm ("tree"): the discrete lobe at a cost that does not grow with the number
// of flakes in the footprint.
//
// The footprint is covered by the quad-tree cells of the finest level whose cells are at least as
// large as the footprint, so it overlaps at most 2 x 2 of them (per uv tile). A cell holding at
// most `exact_flakes` flakes is enumerated: its true flakes enter the reflection cache exactly as
// the enumerating algorithm does, so small footprints see the very same glints. A larger cell is
// an aggregate:
//
// - its count inside the footprint is k = B(n, rho), rho the share of the cell's area the
//   footprint covers, drawn by inverting a uniform fixed per cell (so k only grows as the
//   footprint covers more of the cell);
// - K of its flakes are stand-ins (the footprint's K_max shared among its aggregates by their
//   counts, K = min(k, ceil(K_max k / sum of k))): normals drawn from the flake distribution by a
//   hash of (the aggregate's key, index), each entering the reflection cache as a real flake does
//   (its own cone, colour and film), with its weight times sqrt(k / K); the other k (1 - beta)
//   flakes' worth, beta = sqrt(K / k), is the smooth lobe (the exact expectation of one flake's
//   lobe) times k (1 - beta) flakes of the expected weight. When the footprint's aggregates hold
//   at most K_max flakes in all, every one is a stand-in of its own (beta = 1).
//
// Energy: the normaliser W is the sum of the weights of what the lobe holds, the cache's (true
// flakes and stand-ins, each w_j times its factor) plus k (1 - beta) E[w]; each cache entry
// reflects at most its weight (the share of its cone above the horizon, times F <= 1) and the
// smooth lobe at most E[w] per flake, so every footprint reflects at most what it receives, as the
// enumeration does, whatever the stand-ins drawn.
// Mean: the stand-ins' normals follow the flake distribution, so the expected lobe of the
// aggregate is k smooth lobes whatever beta is: the footprint average is the smooth lobe.
// Grain: in a direction lit by k p flakes on average (p the chance that one flake's cone holds
// it), the stand-ins give the lobe a relative variance beta^2 / (K p) = 1 / (k p), that of k real
// flakes; with few flakes per cone (K = k) the glints are single flakes, as real ones are.
//
// Stand-ins are statistical: a pure function of (seed, cell, place, index), the same from every
// view and frame, but not the same flakes as the enumeration would find (a cell switches between
// the two when the footprint's size crosses the cell's).

#include <cstdint>
#include <vector>

#include "discrete_lobe.h"
#include "field.h"
#include "palette.h"
#include "thin_film.h"

namespace spangle::flake {

/** Flakes of one aggregated cell inside the footprint. */
struct Aggregate {
    uint64_t key = 0;    ///< the cell's node key with the footprint's place (see place_key)
    uint32_t count = 0;  ///< k: flakes of the cell inside the footprint
};

/** At most this many aggregates per shading point (2 x 2 cells in each of up to four tiles). */
constexpr uint32_t kMaxAggregates = 16;

/** The direction side of the counting algorithm, per material: the flake distribution and the
 *  cone. */
struct DirectionGrid {
    float alpha = 0.15f;     ///< flake roughness
    float sin2_half = 0.0f;  ///< sin^2(gamma / 2) of the cone
    void init(float alpha_, float gamma_rad);
};

/** What the footprint holds, as the counting algorithm sees it. */
struct CountedFootprint {
    Aggregate agg[kMaxAggregates];
    uint32_t n_agg = 0;
    uint32_t aggregated = 0;  ///< sum of the aggregates' counts
    /** Flakes of the aggregates carried by the smooth lobe, sum of k (1 - beta) (set by
     *  add_stand_ins). */
    float smooth = 0.0f;
    bool truncated = false;  ///< the footprint spans more tiles than the algorithm handles
};

/** Aggregates of at most this many flakes light every direction sparsely (fewer than kDenseLit
 *  flakes per cone on average at the distribution's peak, thr / (4 alpha^2 cos_o) per flake). */
constexpr float kDenseLit = 16.0f;
float sparse_count(const DirectionGrid& grid, float cos_o);

/** Stand-ins per footprint, shared among its aggregates (each at least one): sparse_count()
 *  clamped to [kMinStandIns, kMaxStandIns]. */
constexpr uint32_t kMinStandIns = 16;
constexpr uint32_t kMaxStandIns = 64;

/** Appends the stand-ins of cf's aggregates, seen from wo, to the reflection cache `out` and sets
 *  cf.smooth (see the top of this file). */
void add_stand_ins(CountedFootprint& cf, const DirectionGrid& grid, const ColorTable& colors,
                   const FresnelTable& fresnel, const FilmTables& film, V3 wo,
                   std::vector<CacheEntry>& out);

/** Walks the cells of P: calls exact(const Flake&) for every flake of the enumerated cells that
 *  lies inside P and fills `out` with the aggregates. `exact_flakes` is the largest cell count
 *  that is enumerated. Work is bounded: at most 16 tiles, 4 cells each. */
template <class Exact>
void gather_cells(const FieldParams& fp, const Footprint& p, uint32_t exact_flakes,
                  CountedFootprint& out, Exact&& exact);

/** The key of an aggregate's flakes: the cell's key and where in the cell the footprint's centre
 *  lies, on a grid of the footprint's half size (a power-of-two fraction of the cell). The k
 *  flakes counted in a cell are stand-ins for the flakes of the part of the cell the footprint
 *  covers, so two footprints at different places of one cell (neighbouring pixels) must not see
 *  the same stand-ins: keyed by the cell alone they did, and the same glints and the same
 *  modulation of the lobe spread over every pixel of the cell (blotches and dashes where real
 *  flakes are points). With the place in the key, footprints half their size apart or more see
 *  independent stand-ins, as footprints that share no flake do; a footprint that moves by less
 *  keeps them. */
uint64_t place_key(uint64_t cell_key, const Footprint& local, double x0, double y0, double size);

/** The quad-tree level (0 = the tile) whose cells are the smallest at least as large as P's
 *  bounding box, so that P overlaps at most 2 x 2 of them; at most the field's max_depth. */
int footprint_level(const FieldParams& fp, const Footprint& p);

/** A node of a tile's quad-tree: where it is and how many flakes it holds. */
struct NodeRef {
    int depth = 0;
    uint32_t ix = 0, iy = 0, n = 0;
};

/** The node that holds the flakes of cell (depth, ix, iy) of tile (tx, ty): the cell itself, or
 *  the leaf above it when the tree stops splitting before `depth`. */
NodeRef resolve_cell(const FieldParams& fp, int64_t tx, int64_t ty, int depth, uint32_t ix,
                     uint32_t iy);

/** resolve_cell() for the neighbouring cells of one footprint: the path from the tile's root is
 *  kept, so that the next cell of the same tile starts from the deepest common ancestor (the 2 x 2
 *  cells of a footprint share all but the last few levels). Same results. */
class CellResolver {
public:
    explicit CellResolver(const FieldParams& fp) : fp_(fp) {}
    NodeRef resolve(int64_t tx, int64_t ty, int depth, uint32_t ix, uint32_t iy);

private:
    const FieldParams& fp_;
    int64_t tx_ = 0, ty_ = 0;
    uint64_t tile_ = 0;
    int levels_ = 0;  ///< path_[0 .. levels_ - 1] are valid (0: none yet)
    NodeRef path_[32];
};

// ------------------------------------------------------------------------------------ template

template <class Exact>
void gather_cells(const FieldParams& fp, const Footprint& p, uint32_t exact_flakes,
                  CountedFootprint& out, Exact&& exact) {
    out = CountedFootprint{};
    const TileRange tr = tiles_of(p);
    if (tr.count() > 4) {
        out.truncated = true;
        return;
    }
    const int depth = footprint_level(fp, p);
    const double size = pow2_neg(depth);
    CellResolver resolver(fp);
    for (int64_t ty = tr.ty0; ty <= tr.ty1; ++ty)
        for (int64_t tx = tr.tx0; tx <= tr.tx1; ++tx) {
            // P relative to this tile; the cells of `depth` under its bounding box.
            const double cu = p.cu - static_cast<double>(tx), cv = p.cv - static_cast<double>(ty);
            const double hx = p.half_width(), hy = p.half_height();
            const double cells = 1.0 / size;
            const auto lo = [&](double x) {
                return static_cast<int64_t>(std::clamp(std::floor(x / size), 0.0, cells - 1));
            };
            const int64_t ix0 = lo(cu - hx), ix1 = lo(cu + hx), iy0 = lo(cv - hy),
                          iy1 = lo(cv + hy);
            Footprint local = p;
            local.cu = cu;
            local.cv = cv;
            NodeRef seen[4];
            int n_seen = 0;
            for (int64_t iy = iy0; iy <= iy1; ++iy)
                for (int64_t ix = ix0; ix <= ix1; ++ix) {
                    const double x0 = static_cast<double>(ix) * size,
                                 y0 = static_cast<double>(iy) * size;
                    if (!overlaps(local, x0, y0, x0 + size, y0 + size)) continue;
                    const NodeRef node = resolver.resolve(tx, ty, depth, static_cast<uint32_t>(ix),
                                                          static_cast<uint32_t>(iy));
                    if (node.n == 0) continue;
                    // Cells inside one leaf share it: visit each node once.
                    bool dup = false;
                    for (int k = 0; k < n_seen; ++k)
                        dup = dup || (seen[k].depth == node.depth && seen[k].ix == node.ix &&
                                      seen[k].iy == node.iy);
                    if (dup) continue;
                    seen[n_seen++] = node;
                    if (node.n <= exact_flakes) {
                        bool trunc = false;
                        flakes_in_node(fp, p, tx, ty, node.depth, node.ix, node.iy, node.n, node.n,
                                       trunc, exact);
                        continue;
                    }
                    // The share of the cell inside P, and as many of its flakes (monotone in it).
                    const double nsize = pow2_neg(node.depth);
                    const double nx0 = node.ix * nsize, ny0 = node.iy * nsize;
                    const double rho =
                        overlap_area(local, nx0, ny0, nx0 + nsize, ny0 + nsize) / (nsize * nsize);
                    const uint64_t key =
                        node_key(tile_key(fp.seed, tx, ty), node.depth, node.ix, node.iy);
                    const uint32_t k = binomial(node.n, std::clamp(rho, 0.0, 1.0),
                                                unit(mix(key, 0x51)), fp.exact_below);
                    if (k == 0 || out.n_agg >= kMaxAggregates) continue;
                    out.agg[out.n_agg++] = {place_key(key, local, nx0, ny0, nsize), k};
                    out.aggregated += k;
                }
        }
}

}  // namespace spangle::flake
