#pragma once
// The whole flake material: a diffuse base, the flakes (discrete, smooth, or a blend of the two by
// the expected flake count in the footprint), optionally under a clear coat:
//
//     f = f_coat + (1 - E(wo)) (1 - E(wi)) [(1 - flake_weight) base / pi + flake_weight f_flakes]
//
// Per shading point, prepare_point() decides from the expected count lambda (density x footprint
// area) between the discrete lobe (lambda <= min_flakes), the smooth lobe (lambda >= max_flakes,
// or no ray differentials) or a blend with weight smoothstep(log lambda). The discrete lobe comes
// from one of two algorithms over the same flake field: `enumerate` (a reflection cache of every
// flake in the footprint, cost linear in lambda) or `tree` (cache for small cells, counted
// aggregates for the rest, cost independent of lambda). Directions are in the local shading
// frame; the thin coat does not bend them. The discrete lobe is not reciprocal (it is built around
// wo); a path tracer from the camera does not need reciprocity.

#include <spangle/plugin.h>

#include <atomic>
#include <memory>
#include <string>

#include "coat.h"
#include "counted_lobe.h"
#include "discrete_lobe.h"
#include "field.h"
#include "palette.h"
#include "smooth_lobe.h"
#include "thin_film.h"

namespace spangle::flake {

/** A created material: parameters and every table derived from them. Read-only after create(),
 *  except the statistics counters and the smooth lobe's lazily built view slices. */
struct Material {
    enum class Space { Auto, Uv, World, Object };
    FieldParams field;
    Space space = Space::Auto;
    float density = 0;
    float alpha = 0.15f;
    Cone cone;
    float footprint_scale = 1;
    double min_flakes = 500, max_flakes = 2000;
    bool tree = true;                     ///< algorithm = "tree"
    uint32_t exact_flakes = 256;          ///< tree: cells up to this count are enumerated
    uint32_t stand_ins = kStandIns;       ///< tree: stand-ins per footprint area (counted_lobe.h)
    float sparse_flakes = kSparseFlakes;  ///< tree: footprints this sparse are enumerated
    uint32_t enumerate_cap = 0;           ///< enumerate: hard bound on flakes per shading point
    float base[3] = {0, 0, 0};
    float flake_weight = 0.6f;
    bool shadowing = true;
    FresnelTable fresnel;  ///< the flakes' Fresnel (with a film: its mean over the thicknesses)
    /** Dielectric flakes (mica, glass): what a flake does not reflect passes through it to the
     *  base and back, 1 - F each way (a conductor's is absorbed). */
    bool transmits = false;
    FilmTables film;  ///< per-thickness Fresnel tables of interference flakes (empty: none)
    ColorTable colors;
    SmoothLobe smooth;
    DirectionGrid grid;
    /** The share of flakes that enter a view's reflection cache (the rest reflect wo under the
     *  horizon): a footprint holds one that counts with probability 1 - e^-(lambda x it). */
    CacheShare cache_share;
    /** The scale of a footprint of few flakes, so that it averages to the far look (its lobe is
     *  normalised by its own W: it reflects its flakes' albedos weighted among themselves). */
    SparseAlbedo sparse;
    Coat coat;
    /** The coat made rougher for path regularisation (SPANGLE_SHADING_ROUGHNESS_FLOOR). */
    std::unique_ptr<CoatFloors> coat_floors;
    /** Facets (flake_size > 0): the outline every flake has; null for point flakes. */
    std::unique_ptr<FacetShape> facet;
    double flake_size = 0;  ///< metres (object units in object space): a facet's width
    /** The second flake population (flakes2_*): a material of its own density, roughness, cone,
     *  colour and field (its seed salted), sharing this one's Fresnel, film, colour variation and
     *  footprint; only its flake lobe is used. Null with flakes2_weight = 0. */
    std::unique_ptr<Material> second;
    float second_weight = 0;  ///< flakes2_weight: the second population's share of the flakes

