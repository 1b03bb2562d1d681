#pragma once
// The flake field: which flakes exist, where, and which way they face. Every flake is a pure
// function of (material seed, uv tile, quad-tree node, index in the leaf) or (material seed, uv
// tile, class, block, index), so the same flakes are seen from every view, in every frame, on
// every thread count. Both evaluation algorithms (the enumerating reflection cache and the
// counting tree) read this one field.
//
// A tile (integer uv square) holds N flakes: floor(N / 2) on average in ranked classes (below,
// at ClassLayout) and the rest in its quad-tree. The quad-tree splits a node's count among the four
// children with an exact multinomial of p = 1/4 (two random bits per flake, counted with
// popcounts) below `exact_below` flakes and a normal approximation above. A node with at most
// `leaf_size` flakes, or at `max_depth`, is a leaf: its flakes get positions uniform in the cell
// and normals from the GGX distribution of flake normals (D(m) (m.n)), through the map of the unit
// square onto GGX normals in flake_normal().

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

#include "../common/microfacet.h"
#include "facet.h"

namespace spangle::flake {

using mf::V3;

/** Counter-based hash of two words (a 64-bit finaliser with full avalanche). The engine has its
 *  own (core/hash.h), but a plugin includes nothing of the engine except plugin.h, and calling the
 *  host's hash through a function pointer per flake would cost more than the hash. */
inline uint64_t mix(uint64_t a, uint64_t b) {
    uint64_t x = (a + 0x9e3779b97f4a7c15ull) * 0xbf58476d1ce4e5b9ull ^ (b + 0x632be59bd9b4e019ull);
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    x ^= x >> 31;
    return x;
}

/** 2^-d exactly, for 0 <= d <= 1022 (the cell size at depth d), without a libm call. */
inline double pow2_neg(int d) {
    return std::bit_cast<double>(static_cast<uint64_t>(1023 - d) << 52);
}

/** Uniform double in [0, 1) from the top 53 bits. */
inline double unit(uint64_t h) {
    return static_cast<double>(h >> 11) * 0x1p-53;
}

/** Two uniform floats in [0, 1) from one hash (24 bits each). */
inline void unit2(uint64_t h, float& a, float& b) {
    a = static_cast<float>(h >> 40) * 0x1p-24f;
    b = static_cast<float>((h >> 16) & 0xffffffu) * 0x1p-24f;
}

/** The footprint parallelogram P = c + s a + t b, s, t in [-1/2, 1/2], in uv. */
struct Footprint {
    double cu = 0, cv = 0;  ///< centre
    double ax = 0, ay = 0;  ///< axis a = (du/dx, dv/dx) x footprint_scale
    double bx = 0, by = 0;  ///< axis b = (du/dy, dv/dy) x footprint_scale
    double i00 = 0, i01 = 0, i10 = 0,
           i11 = 0;  ///< inverse of [a b]: uv offset -> (s, t); all 0 when singular
    /** Flakes whose centre lies within this uv distance of P may reach into it (the facets'
     *  circumradius with flake_size; 0 for point flakes). Cells and tiles are searched that far
     *  around P. */
    double reach = 0;
    double area() const { return std::fabs(ax * by - ay * bx); }
    /** Half extents of P's bounding box, widened by `reach`. */
    double half_width() const { return 0.5 * (std::fabs(ax) + std::fabs(bx)) + reach; }
    double half_height() const { return 0.5 * (std::fabs(ay) + std::fabs(by)) + reach; }
};

/** The largest ratio of a footprint's principal axes: a receding surface's footprints keep their
 *  true shape down to cos 1/32 (clamped to 4, a footprint at grazing views was widened over 4 to
 *  6 of its neighbours, and each flake lit a horizontal dash of pixels). */
constexpr double kMaxFootprintRatio = 32.0;

/** Footprint from uv derivatives, scaled, with the ratio of its principal axes clamped to
 *  max_ratio (the minor axis widened, the centre kept): this bounds skew and needles alike. */
Footprint make_footprint(double u, double v, double dudx, double dvdx, double dudy, double dvdy,
                         double scale, double max_ratio = kMaxFootprintRatio);

/** Whether P has no area (its inverse is all 0): it holds no point flake. */
inline bool singular(const Footprint& p) {
    return p.i00 == 0.0 && p.i01 == 0.0 && p.i10 == 0.0 && p.i11 == 0.0;
}

/** inside() for a P that is not singular, without branches: loops over many candidate flakes
 *  test them with it (whether one lies inside is a coin toss along P's edges, and a branch on
 *  it was mispredicted often enough to be most of such a loop's time). */
inline bool inside_nonsingular(const Footprint& p, double u, double v) {
    // (s, t) = [a b]^-1 ((u, v) - c).
    const double du = u - p.cu, dv = v - p.cv;
    const double s = p.i00 * du + p.i01 * dv;
    const double t = p.i10 * du + p.i11 * dv;
    // |s| <= 1/2 is -1/2 <= s <= 1/2 (false for NaN alike), in fewer instructions.
    return (std::fabs(s) <= 0.5) & (std::fabs(t) <= 0.5);
}

/** Whether (u, v) lies inside P (in P's own coordinates, in double). */
inline bool inside(const Footprint& p, double u, double v) {
    return !singular(p) && inside_nonsingular(p, u, v);
}

/** Whether the cell [x0, x1] x [y0, y1] may intersect P widened by its reach (separating axes;
 *  exact for a parallelogram and a box when the reach is 0, conservative otherwise). */
bool overlaps(const Footprint& p, double x0, double y0, double x1, double y1);

/** The block of width 1 / blocks (a power of two, blocks across the tile) holding x, clamped
 *  to the tile's; 0 for x below 0 or not a number. (x / block is x * blocks exactly, and the
 *  floor of a number from 0 up is its truncation: floor was a libm call.) */
inline int64_t block_index(double x, double blocks) {
    const double f = x * blocks;
    return f >= 0.0 ? static_cast<int64_t>(std::min(f, blocks - 1.0)) : int64_t{0};
}

/** The x-range of P's points in a row of y: P is the intersection of two slabs (|s| <= 1/2 and
 *  |t| <= 1/2), and the row's range is taken as the intersection of theirs and of P's bounding
 *  box: a range holding all of P's points in the row (P's reach left out), widened by a
 *  millionth of P's width, and each slab by far more than its rounding and the inside test's,
 *  so that no point inside_nonsingular() accepts falls outside it. Cheap per row: loops over rows
 * of blocks skip those beyond it. */
struct StripSpan {
    explicit StripSpan(const Footprint& p);
    /** The range [x0, x1] for the rows y in [y0, y1]; false where P has no point there. */
    bool at(double y0, double y1, double& x0, double& x1) const;
    /** Narrows the blocks [bx0, bx1] of row `by` (blocks of width `block`, 1 / block of them
     *  across the tile) to those under the range of that row; false where P has none there. */
    bool row_blocks(int64_t by, double block, int64_t& bx0, int64_t& bx1) const;

private:
    struct Slab {
        bool bounds_x = true;
        double slope = 0;  ///< its centre's x moves by this per unit of y (from (cu, cv))
        double half = 0;   ///< its half width in x (in y, where it does not bound x)
    };
    Slab slab[2];
    double cu = 0, cv = 0, half_width = 0, margin = 0;
};

inline bool StripSpan::at(double y0, double y1, double& x0, double& x1) const {
    // (Within P's bounding box: the slabs' ranges over a tall row can reach beyond it.)
    double lo = cu - half_width, hi = cu + half_width;
    for (const Slab& s : slab) {
        if (s.bounds_x) {
            const double d0 = y0 - cv, d1 = y1 - cv;
            const double c0 = cu + s.slope * d0, c1 = cu + s.slope * d1;
            // Against the rounding of these sums and of the inside test's own (which adds
            // i01 dv to i00 du): far more than either's error, far less than a block.
            const double err =
                1e-12 *
                (std::fabs(cu) + std::fabs(s.slope) * (std::fabs(d0) + std::fabs(d1)) + s.half);
            lo = std::max(lo, std::min(c0, c1) - s.half - err);
            hi = std::min(hi, std::max(c0, c1) + s.half + err);
        } else {
            // A slab that bounds y alone, widened alike (t = i11 dv rounds too).
            const double err = 1e-6 * s.half + 1e-12 * std::fabs(cv);
            if (y1 < cv - s.half - err || y0 > cv + s.half + err) return false;
        }
    }
    // (Not a number anywhere: no point of P.)
    if (!(lo - margin <= hi + margin)) return false;
    x0 = lo - margin;
    x1 = hi + margin;
    return true;
}

inline bool StripSpan::row_blocks(int64_t by, double block, int64_t& bx0, int64_t& bx1) const {
    double x0 = 0.0, x1 = 0.0;
    if (!at(static_cast<double>(by) * block, static_cast<double>(by + 1) * block, x0, x1))
        return false;
    const double blocks = 1.0 / block;
    bx0 = std::max(bx0, block_index(x0, blocks));
    bx1 = std::min(bx1, block_index(x1, blocks));
    return true;
}

/** Whether the cell lies entirely inside P. */
bool contains(const Footprint& p, double x0, double y0, double x1, double y1);

/** The most vertices of a polygon clipped_area() takes. */
constexpr int kMaxClipVertices = 32;

/** Area of the convex polygon (xs, ys) of n vertices (at most kMaxClipVertices) intersected with
 *  the box [x0, x1] x [y0, y1] (Sutherland-Hodgman clipping, in double). */
double clipped_area(const double* xs, const double* ys, int n, double x0, double y0, double x1,
                    double y1);

/** Area of P intersected with the cell [x0, x1] x [y0, y1] (polygon clipping, in double). */
double overlap_area(const Footprint& p, double x0, double y0, double x1, double y1);

/** Settings of the flake field (everything that decides which flakes exist). */
struct FieldParams {
    uint64_t seed = 0;           ///< material seed
    double flakes_per_tile = 0;  ///< N: count in one tile (footprint units), at most 2^31 - 1
    float alpha = 0.1f;          ///< GGX roughness of the flake normal distribution
    int leaf_size = 16;          ///< nodes with at most this many flakes are leaves
    int max_depth = 12;          ///< deepest level of the quad-tree
    int exact_below = 128;       ///< splits of fewer flakes than this are exact multinomials
    /** Facets (flake_size): each flake is this outline, `facet_size` wide in uv and turned by an
     *  angle from its own hash, and counts by the share of it inside P. Null: point flakes. */
    const FacetShape* facet = nullptr;
    double facet_size = 0;  ///< width of a facet in the footprint's plane (uv units)
    /** Leave Flake::m unset (its caller computes the normals of many flakes at once from
     *  Flake::s, t). */
    bool lazy_normals = false;
    /** Set Flake::id and color_u of the class flakes (a hash more each): false where neither
     *  is read (one colour and no film). */
    bool flake_ids = true;
};

/** Deterministic binomial B(n, p) from a uniform u: exact inversion of the CDF when n is below
 *  exact_below (at most 1000), otherwise the normal approximation rounded and clamped to [0, n].
 *  For a fixed u the result never decreases when n or p grows (inversion is monotone). */
uint32_t binomial(uint32_t n, double p, double u, int exact_below);

/** Splits n flakes among a node's four children, a multinomial with p = 1/4: exactly, from two
 *  hashed bits per flake, when n < exact_below; by three sequential normal-approximated
 *  binomials otherwise. Random numbers come from `key`. Adding one flake to n (below
 *  exact_below) adds it to exactly one child, which keeps nested counts coherent. */
void split_counts(uint64_t key, uint32_t n, int exact_below, uint32_t out[4]);

/** split_counts memoised per thread (same results): nodes near the root are split once. */
void split_counts_cached(uint64_t key, uint32_t n, int exact_below, uint32_t out[4]);

/** Key of a uv tile. */
uint64_t tile_key(uint64_t seed, int64_t tx, int64_t ty);

/** Key of a quad-tree node: a pure function of the tile key, depth and cell. */
uint64_t node_key(uint64_t tile_key, int depth, uint32_t ix, uint32_t iy);

/** Flake normal (local frame, n = z) of the unit-square point (s, t): a uniform point of the disk
 *  (Shirley and Chiu's concentric map, area preserving) lifted to the hemisphere and stretched by
 *  (alpha, alpha, 1). Uniform (s, t) gives normals with density D(m) (m.n) for GGX (Heitz 2018:
 *  GGX is the distribution of normals of a stretched hemisphere). Neighbouring squares map to
 *  neighbouring normals. */
V3 flake_normal(float alpha, float s, float t);

/** flake_normal() itself, inline and without branches (the concentric map's two sectors are
 *  chosen by selects), so that a loop over many flakes compiles to vector code; the same
 *  arithmetic in the same order, so the same bits. (A branch on the sector was mispredicted for
 *  half the flakes: flake_normal was a fifth of a counted footprint's time.) */
inline void flake_normal_of(float alpha, float s, float t, float& mx, float& my, float& mz) {
    const float a = 2.0f * s - 1.0f, b = 2.0f * t - 1.0f;
    // Within each of the four sectors the angle is pi/4 times a ratio in [-1, 1] around the
    // sector's axis: b / a around +-x where |a| > |b|, else a / b around +-y (phi = pi/2 - delta:
    // cos(phi) = sin(delta), sin(phi) = cos(delta)). At the centre (a = b = 0) the ratio is 0 and
    // the point (0, 0).
    const bool around_x = std::fabs(a) > std::fabs(b);
    const float num = around_x ? b : a, den = around_x ? a : b;
    const float ratio = num / (den != 0.0f ? den : 1.0f);
    // sin and cos of x in [-pi/4, pi/4]: Taylor to x^9 and x^8 (error below 4e-8) in Horner
    // form with constant coefficients.
    const float q = 0.25f * mf::kPi * ratio, q2 = q * q;
    const float sn =
        q * (1.0f + q2 * (-1.0f / 6.0f +
                          q2 * (1.0f / 120.0f + q2 * (-1.0f / 5040.0f + q2 * (1.0f / 362880.0f)))));
    const float cs =
        1.0f + q2 * (-0.5f + q2 * (1.0f / 24.0f + q2 * (-1.0f / 720.0f + q2 * (1.0f / 40320.0f))));
    const float x = around_x ? a * cs : b * sn;
    const float y = around_x ? a * sn : b * cs;
    // Lift to the hemisphere (x, y, sqrt(1 - x^2 - y^2)) and stretch; the length of the
    // stretched vector from z^2 itself, so that its square root does not wait for z's.
    const float r2 = x * x + y * y, z2 = std::max(1e-12f, 1.0f - r2);
    const float z = std::sqrt(z2);
    const float inv = 1.0f / std::sqrt(alpha * alpha * r2 + z2);
    mx = alpha * x * inv;
    my = alpha * y * inv;
    mz = z * inv;
}

/** Inverse of flake_normal for m.z > 0: the (s, t) whose normal is m. */
void flake_square(float alpha, V3 m, float& s, float& t);

/** One flake: where it is and which way it faces. */
struct Flake {
    double u = 0, v = 0;  ///< position in uv (absolute, tile included)
    V3 m;                 ///< normal, local shading frame (unset with lazy_normals)
    float s = 0, t = 0;   ///< the normal's point of the unit square: m = flake_normal(alpha, s, t)
    float color_u = 0;    ///< uniform number that picks its colour-table entry
    uint64_t id = 0;      ///< the flake's own hash: its colour variation and film draw from it
    float cover = 1;      ///< share of the flake inside P (1 for a point flake inside it)
};

/** The position of flake i of the leaf with key `key` whose cell is [x0, x0 + size]^2
 *  (tile-relative): one hash, its two halves the position's fractions of the cell (32 bits each:
 *  2^-32 of a cell, far below any footprint). Returns the hash for leaf_flake_finish(). */
inline uint64_t leaf_flake_position(uint64_t key, uint32_t i, double x0, double y0, double size,
                                    Flake& f) {
    const uint64_t h = mix(key, i);
    f.u = x0 + size * (static_cast<double>(h >> 32) * 0x1p-32);
    f.v = y0 + size * (static_cast<double>(h & 0xffffffffu) * 0x1p-32);
    f.id = h;
    return h;
}

/** The rest of a flake from its hash, by one more hash: its normal (24 bits per coordinate of the
 *  square of normals) and its colour number (16 bits: the colour table has at most 360 entries).
 */
inline void leaf_flake_finish(const FieldParams& fp, uint64_t h, Flake& f) {
    const uint64_t g = mix(h, 3);
    unit2(g, f.s, f.t);
    if (!fp.lazy_normals) f.m = flake_normal(fp.alpha, f.s, f.t);
    f.color_u = static_cast<float>(g & 0xffffu) * 0x1p-16f;
}

/** Whether the flake at (u, v) survives a view's thinning to the share `keep` (a hash of its
 *  place: a pure function of the flake, so the same flakes survive from every view, and the
 *  counting algorithm's stand-ins as the enumeration's flakes). */
inline bool kept(double u, double v, float keep) {
    if (keep >= 1.0f) return true;
    const uint64_t bu = std::bit_cast<uint64_t>(u), bv = std::bit_cast<uint64_t>(v);
    return unit(mix(mix(bu, bv), 0x7417)) < static_cast<double>(keep);
}

/** The flake count of one tile (its expectation: the ranked classes below are a Poisson count). */
inline uint32_t root_count(const FieldParams& fp) {
    return static_cast<uint32_t>(std::min(fp.flakes_per_tile + 0.5, 2147483647.0));
}

// Ranked classes. Half of a tile's flakes (on average) are laid out in classes c = 0, 1, ...:
// class c cuts the tile into blocks 2^-(c + 3) wide and puts a Poisson count of mean 3 flakes in
// each (192 x 4^c per tile), at places, normals and colours that are hashes of (tile, class,
// block, index); the last class present may be partial (a smaller mean per block). The other
// half are the quad-tree's (a fixed count spread uniformly: binomial in any region). Both place
// each flake uniformly and independently of the others, so their union is one flake field with
// the tree's old statistics (mean N per tile, counts in a region binomial-like, variance about
// the mean), and the enumeration visits both. The classes are what the counting algorithm's
// stand-ins are: a footprint that the tree counts takes the flakes of the classes up to a density
// of its own (counted_lobe.h), real flakes the enumeration also finds, so that a cell switching
// from counted to enumerated as a camera dollies in keeps the glints it had.

/** Mean flakes per block of a whole class. */
constexpr double kClassMean = 3.0;
/** The most flakes one block holds (the Poisson count stops there: the chance of more is below
 *  1e-11 at mean 3). */
constexpr uint32_t kClassMaxPerBlock = 24;

/** The Poisson law of one mean, tabulated for drawing counts by inversion: cdf[j] = P(X <= j). */
struct PoissonCdf {
    double cdf[kClassMaxPerBlock] = {};
    PoissonCdf() = default;
    explicit PoissonCdf(double mean);
    /** The count whose cdf first exceeds the block's own uniform (at most kClassMaxPerBlock):
     *  for a block, it never decreases as the mean grows (a footprint's share of a class nests in
     *  the class, and a smaller share in a larger one). Without branches: a count drawn per
     *  block was mispredicted as often as not. */
    uint32_t count(uint64_t bkey) const {
        const double u = unit(bkey);
        // How many of cdf[0 .. 6] are at most u (the cdf rises: the count is the search's
        // answer), as seven independent comparisons added up; seven and more (3.4% at mean 3)
        // counted on. (A search of three dependent steps compiled to branches on each.)
        uint32_t k = 0;
        for (uint32_t j = 0; j < 7; ++j) k += u >= cdf[j] ? 1u : 0u;
        if (k == 7)
            for (uint32_t j = 7; j < kClassMaxPerBlock; ++j) k += u >= cdf[j] ? 1u : 0u;
        return k;
    }
};

/** The law of a whole class's blocks (mean kClassMean). */
extern const PoissonCdf kWholeClass;

/** PoissonCdf(mean), kept per thread for the last mean asked: a layout's last, partial class has
 *  the same mean at every footprint of a material, and its table (24 divisions and an exp) was
 *  made again for each. */
PoissonCdf poisson_law(double mean);

/** How a tile's flakes are shared between the classes and the quad-tree. */
struct ClassLayout {
    int last = -1;            ///< classes 0 .. last exist (none when -1)
    double last_share = 0.0;  ///< class `last` has the mean kClassMean x last_share per block
    uint32_t residual = 0;    ///< flakes of the tile's quad-tree
    double per_tile = 0.0;    ///< class flakes per tile, on average (all classes)
    /** The mean per block of class c (0 beyond `last`). */
    double mean(int c) const {
        return c < last ? kClassMean : c == last ? kClassMean * last_share : 0.0;
    }
};

/** The layout of fp's tiles: floor(N / 2) flakes per tile in classes, the rest in the tree. */
ClassLayout class_layout(const FieldParams& fp);

/** Key of class c of a tile. */
inline uint64_t class_key(uint64_t tile_key, int c) {
    return mix(tile_key, 0x57a2d000u + static_cast<uint64_t>(c));
}

/** Key of block (bx, by) of a class. */
inline uint64_t block_key(uint64_t class_key, int64_t bx, int64_t by) {
    return mix(class_key, static_cast<uint64_t>(by) << 32 | static_cast<uint64_t>(bx));
}

/** Flake i of a block of width `block`: its hash, and its place (24 bits each way:
 *  (block index x 2^24 + bits) x 2^-24 block, exact in double). */
inline uint64_t class_flake_position(uint64_t bkey, uint32_t i, int64_t bx, int64_t by,
                                     double block, double& x, double& y) {
    const uint64_t h = mix(bkey, i);
    const double step = 0x1p-24 * block;
    x = static_cast<double>((bx << 24) + static_cast<int64_t>(h >> 40)) * step;
    y = static_cast<double>((by << 24) + static_cast<int64_t>((h >> 16) & 0xffffffu)) * step;
    return h;
}

/** A class flake's normal, colour number and id from its hash h (the counting algorithm's
 *  stand-ins read the same: counted_lobe.cpp). */
inline void class_flake_finish(const FieldParams& fp, uint64_t h, Flake& f) {
    const uint64_t g = mix(h, 0x5eed);
    unit2(g, f.s, f.t);
    if (!fp.lazy_normals) f.m = flake_normal(fp.alpha, f.s, f.t);
    if (!fp.flake_ids) return;
    f.id = mix(g, 0xc0);
    f.color_u = static_cast<float>(f.id >> 40) * 0x1p-24f;
}

/** Means from which poisson() takes the normal approximation. */
constexpr double kPoissonNormalFrom = 64.0;

/** Deterministic Poisson count of mean `mean` from a uniform u: exact inversion below a mean of
 *  kPoissonNormalFrom, the normal approximation (rounded, at least 0) from there. */
uint32_t poisson(double mean, double u);

/** The class flakes of a cell (of `size` tile units, node key `key`), as the counting algorithm
 *  counts them: a Poisson draw of their expectation, fixed per cell (counting them would visit
 *  up to all of the classes' blocks in it; they are a Poisson process, so the draw has their
 *  count's law, though not the enumeration's very count). */
inline uint32_t class_count_in_cell(const ClassLayout& cl, uint64_t key, double size) {
    return poisson(cl.per_tile * size * size, unit(mix(key, 0xc1a55)));
}

/** Visits the class flakes whose centres lie in the box [x0, x1) x [y0, y1) of tile (tx, ty),
 *  in `region` (region(x, y): a part of the box) and inside P (`local`: P relative to the tile),
 *  or whose facets reach into it: emit(Flake&, hash) returns false to stop. Sets `truncated`
 *  (and stops) where the blocks under P would hold far more than `budget` flakes. */
template <class Region, class Emit>
void class_flakes_in(const FieldParams& fp, const ClassLayout& cl, const Footprint& local,
                     uint64_t tile, double x0, double y0, double x1, double y1, Region&& region,
                     uint32_t budget, bool& truncated, Emit&& emit);

/** The flakes of the tile's quad-tree (the root's count). */
inline uint32_t residual_count(const FieldParams& fp) {
    return class_layout(fp).residual;
}

/** Tiles a footprint spans: [tx0, tx1] x [ty0, ty1]. */
struct TileRange {
    int64_t tx0 = 0, tx1 = -1, ty0 = 0, ty1 = -1;
    /** Tiles in the range, saturating (a range over far-away uv must not overflow). */
    uint64_t count() const {
        if (tx1 < tx0 || ty1 < ty0) return 0;
        const uint64_t w = static_cast<uint64_t>(tx1 - tx0) + 1,
                       h = static_cast<uint64_t>(ty1 - ty0) + 1;
        return w > UINT64_MAX / h ? UINT64_MAX : w * h;
    }
};
TileRange tiles_of(const Footprint& p);

/** Enumerates the flakes of node (depth, ix, iy) of tile (tx, ty) that lie inside P: the class
 *  flakes (layout *cl = class_layout(fp); none when cl is null) whose centres lie in its cell,
 *  then the n of its quad-tree. Calls visit(const Flake&) for each, stopping after `budget` of
 * them. Returns the number visited and sets `truncated` when more existed. */
template <class Visit>
uint32_t flakes_in_node(const FieldParams& fp, const ClassLayout* cl, const Footprint& p,
                        int64_t tx, int64_t ty, int depth, uint32_t ix, uint32_t iy, uint32_t n,
                        uint32_t budget, bool& truncated, Visit&& visit);

/** Enumerates every flake inside P (all tiles it touches, at most 64), as flakes_in_node. */
template <class Visit>
uint32_t for_each_flake(const FieldParams& fp, const Footprint& p, uint32_t max_flakes,
                        bool& truncated, Visit&& visit);

// ------------------------------------------------------------------------------------ templates

/** Candidate flakes gathered over many blocks (of any class and row) or leaves, then placed
 *  and tested without branches (whether one lies inside is a coin toss along P's edges), and
 *  those inside emitted in the order gathered. A block or a leaf writes a fixed number of slots
 *  whatever its count and moves the cursor by its count: a loop of each one's own count, and
 *  one over the few it found, were a mispredicted exit per block or leaf. */
struct CandidateRun {
    static constexpr uint32_t kRunSlots = 256;          ///< slots tested at once (about)
    static constexpr uint32_t kSlots = kRunSlots + 64;  ///< room for a block or a leaf chunk more
    static constexpr uint32_t kSources = 256;           ///< blocks or leaf chunks of a run, at most
    static constexpr uint32_t kBlockSlots = 8;          ///< slots a block writes whatever its count
    static constexpr uint32_t kLeafSlots = 16;          ///< slots a leaf chunk writes, at least
    static constexpr uint32_t kLeafChunk = 64;          ///< flakes of a leaf per chunk, at most
    // A block or a leaf chunk is added while fewer than kRunSlots slots are taken, and writes at
    // most this many; a source's index is 16 bits.
    static_assert(kSlots >= kRunSlots - 1 +
                                std::max({kLeafChunk, kLeafSlots, kBlockSlots, kClassMaxPerBlock}));
    static_assert(kSources <= 65536);
    // Per source (a block or a chunk of a leaf): its key and place. Class blocks: column, row
    // (exact in double) and width; leaves: the cell's corner and size.
    uint64_t key[kSources];
    double ox[kSources], oy[kSources], size[kSources];
    // Per slot: its source and the flake's index there.
    uint16_t owner[kSlots];
    uint32_t index[kSlots];
    // The flakes found inside: hash and place.
    uint64_t hs[kSlots];
    double xs[kSlots], ys[kSlots];
    uint32_t n = 0, sources = 0;

