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
// - its k flakes' normals are spread over the square of flake normals (see flake_normal) by a
//   quad-tree keyed by the cell, down to leaves about half the cone's preimage: stratified splits
//   (each child n / 4, the remainder to hashed children) above the last level, so that the
//   aggregate's energy footprint by footprint is its expected one, and a multinomial in the last
//   level for the local grain; adding a flake to k adds it to exactly one leaf;
// - its lobe is the exact smooth lobe times a modulation M(wi) = (tent-weighted count of the
//   leaves whose centre reflects wo near wi) / (that count's expectation). E[M] = 1 exactly, for
//   any leaf size and weighting, so the aggregate's mean is the smooth lobe's; the counts give
//   it the grain of real flakes (Poisson-like in each direction, glints of about the cone's size)
//   and each leaf's flakes their own colours from the colour table.
//
// Aggregated flakes are statistical stand-ins: a pure function of (seed, cell, leaf), the same
// from every view and frame, but not the same flakes as the enumeration would find (a cell
// switches between the two when the footprint's size crosses the cell's). Normalisation follows
// the reflection cache: W = sum of the cached flakes' w + k E[w] per aggregate, so a footprint
// reflects the mean F c of its flakes, up to the spread of the aggregated flakes' w (about
// CV(w) / sqrt(k)).

#include <cstdint>
#include <vector>

#include "discrete_lobe.h"
#include "field.h"
#include "palette.h"
#include "thin_film.h"

namespace spangle::flake {

/** Virtual flakes of one aggregated cell inside the footprint. */
struct Aggregate {
    uint64_t key = 0;    ///< the cell's node key (its direction tree is keyed from it)
    uint32_t count = 0;  ///< k: flakes of the cell inside the footprint
    /** Sparse in every direction (see mark_sparse): its lobe is always its virtual flakes, and
     *  it is sampled by picking one of them. */
    bool sparse = false;
};

/** At most this many aggregates per shading point (2 x 2 cells in each of up to four tiles). */
constexpr uint32_t kMaxAggregates = 16;

/** The direction side of the counting algorithm, per material: the leaf level of the aggregates'
 *  direction trees and the normals at the leaf centres. */
struct DirectionGrid {
    /** Level of the direction tree whose realised counts set an aggregate's weight (see
     *  realised_weight). */
    static constexpr int kWeightLevel = 2;
    static constexpr int kWeightNodes = 1 << (2 * kWeightLevel);
    /** kWeightSide^2 stratified normals per node estimate its mean weight. */
    static constexpr int kWeightSide = 2;
    int depth = 4;            ///< leaves are 4^-depth of the square of flake normals
    int weight_level = 2;     ///< min(kWeightLevel, depth)
    float alpha = 0.15f;      ///< flake roughness
    float sin2_half = 0.0f;   ///< sin^2(gamma / 2) of the cone
    std::vector<V3> centres;  ///< normal at each leaf centre, row-major (2^depth per row)
    /** kWeightSide^2 stratified normals in each node of weight_level (node-major). */
    std::vector<V3> weight_normals;
    /** Chooses the leaf level from the cone's size relative to the flake roughness. */
    void init(float alpha_, float gamma_rad);
};

/** What the footprint holds, as the counting algorithm sees it. */
struct CountedFootprint {
    Aggregate agg[kMaxAggregates];
    uint32_t n_agg = 0;
    uint32_t aggregated = 0;  ///< sum of the aggregates' counts
    uint32_t dense = 0;       ///< sum of the counts of the aggregates that are not sparse
    bool truncated = false;   ///< the footprint spans more tiles than the algorithm handles
};

/** Marks the aggregates that light every direction sparsely: k times the largest chance that
 *  one flake lights a direction (thr / (4 alpha^2 cos_o), at the distribution's peak) is below
 *  kDenseLit. Sets cf.dense. */
void mark_sparse(CountedFootprint& cf, const DirectionGrid& grid, float cos_o);

/** Samples a direction from sparse aggregate a: one of its virtual flakes, each as likely as
 *  its weight (a descent of its direction tree by the counts, u choosing the way), then a
 *  direction uniform in that flake's cone (u0, u1). False when the flake faces away from wo or
 *  the direction falls under the horizon. The density is lit / (k sigma), lit from
 *  aggregate_lobe. */
bool sample_aggregate(const Aggregate& a, const DirectionGrid& grid, int exact_below, V3 wo,
                      float u, float u0, float u1, V3& wi);

/** Walks the cells of P: calls exact(const Flake&) for every flake of the enumerated cells that
 *  lies inside P and fills `out` with the aggregates. `exact_flakes` is the largest cell count
 *  that is enumerated. Work is bounded: at most 16 tiles, 4 cells each. */
template <class Exact>
void gather_cells(const FieldParams& fp, const Footprint& p, uint32_t exact_flakes,
                  CountedFootprint& out, Exact&& exact);

/** Aggregates whose expected count of flakes lighting a direction is at least this are "dense"
 *  there (see aggregate_lobe). */
constexpr float kDenseLit = 16.0f;

/** The aggregates' part of the discrete lobe at wi, in two forms, per aggregate by how densely
 *  its flakes light wi on average:
 *  - sparse (fewer than kDenseLit expected): its flakes near wi as individual virtual flakes, in
 *    the leaves of its direction tree that can reach wi, at positions hashed uniformly within
 *    each leaf; `virt` gets sum w c F over those whose cone holds wi, in the units of the
 *    reflection cache's cone sums (each glint as sharp and as bright as a real flake's);
 *  - dense: `mod` gets sum_a k_a M_a(wi) per channel, the colour-weighted modulation of the
 *    smooth lobe (per flake of unit colour) by the counts of the leaves near wi, E[M] = 1. With
 *    many flakes per cone the lobe is nearly continuous, and this costs the same for any count.
 *  Both are unbiased: the expected lobe is the smooth lobe either way. Sparse aggregates (see
 *  mark_sparse) are always treated the first way; `lit` gets the summed weight of their virtual
 *  flakes whose cone holds wi (for the density of sample_aggregate). */
void aggregate_lobe(const CountedFootprint& cf, const DirectionGrid& grid, const ColorTable& colors,
                    const FresnelTable& fresnel, const FilmTables& film, V3 wo, V3 wi,
                    int exact_below, float virt[3], float mod[3], float& lit);

/** The mean projected-area weight w = (wo.m) / m.z of the valid flakes (facing wo, reflecting
 *  above the horizon) in each node of the direction tree's weight_level, as a share of the
 *  square (kWeightSide^2 normals per node). */
void node_weights(const DirectionGrid& grid, V3 wo, float out[DirectionGrid::kWeightNodes]);

/** An aggregate's realised weight relative to its expected one, k E[w]: its flakes' counts in the
 *  nodes of weight_level (the same splits the modulation descends through) weighted by the nodes'
 *  mean weights. The reflection cache normalises by its flakes' actual weights, so that a
 *  footprint whose flakes happen to face the viewer more reflects no more than it receives; this
 *  does the same for the aggregates at the scale where their counts vary most in energy (the
 *  square's quadrants differ most at grazing views, where half of them reflect under the
 *  horizon). Returns 1 when no node holds a valid flake. */
float realised_weight(const Aggregate& a, const DirectionGrid& grid,
                      const float node_w[DirectionGrid::kWeightNodes], int exact_below);

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