    // Statistics for --stats (relaxed atomics, summed per batch).
    mutable std::atomic<uint64_t> points{0}, discrete{0}, blended{0}, smooth_only{0};
    mutable std::atomic<uint64_t> truncated{0}, flakes_cached{0}, flakes_aggregated{0};
    mutable std::atomic<uint64_t> aggregates{0}, lambda_milli_sum{0}, lambda_count{0};
    mutable std::atomic<uint64_t> sparse_enumerated{0}, sparse_faded{0};
    mutable std::atomic<uint64_t> ns_prepare{0}, ns_eval{0}, ns_sample{0};
};

/** Builds m from validated parameters; false with `why` set when they cannot be used together. */
bool init_material(Material& m, const SpangleParams_v3* p, const SpangleHost_v3* host,
                   std::string& why);

/** Per-shading-point closure (lives in the host's closure array). */
struct Closure {
    V3 wo;
    float t = 1.0f;            ///< weight of the smooth lobe in the flake blend
    DiscreteLobe lobe;         ///< the reflection cache (count 0 when unused)
    CountedFootprint counted;  ///< tree: the aggregates
    float w_norm = 0;          ///< W: cached flakes' weights plus the aggregates' expected ones
    float w_expected = 0;      ///< E[w] of one flake at wo
    float p_cache = 1;         ///< discrete part: probability of sampling the cache
    float p_coat = 0, p_base = 0, p_flake = 0;  ///< lobe selection probabilities
    float e_coat_o = 0;                         ///< coat albedo at wo
    const Coat* coat = nullptr;  ///< the material's coat, or a rougher one (set by prepare_point)
    float v_o = 1;               ///< share of visible flake normals reflecting above the horizon
    uint32_t valid = 0;          ///< wo above the surface
    float base[3] = {0, 0, 0};   ///< base_color here (textured or the material's)
    float weight = 0;            ///< the flakes' share of the footprint (flake_weight far away)
    const Closure* second = nullptr;  ///< the second population's flakes (arena; null: none)
    float w_second = 0;               ///< its share of the flake lobe (0 without it)
    float cover = 0;                  ///< facets: the shares of the flakes inside the footprint
    uint32_t centres_in = 0;          ///< facets with a cache entry whose centre is inside
    float q_second = 0;               ///< probability that flake sampling picks it
};

/** What prepare_point() reports for the statistics. */
struct PointStats {
    uint64_t discrete = 0, blended = 0, smooth = 0, truncated = 0;
    uint64_t cached = 0, aggregated = 0, aggregates = 0, lambda_milli = 0, lambda_count = 0;
    /** Tree: footprints of point flakes enumerated for their sparse lobes (sparse_share 1), and
     *  those mixing the enumeration with the count (between 0 and 1). */
    uint64_t sparse_enumerated = 0, sparse_faded = 0;
};

/** The shading data of one point, as the batch gives it. */
struct PointInput {
    V3 wo;
    float u = 0, v = 0, du_dx = 0, du_dy = 0, dv_dx = 0, dv_dy = 0, uv_area = 0;
    V3 p_obj, n_obj, dpdx_obj, dpdy_obj;  ///< object space: position, normal, footprint axes
    uint32_t flags = 0;
    float roughness_floor = 0;  ///< path regularisation: GGX alpha the coat is kept above (0: none)
    float base[3] = {0, 0, 0};  ///< base_color at the point
    float weight = 0;           ///< flake_weight at the point (0: no flakes, nothing to find)
};

/** Where a shading point's flakes come from: a footprint in some plane of flake tiles, the field's
 *  density there and seed, and the share of the field's flakes that belong to the surface. */
struct FieldView {
    Footprint footprint;
    double per_tile = 0;    ///< flakes per tile (a unit square, or 2^j units: tile_side)
    uint64_t seed = 0;      ///< the field's seed (the material's, salted per object-space plane)
    float keep = 1.0f;      ///< each flake is kept with this probability (hashed per flake)
    double facet_size = 0;  ///< facets: a flake's width in the plane's units (0: point flakes)
    double lambda() const { return per_tile * footprint.area() * static_cast<double>(keep); }
};

/** The field view of a point: uv (density per uv square, or per square metre with `world`), or
 *  object space for `object` (and for `auto` where the mesh has no usable uvs). In object space
 *  the flakes lie in the coordinate plane most facing the surface (the one of the normal's largest
 *  component k), at density sqrt(3) times the material's, thinned by 1 / (sqrt(3) |n_k|) (at most
 *  1: |n_k| >= 1 / sqrt(3)): the surface gets exactly the material's density per unit area, and
 *  the flakes are fixed to the object. Where the dominant plane changes, the realisation changes
 *  (a seam in which flakes, never in how many or how bright). */
FieldView field_view(const Material& m, const PointInput& in);

/** Builds the closure of one point; the cache goes to `arena`. */
void prepare_point(const Material& m, const PointInput& in, Closure& c, SpangleArena_v3* arena,
                   PointStats& st);

/** The whole material at wi: f (RGB) and the pdf of sample_material(). `glint`, when not null,
 *  receives the part of f the discrete flakes make (the glints, without the smooth lobe). */
void eval_material(const Material& m, const Closure& c, V3 wi, float f[3], float& pdf,
                   float* glint = nullptr);

/** Samples the whole material. Fills wi, f, pdf and SPANGLE_SAMPLE_* flags (0 when it fails). */
void sample_material(const Material& m, const Closure& c, float u0, float u1, float u2, V3& wi,
                     float f[3], float& pdf, uint32_t& flags, float* glint = nullptr);

}  // namespace spangle::flake