    /** Whether the run is full: flush it before adding more. */
    bool full() const { return n >= kRunSlots || sources == kSources; }

    /** Block (bx, by) of width `block` and key bk, holding `count` flakes (at most
     *  kClassMaxPerBlock). */
    void add_block(uint64_t bk, int64_t bx, int64_t by, double block, uint32_t count) {
        const uint32_t src =
            add_source(bk, static_cast<double>(bx), static_cast<double>(by), block);
        for (uint32_t k = 0; k < kBlockSlots; ++k) set(n + k, src, k);
        if (count > kBlockSlots) [[unlikely]]
            for (uint32_t k = kBlockSlots; k < count; ++k) set(n + k, src, k);
        n += count;
    }
    /** The class flakes gathered: placed, tested with in(x, y), those inside finished and
     *  emitted (emit(Flake&, hash)). False when emit stopped. */
    template <class In, class E>
    bool flush_class(In&& in, const FieldParams& fp, const Footprint& local, E&& emit) {
        uint32_t found = 0;
        for (uint32_t j = 0; j < n; ++j) {
            const uint32_t s = owner[j];
            double x, y;
            hs[found] = class_flake_position(key[s], index[j], static_cast<int64_t>(ox[s]),
                                             static_cast<int64_t>(oy[s]), size[s], x, y);
            xs[found] = x;
            ys[found] = y;
            found += in(x, y) ? 1u : 0u;
        }
        n = sources = 0;
        for (uint32_t j = 0; j < found; ++j) {
            Flake f;
            f.u = xs[j];
            f.v = ys[j];
            if (fp.facet) {
                f.cover = facet_coverage(local, *fp.facet, fp.facet_size, f.u, f.v, hs[j]);
                if (!(f.cover > 0.0f)) continue;
            }
            class_flake_finish(fp, hs[j], f);
            if (!emit(f, hs[j])) return false;
        }
        return true;
    }

