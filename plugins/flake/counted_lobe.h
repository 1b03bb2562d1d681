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
// - its stand-ins are the field's ranked classes (field.h): real flakes, laid out once per tile
//   in classes c = 0, 1, ... of 192 x 4^c per tile (a Poisson count of mean 3 per block of
//   2^-(c + 3) of the tile), whatever the footprint. A footprint of area A takes the density
//   `stand_ins` / A of them (whole classes, and a share of the densest: nested as A shrinks, so
//   a dollying camera keeps its glints, and found again by the enumeration where the cell
//   becomes few enough to enumerate; virtual classes of the same layout beyond the field's
//   where a footprint wants more than they hold). The K of them inside the footprint and the
//   cell (at most k: those of smallest hash) enter the reflection cache as real flakes do, each
//   with its weight times sqrt(k / K); the other k (1 - beta) flakes' worth, beta = sqrt(K / k),
//   is the smooth lobe (the exact expectation of one flake's lobe) times k (1 - beta) flakes of the
//   expected weight. When a
//   footprint's aggregate holds at most as many flakes as it finds stand-ins, k of them are its
//   flakes (beta = 1).
//   Because stand-ins have places, footprints share them as they share real flakes: two that
//   overlap by half share about half (the samples of one pixel see nearly the same glints, as
//   they see nearly the same flakes), two side by side share none (their glints are their own).
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
// Stand-ins are a pure function of (seed, tile, class, block, index), the same from every view
// and frame, and the same flakes as the enumeration finds (but for the virtual classes beyond the
// field's): a cell switching from counted to enumerated as a footprint shrinks keeps them.

#include <cstdint>
#include <vector>

#include "discrete_lobe.h"
#include "field.h"
#include "palette.h"
#include "thin_film.h"

