#pragma once
// The path tracer's state, declared once as field lists and generated into structure-of-arrays
// batches (as ecs/pool.h does for components): a field added here is a column of every wave,
// resized with the others, with no list to keep by hand.
//
//   PathBatch      one entry per path of a wave: its pixel and sample, its ray, throughput and
//                  radiance, what its last bounce was, the surface it stands on
//   ShadingBatch   one entry per shading point of a material batch: the plugin ABI's SoA inputs
//                  (positions, outgoing directions, uvs and footprints, object-space frames),
//                  and the buffers eval and sample fill

#include <cstddef>
#include <cstdint>
#include <vector>

#include "render/camera.h"
#include "render/lights.h"
#include "render/surface.h"

#define SPANGLE_DETAIL_SOA_COLUMN(type, name, doc) std::vector<type> name;
#define SPANGLE_DETAIL_SOA_RESIZE(type, name, doc) name.resize(n);

/** Declares struct Name with one std::vector column per (type, name, doc) entry of FIELDS and
 *  resize(n), which resizes every column (new entries are value-initialised; old ones keep
 *  their values: every stage writes a column before it reads it). */
#define SPANGLE_SOA(Name, FIELDS)                                        \
    struct Name {                                                        \
        FIELDS(SPANGLE_DETAIL_SOA_COLUMN)                                \
        void resize(std::size_t n) { FIELDS(SPANGLE_DETAIL_SOA_RESIZE) } \
    }

namespace spangle {

#define SPANGLE_PATH_FIELDS(X)                                                                    \
    X(uint32_t, pixel, "full-frame pixel index y * width + x (the block's pixel in a preview)")   \
    X(uint32_t, sample, "sample index within the pixel")                                          \
    X(uint64_t, key, "sobol_pixel_key of the pixel")                                              \
    X(float, time, "time in the shutter, 0..1 (0 without motion)")                                \
    X(RayDifferential, ray, "the ray to trace next, with its differentials")                      \
    X(uint8_t, has_diff, "the ray's differentials are real (camera or specular bounces)")         \
    X(float, fp_width, "footprint width at the ray origin (without differentials)")               \
    X(float, fp_spread, "footprint growth per unit distance (without differentials)")             \
    X(Vec3, throughput, "product of f cos / pdf along the path")                                  \
    X(Vec3, radiance, "light the path has gathered")                                              \
    X(float, prev_pdf, "solid-angle pdf of the last BSDF sample")                                 \
    X(uint8_t, prev_delta, "the last bounce was a delta lobe (or the camera)")                    \
    X(float, min_pdf, "smallest pdf of the path's non-delta bounces (+inf: none yet)")            \
    X(uint8_t, active, "the path goes on")                                                        \
    X(uint8_t, catcher,                                                                           \
      "0: ordinary; 1: its camera ray met a shadow catcher, its light is the plate's (dropped); " \
      "2: it then met another object, its light is a reflection (kept)")                          \
    X(uint32_t, material, "material of the surface hit at this bounce")                           \
    X(SurfacePoint, surf, "the surface hit at this bounce, as shading sees it")
/** The paths of one wave. */
SPANGLE_SOA(PathBatch, SPANGLE_PATH_FIELDS);

#define SPANGLE_SHADING_FIELDS(X)                                                      \
    X(float, px, "position x, world")                                                  \
    X(float, py, "position y, world")                                                  \
    X(float, pz, "position z, world")                                                  \
    X(float, wox, "outgoing direction x, shading frame")                               \
    X(float, woy, "outgoing direction y, shading frame")                               \
    X(float, woz, "outgoing direction z (along the normal), shading frame")            \
    X(float, u, "surface u")                                                           \
    X(float, v, "surface v")                                                           \
    X(float, dudx, "du of the footprint's x axis (ray differentials)")                 \
    X(float, dudy, "du of the footprint's y axis")                                     \
    X(float, dvdx, "dv of the footprint's x axis")                                     \
    X(float, dvdy, "dv of the footprint's y axis")                                     \
    X(float, uv_area, "|dp/du x dp/dv|, m^2 per unit uv area")                         \
    X(float, opx, "position x, object space")                                          \
    X(float, opy, "position y, object space")                                          \
    X(float, opz, "position z, object space")                                          \
    X(float, onx, "geometric normal x, object space")                                  \
    X(float, ony, "geometric normal y, object space")                                  \
    X(float, onz, "geometric normal z, object space")                                  \
    X(float, odxx, "footprint x axis, x, object space")                                \
    X(float, odxy, "footprint x axis, y, object space")                                \
    X(float, odxz, "footprint x axis, z, object space")                                \
    X(float, odyx, "footprint y axis, x, object space")                                \
    X(float, odyy, "footprint y axis, y, object space")                                \
    X(float, odyz, "footprint y axis, z, object space")                                \
    X(uint32_t, flags, "SPANGLE_SHADING_* flags")                                      \
    X(uint32_t, path_id, "the path each point belongs to")                             \
    X(float, rough_floor, "path regularisation: GGX alpha floor (0: none)")            \
    X(float, f_r, "BSDF value, red (eval and sample)")                                 \
    X(float, f_g, "BSDF value, green")                                                 \
    X(float, f_b, "BSDF value, blue")                                                  \
    X(float, pdf, "solid-angle pdf (eval and sample)")                                 \
    X(float, wix, "incident direction x, shading frame (light queries, then samples)") \
    X(float, wiy, "incident direction y, shading frame")                               \
    X(float, wiz, "incident direction z, shading frame")                               \
    X(float, u0, "BSDF sample number, first")                                          \
    X(float, u1, "BSDF sample number, second")                                         \
    X(float, u2, "BSDF lobe choice number")                                            \
    X(float, eta, "relative index of refraction of a sampled transmission")            \
    X(uint32_t, closure_index, "the shading point of each eval query")                 \
    X(uint32_t, sample_flags, "SPANGLE_SAMPLE_* flags of each sample")                 \
    X(uint32_t, light_query, "the shading point of each light query")                  \
    X(LightSample, light, "the light sample of each query")
/** One material batch's shading points (the plugin ABI's arrays). */
SPANGLE_SOA(ShadingBatch, SPANGLE_SHADING_FIELDS);

}  // namespace spangle