    /** The `count` flakes of the leaf with key `leaf_key` and cell [x0, x0 + cell] x [y0, y0 +
     *  cell]; calls flush() (false: stop) whenever the run is full. False when flush stopped. */
    template <class F>
    bool add_leaf(uint64_t leaf_key, double x0, double y0, double cell, uint32_t count, F&& flush) {
        for (uint32_t first = 0; first < count;) {
            if (full() && !flush()) return false;
            const uint32_t take = std::min(count - first, kLeafChunk);
            const uint32_t src = add_source(leaf_key, x0, y0, cell);
            for (uint32_t k = 0; k < kLeafSlots; ++k) set(n + k, src, first + k);
            if (take > kLeafSlots) [[unlikely]]
                for (uint32_t k = kLeafSlots; k < take; ++k) set(n + k, src, first + k);
            n += take;
            first += take;
        }
        return true;
    }
    /** The leaf flakes gathered: placed, tested against P (`local`, not singular), those inside
     *  emitted (emit(Flake&, hash), the flake placed, its id set). False when emit stopped. */
    template <class E>
    bool flush_leaves(const Footprint& local, E&& emit) {
        uint32_t found = 0;
        for (uint32_t j = 0; j < n; ++j) {
            const uint32_t s = owner[j];
            Flake f;
            hs[found] = leaf_flake_position(key[s], index[j], ox[s], oy[s], size[s], f);
            xs[found] = f.u;
            ys[found] = f.v;
            found += inside_nonsingular(local, f.u, f.v) ? 1u : 0u;
        }
        n = sources = 0;
        for (uint32_t j = 0; j < found; ++j) {
            Flake f;
            f.u = xs[j];
            f.v = ys[j];
            f.id = hs[j];
            if (!emit(f, hs[j])) return false;
        }
        return true;
    }

private:
    uint32_t add_source(uint64_t k, double x, double y, double sz) {
        key[sources] = k;
        ox[sources] = x;
        oy[sources] = y;
        size[sources] = sz;
        return sources++;
    }
    void set(uint32_t slot, uint32_t src, uint32_t idx) {
        owner[slot] = static_cast<uint16_t>(src);
        index[slot] = idx;
    }
};

template <class Region, class Emit>
void class_flakes_in(const FieldParams& fp, const ClassLayout& cl, const Footprint& local,
                     uint64_t tile, double x0, double y0, double x1, double y1, Region&& region,
                     uint32_t budget, bool& truncated, Emit&& emit) {
    if (cl.last < 0 || (singular(local) && !fp.facet)) return;
    // The part of P's bounding box (widened by the facets' reach) inside the box. (A centre that
    // is not a number does not come here: tiles_of() gives it every tile, too many.)
    const double hx = local.half_width(), hy = local.half_height();
    const double lx = std::max(x0, local.cu - hx), ux = std::min(x1, local.cu + hx);
    const double ly = std::max(y0, local.cv - hy), uy = std::min(y1, local.cv + hy);
    if (!(lx <= ux && ly <= uy)) return;
    // The flakes P holds in the box on average, and the candidates under its bounding box: far
    // more of the one than the budget, or of the other than the budget allows work for, and the
    // footprint is truncated before any is hashed. (The candidates alone misjudged a sliver of
    // P over a tile: few flakes inside, many under the box.)
    const double inside = cl.per_tile * overlap_area(local, x0, y0, x1, y1);
    if (!fp.facet && inside > 4.0 * static_cast<double>(budget) + 64.0) {
        truncated = true;
        return;
    }
    double candidates = 0.0;
    const StripSpan span(local);
    const auto in = [&](double x, double y) {
        return (x >= x0) & (x < x1) & (y >= y0) & (y < y1) & region(x, y) &
               (fp.facet != nullptr || inside_nonsingular(local, x, y));
    };
    CandidateRun run;  // (about 17 KB of stack, unset: every slot is written before it is read)
    for (int c = 0; c <= cl.last; ++c) {
        const double block = pow2_neg(c + 3);
        const double blocks = 1.0 / block;
        const int64_t bx0 = block_index(lx, blocks), bx1 = block_index(ux, blocks),
                      by0 = block_index(ly, blocks), by1 = block_index(uy, blocks);
        const double mean = cl.mean(c);
        // (The last class's law fetched here, not in the layout: a layout is made per
        // footprint, and most footprints the counting algorithm does not enumerate.)
        PoissonCdf last_law;
        if (c == cl.last) last_law = poisson_law(mean);
        const PoissonCdf& law = c < cl.last ? kWholeClass : last_law;
        // (Too many candidates: a needle's bounding box.) The flakes of the classes before
        // this one are emitted first, as they were found.
        candidates +=
            mean * static_cast<double>(bx1 - bx0 + 1) * static_cast<double>(by1 - by0 + 1);
        if (candidates > 64.0 * static_cast<double>(budget) + 65536.0) {
            if (run.flush_class(in, fp, local, emit)) truncated = true;
            return;
        }
        const uint64_t ck = class_key(tile, c);
        for (int64_t by = by0; by <= by1; ++by) {
            // Point flakes: only the blocks of the row under P's span in it (a turned or
            // needle-shaped P's bounding box holds several times the blocks that meet it).
            int64_t rx0 = bx0, rx1 = bx1;
            if (!fp.facet && !span.row_blocks(by, block, rx0, rx1)) continue;
            for (int64_t bx = rx0; bx <= rx1; ++bx) {
                const uint64_t bk = block_key(ck, bx, by);
                if (run.full() && !run.flush_class(in, fp, local, emit)) return;
                run.add_block(bk, bx, by, block, law.count(bk));
            }
        }
    }
    run.flush_class(in, fp, local, emit);
}

template <class Visit>
uint32_t flakes_in_node(const FieldParams& fp, const ClassLayout* cl, const Footprint& p,
                        int64_t tx, int64_t ty, int depth, uint32_t ix, uint32_t iy, uint32_t n,
                        uint32_t budget, bool& truncated, Visit&& visit) {
    const uint64_t tk = tile_key(fp.seed, tx, ty);
    // The footprint relative to this tile's origin.
    Footprint local = p;
    local.cu -= static_cast<double>(tx);
    local.cv -= static_cast<double>(ty);
    struct Node {
        int depth;
        uint32_t ix, iy, n;
    };
    Node stack[4 * 26];
    // A footprint of zero area holds no point flake (inside() is false everywhere).
    const bool no_area = singular(local);
    int top = 0;
    stack[top++] = {depth, ix, iy, n};
    uint32_t visited = 0;
    // The class flakes of the node's cell first (finished already: placed and visited).
    if (cl) {
        const double size = pow2_neg(depth);
        const auto emit_class = [&](Flake& f, uint64_t) {
            if (visited >= budget) {
                truncated = true;
                return false;
            }
            f.u += static_cast<double>(tx);
            f.v += static_cast<double>(ty);
            visit(static_cast<const Flake&>(f));
            ++visited;
            return true;
        };
        class_flakes_in(
            fp, *cl, local, tk, ix * size, iy * size, (ix + 1) * size, (iy + 1) * size,
            [](double, double) { return true; }, budget, truncated, emit_class);
        if (truncated) return visited;
    }
    // A flake inside P, positioned by hash h: finished, placed in its tile and visited; false
    // (truncated) when the budget is spent.
    const auto emit = [&](Flake& f, uint64_t h) {
        if (visited >= budget) {
            truncated = true;
            return false;
        }
        leaf_flake_finish(fp, h, f);
        f.u += static_cast<double>(tx);
        f.v += static_cast<double>(ty);
        visit(static_cast<const Flake&>(f));
        ++visited;
        return true;
    };
    // Leaves' flakes gathered over several leaves (CandidateRun), then placed, tested against
    // P and visited in order (their hashes and places kept from the test).
    CandidateRun run;  // (about 17 KB of stack, unset: every slot is written before it is read)
    const auto flush_leaves = [&] {
        return run.flush_leaves(local, [&](Flake& f, uint64_t h) { return emit(f, h); });
    };
    while (top > 0) {
        const Node node = stack[--top];
        if (node.n == 0) continue;
        const double size = pow2_neg(node.depth);
        const double x0 = node.ix * size, y0 = node.iy * size;
        if (!overlaps(local, x0, y0, x0 + size, y0 + size)) continue;
        const uint64_t key = node_key(tk, node.depth, node.ix, node.iy);
        if (static_cast<int>(node.n) <= fp.leaf_size || node.depth >= fp.max_depth) {
            if (!fp.facet) {
                // Point flakes: the leaf's flakes join the run, tested and visited in order
                // when it is full and once the walk ends.
                if (no_area) continue;
                if (!run.add_leaf(key, x0, y0, size, node.n, flush_leaves)) return visited;
                continue;
            }
            for (uint32_t i = 0; i < node.n; ++i) {
                Flake f;
                const uint64_t h = leaf_flake_position(key, i, x0, y0, size, f);
                f.cover = facet_coverage(local, *fp.facet, fp.facet_size, f.u, f.v, h);
                if (!(f.cover > 0.0f)) continue;
                if (!emit(f, h)) return visited;
            }
            continue;
        }
        uint32_t child[4];
        split_counts_cached(key, node.n, fp.exact_below, child);
        for (uint32_t c = 0; c < 4; ++c)
            stack[top++] = {node.depth + 1, 2 * node.ix + (c & 1u), 2 * node.iy + (c >> 1),
                            child[c]};
    }
    flush_leaves();
    return visited;
}

template <class Visit>
uint32_t for_each_flake(const FieldParams& fp, const Footprint& p, uint32_t max_flakes,
                        bool& truncated, Visit&& visit) {
    truncated = false;
    const TileRange tr = tiles_of(p);
    if (tr.count() > 64) {
        truncated = true;
        return 0;
    }
    uint32_t visited = 0;
    const ClassLayout cl = class_layout(fp);
    for (int64_t ty = tr.ty0; ty <= tr.ty1; ++ty)
        for (int64_t tx = tr.tx0; tx <= tr.tx1; ++tx) {
            visited += flakes_in_node(fp, &cl, p, tx, ty, 0, 0, 0, cl.residual,
                                      max_flakes - visited, truncated, visit);
            if (truncated) return visited;
        }
    return visited;
}

}  // namespace spangle::flake