namespace spangle::flake {

/** Flakes of one aggregated cell inside the footprint. */
struct Aggregate {
    uint64_t key = 0;                 ///< the cell's node key
    uint64_t tile = 0;                ///< its tile's key (the stand-ins' classes are keyed by it)
    uint32_t count = 0;               ///< k: flakes of the cell inside the footprint
    int64_t tx = 0, ty = 0;           ///< the tile holding the cell
    double x0 = 0, y0 = 0, size = 0;  ///< the cell in its tile's coordinates
};

/** At most this many aggregates per shading point (2 x 2 cells in each of up to four tiles). */
constexpr uint32_t kMaxAggregates = 16;

/** The direction side of the counting algorithm, per material: the flake distribution and the
 *  cone. (Default-constructed, before init(), its lit_share is 0: every footprint is sparse.) */
struct DirectionGrid {
    float alpha = 0.15f;     ///< flake roughness
    float sin2_half = 0.0f;  ///< sin^2(gamma / 2) of the cone
    static constexpr int kLitNodes = 17;
    /** lit_share_exact() at cos_o = (i / (kLitNodes - 1))^2 (i = 0: cos_o 1e-4). */
    float lit[kLitNodes] = {};
    /** Sets the distribution and the cone, and the lit table where `with_lit` (2 to 5 ms: left
     *  0 for a material that never asks, as `enumerate` or `sparse_flakes` 0). */
    void init(float alpha_, float gamma_rad, bool with_lit = true);
    /** lit_share_exact() interpolated in sqrt(cos_o). */
    float lit_share(float cos_o) const;
};

/** What the footprint holds, as the counting algorithm sees it. */
struct CountedFootprint {
    Aggregate agg[kMaxAggregates];
    uint32_t n_agg = 0;
    uint32_t aggregated = 0;  ///< sum of the aggregates' counts
    /** Their expectation, sum of n rho over the counted cells: what facets count towards the
     *  footprint's cover (a count drawn by a quantile fixed per cell made every footprint of a
     *  cell a facet's width wide darker or lighter alike: square blocks). */
    double expected = 0.0;
    /** Flakes of the aggregates carried by the smooth lobe, sum of k (1 - beta) (set by
     *  add_stand_ins). */
    float smooth = 0.0f;
    bool truncated = false;  ///< the footprint spans more tiles than the algorithm handles
};

/** Cells of at most 16 alpha^2 cos_o / sin^2(gamma / 2) flakes light every direction sparsely:
 *  fewer than kDenseLit per cone on average at the distribution's peak. */
constexpr float kDenseLit = 16.0f;
constexpr double kSparseExactCap = 4096.0;

/** The largest cell the counting algorithm enumerates for a view of cos(theta_o) = cos_o:
 *  exact_flakes, or more for cells whose flakes would light every direction sparsely (above), up
 *  to kSparseExactCap. Enumerated, each glint is a flake with its own position; counted, a cell's
 *  glints are stand-ins. Dense cells stay counted. */
uint32_t exact_limit(uint32_t exact_flakes, const DirectionGrid& grid, float cos_o);

/** How sparsely the flakes light the directions of their lobe, seen from cos_o: the share p
 *  such that a footprint of k flakes lights a typical direction of the lobe as k p flakes of
 *  equal weight would. Per direction d, k flakes give f(d) a spread sd / mean =
 *  sqrt(E[w^2 1_d]) / (sqrt(k) E[w 1_d]) (1_d: the flake's cone holds d; w its projected area
 *  towards wo); p is 1 / (k cv^2) for cv, that spread at one flake, in the median direction of
 *  those drawn from the lobe itself. (Not the mean: GGX's heavy tails hold directions that next
 *  to no flake reaches, and a mean over them fell without end as the flakes computed grew.)
 *  Computed over the unit square's midpoint grid of flake normals (24 x 24 to 48 x 48: enough
 *  for some 16 other flakes' cones at that direction) and 256 directions; 0 where the median
 *  direction meets no other flake's cone (p below what the grid resolves). */
double lit_share_exact(float alpha, float sin2_half, float cos_o);

/** Default of `sparse_flakes`. */
constexpr float kSparseFlakes = 128.0f;
/** The most flakes (expected, after the view's thinning: FieldView::lambda()) in a footprint
 *  that sparse_share() enumerates. */
constexpr double kSparseEnumerate = 4096.0;

/** How much of a footprint's discrete lobe the counting algorithm makes by enumerating its flakes
 *  (1: all of it, 0: none: its cells are counted; between, the two lobes are mixed in that
 *  proportion) for a footprint of `lambda` flakes (expected) seen from cos_o, blended with the
 *  smooth lobe by t. Enumerated where it lights a typical direction of its lobe by at most
 *  `sparse_flakes` flakes (lambda lit_share), holds at most kSparseEnumerate and is more
 *  discrete than smooth (t below 1/2). Counted, a cell's stand-ins match real flakes in spread
 *  (each direction's sd / mean) at any count, but in shape only where a direction meets several
 *  of them: with K stand-ins for k flakes (K < k), the k (1 - sqrt(K / k)) flakes of the smooth
 *  part are a floor under every direction, and where real flakes light a direction by a few
 *  each, so that some directions are dark, the floor fills the gaps between glints and a few
 *  stand-ins are too bright. (Raising the stand-ins to as many flakes cost more than enumerating
 *  them.) Real flakes lighting a direction by m leave it darker than half its mean with the
 *  chance of a Poisson count under m / 2 (0.07% at m = 32); but the typical direction is the
 *  median one, and the lobe's tails, a quarter as densely lit and more, show gaps where it shows
 *  none: `sparse_flakes` 128 by default (at 32 a receding plane of wide cones kept its grey floor
 *  in the distance). Beyond t = 1/2 the smooth share is itself such a floor.
 *
 *  The change is a fade, not a switch: the stand-ins are K of the k flakes, so the counted lobe
 *  and the enumerated one of the same footprint correlate only as sqrt(K / k) (0.23 at the
 *  default paint's t = 1/2, lambda 1 000): switched at once, every glint of a dollying camera's
 *  surface changed in one frame where the footprint crossed the edge. Each of the three bounds
 *  fades over a factor of two below it (lambda lit_share from sparse_flakes / 2, lambda from
 *  kSparseEnumerate / 2: smoothsteps in log2) and t from 0.1 to 1/2, the share being their
 *  product, so no footprint is enumerated beyond where it was. A footprint that shrinks holds
 *  fewer flakes and a smaller t: its share only grows, and its stand-ins were real flakes, which
 *  the enumeration keeps. `sparse_flakes` 0: never (0). */
float sparse_share(float sparse_flakes, const DirectionGrid& grid, float cos_o, double lambda,
                   float t);

/** Stand-ins a footprint finds on average by default (the `stand_ins` parameter): the classes it
 *  takes are this dense. (Drawn per footprint and fewer at grazing views, 16 there, a
 *  receding flake plane's glints were a grey floor with a few bright dashes where the enumeration
 *  shows dense sparkle; and stand-ins keyed by where the footprint lay in its cell, the samples of
 *  one pixel fell on up to four places and averaged independent stand-ins: a smoother pixel than
 *  one of real flakes.) A footprint keeps at most four times as many in all. */
constexpr uint32_t kStandIns = 64;

/** Appends the stand-ins of cf's aggregates inside footprint p, `stand_ins` per footprint area
 *  on average (those that survive the view's thinning to `keep`, as kept() thins the
 *  enumeration's flakes), seen from wo, to the reflection cache `out` and sets cf.smooth (see the
 * top of this file). */
void add_stand_ins(CountedFootprint& cf, const FieldParams& fp, const Footprint& p, float keep,
                   uint32_t stand_ins, const DirectionGrid& grid, const ColorTable& colors,
                   const FresnelTable& fresnel, const FilmTables& film, V3 wo,
                   std::vector<CacheEntry>& out);

/** Walks the cells of P: calls exact(const Flake&) for every flake of the enumerated cells that
 *  lies inside P and fills `out` with the aggregates. `exact_flakes` is the largest cell count
 *  that is enumerated. Work is bounded: at most 4 tiles, 4 cells each. */
template <class Exact>
void gather_cells(const FieldParams& fp, const Footprint& p, uint32_t exact_flakes,
                  CountedFootprint& out, Exact&& exact);

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
    const ClassLayout cl = class_layout(fp);
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
            const uint64_t tk = tile_key(fp.seed, tx, ty);  // (once per tile, not per cell)
            NodeRef seen[4];
            int n_seen = 0;
            // The cells enumerated: their class flakes are visited together after the loop (the
            // coarse classes' blocks, larger than the cells, once for them all).
            double box[4][3];
            int n_box = 0;
            for (int64_t iy = iy0; iy <= iy1; ++iy)
                for (int64_t ix = ix0; ix <= ix1; ++ix) {
                    const double x0 = static_cast<double>(ix) * size,
                                 y0 = static_cast<double>(iy) * size;
                    if (!overlaps(local, x0, y0, x0 + size, y0 + size)) continue;
                    const NodeRef node = resolver.resolve(tx, ty, depth, static_cast<uint32_t>(ix),
                                                          static_cast<uint32_t>(iy));
                    // Cells inside one leaf share it: visit each node once.
                    bool dup = false;
                    for (int k = 0; k < n_seen; ++k)
                        dup = dup || (seen[k].depth == node.depth && seen[k].ix == node.ix &&
                                      seen[k].iy == node.iy);
                    if (dup) continue;
                    seen[n_seen++] = node;
                    const double nsize = pow2_neg(node.depth);
                    const uint64_t key = node_key(tk, node.depth, node.ix, node.iy);
                    // The cell's flakes: its tree node's and its share of the classes'. Whether
                    // it is enumerated follows their expectation (a draw deciding it would
                    // enumerate the cells whose draw fell low: more than their share of flakes,
                    // and none of a cell whose node and draw were both empty); its count, if
                    // counted, is drawn.
                    const double expected =
                        static_cast<double>(node.n) + cl.per_tile * nsize * nsize;
                    if (expected <= 0.0) continue;
                    if (expected <= static_cast<double>(exact_flakes)) {
                        // (The budget bounds nothing here: the cell holds few flakes.)
                        bool trunc = false;
                        flakes_in_node(fp, nullptr, p, tx, ty, node.depth, node.ix, node.iy, node.n,
                                       1u << 30, trunc, exact);
                        box[n_box][0] = node.ix * nsize;
                        box[n_box][1] = node.iy * nsize;
                        box[n_box++][2] = nsize;
                        continue;
                    }
                    // The share of the cell inside P, and as many of its flakes (monotone in it).
                    const double nx0 = node.ix * nsize, ny0 = node.iy * nsize;
                    const double rho =
                        overlap_area(local, nx0, ny0, nx0 + nsize, ny0 + nsize) / (nsize * nsize);
                    const uint32_t n = node.n + class_count_in_cell(cl, key, nsize);
                    const uint32_t k = binomial(n, std::clamp(rho, 0.0, 1.0), unit(mix(key, 0x51)),
                                                fp.exact_below);
                    out.expected += expected * std::clamp(rho, 0.0, 1.0);
                    if (k == 0 || out.n_agg >= kMaxAggregates) continue;
                    out.agg[out.n_agg++] = {key, tk, k, tx, ty, nx0, ny0, nsize};
                    out.aggregated += k;
                }
            if (n_box > 0) {
                double x0 = box[0][0], y0 = box[0][1], x1 = x0 + box[0][2], y1 = y0 + box[0][2];
                for (int b = 1; b < n_box; ++b) {
                    x0 = std::min(x0, box[b][0]);
                    y0 = std::min(y0, box[b][1]);
                    x1 = std::max(x1, box[b][0] + box[b][2]);
                    y1 = std::max(y1, box[b][1] + box[b][2]);
                }
                // The boxes are distinct nodes of the tree, so they tile the rectangle around
                // them when their areas add up to its (dyadic numbers: exact sums); then the
                // rectangle's own test is theirs, and the loop over them per flake is skipped.
                double area = 0.0;
                for (int b = 0; b < n_box; ++b) area += box[b][2] * box[b][2];
                const bool tiled = area == (x1 - x0) * (y1 - y0);
                const auto in_boxes = [&](double x, double y) {
                    if (tiled) return true;
                    bool in = false;
                    for (int b = 0; b < n_box; ++b)
                        in = in || (x >= box[b][0] && x < box[b][0] + box[b][2] && y >= box[b][1] &&
                                    y < box[b][1] + box[b][2]);
                    return in;
                };
                const auto emit = [&](Flake& f, uint64_t) {
                    f.u += static_cast<double>(tx);
                    f.v += static_cast<double>(ty);
                    exact(static_cast<const Flake&>(f));
                    return true;
                };
                bool trunc = false;
                class_flakes_in(fp, cl, local, tk, x0, y0, x1, y1, in_boxes, 1u << 30, trunc, emit);
            }
        }
}

}  // namespace spangle::flake
