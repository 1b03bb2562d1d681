/*
 * Spangle material plugin ABI, version 3.
 *
 * Version 2 added object-space shading data (position, normal, footprint) and the NO_UV flag, so
 * that a model can lay out a texture-like field on meshes without usable uvs, and the optional
 * requirements() query. Version 3 adds textured parameters: a model marks the FLOAT and COLOR
 * parameters it can vary over the surface (SPANGLE_PARAM_TEXTURABLE), and the host hands it
 * their per-point values in the shading batch (param_values); and the optional glint outputs of
 * eval and sample (the part of f that comes from discrete glints, for the render layers).
 * Within version 3, the shading batch gained roughness_floor at its end, announced per point by
 * the flag SPANGLE_SHADING_ROUGHNESS_FLOOR, so that plugins and hosts of either age still agree.
 *
 * The only header a plugin includes. Plain C: no exceptions, no C++ types, memory freed by
 * whoever allocated it. A plugin is a shared library exporting one symbol:
 *
 *     const SpangleMaterialPlugin_v3* spangle_material_plugin(uint32_t host_abi_version);
 *
 * It returns a static table that lives as long as the library is loaded. The host reads
 * abi_version and struct_size first and refuses the table when abi_version differs from its own
 * SPANGLE_MATERIAL_ABI_VERSION. A plugin may offer several models (the smooth plugin offers five:
 * diffuse, conductor, dielectric, plastic, metal_rough); a scene names a plugin and one of its
 * models. The library is found as libspangle_<name>.so on the plugin path; docs/plugins.md says
 * how to build one outside the source tree, with a complete example.
 *
 * Frames and units. Every direction handed to a kernel is in the local shading frame
 * (x = normalised dpdu made orthogonal to n, z = shading normal n), unit length. The host orients
 * the frame towards the incoming ray (flag SPANGLE_SHADING_BACKFACE says it flipped it); with
 * interpolated normals wo.z can still be slightly negative, which reflection models treat as
 * no reflection. wo points away
 * from the surface towards the previous vertex. f is the BSDF value in 1/sr (cosine not
 * included), pdf is per unit solid angle. Colours are RGB in the scene's working space.
 *
 * Threads. create() and destroy() run on one thread. prepare(), eval() and sample() may run
 * concurrently on different batches with the same instance, so an instance is read-only after
 * create() (statistics go through atomics or per-batch counters the plugin owns).
 *
 * What the host tolerates. Nothing may throw across this ABI; an exception that escapes anyway
 * stops the render with an error naming the plugin, material and kernel, and a crash in a kernel
 * prints their names before the process dies. Outputs the integrator cannot use are dropped and
 * reported per material at the end of the render: from sample(), a wi not finite or zero, an f
 * negative or not finite, a pdf not finite, negative or 0 with f > 0, a REFLECTION leaving on
 * the other side from wo or a TRANSMISSION on the same side (flags become 0); from eval(), an f
 * negative or not finite or a pdf not finite or negative (both become 0). A glint outside
 * [0, f] is clamped into it. A wi that is not unit length is normalised.
 */
#ifndef SPANGLE_PLUGIN_H
#define SPANGLE_PLUGIN_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SPANGLE_MATERIAL_ABI_VERSION 3u
#define SPANGLE_MATERIAL_ENTRY_POINT "spangle_material_plugin"

#if defined(_WIN32)
#define SPANGLE_PLUGIN_EXPORT __declspec(dllexport)
#else
#define SPANGLE_PLUGIN_EXPORT __attribute__((visibility("default")))
#endif

/* ---------------------------------------------------------------- parameters */

/** Type of one material parameter. */
typedef enum SpangleParamType {
    SPANGLE_PARAM_FLOAT = 0,  /* one float, range-checked */
    SPANGLE_PARAM_INT = 1,    /* one integer, range-checked; passed in number[0] as a double
                                 (exact up to 2^53) */
    SPANGLE_PARAM_BOOL = 2,   /* true or false */
    SPANGLE_PARAM_COLOR = 3,  /* RGB; the host converts it to the working space at load */
    SPANGLE_PARAM_STRING = 4, /* one of the choices in SpangleParamDesc_v3.choices (any text
                                 when choices is NULL) */
    SPANGLE_PARAM_VEC3 = 5    /* three numbers passed as written (no colour management), each
                                 range-checked; e.g. a conductor's per-channel complex IOR */
} SpangleParamType;

/** One entry of a model's parameter schema. The host validates scene values against it. */
typedef struct SpangleParamDesc_v3 {
    const char* name;           /* snake_case key in the scene file */
    SpangleParamType type;      /* value type */
    double default_value[3];    /* FLOAT/INT/BOOL: [0]; COLOR: RGB in the working space; VEC3 */
    const char* default_string; /* STRING: default choice; NULL otherwise */
    double min_value;           /* FLOAT/INT/COLOR (each channel): inclusive lower bound */
    double max_value;           /* FLOAT/INT/COLOR (each channel): inclusive upper bound */
    const char* choices;        /* STRING: allowed values separated by '|'; NULL otherwise */
    const char* doc;            /* one line for `spangle plugins` */
    uint32_t flags;             /* SPANGLE_PARAM_* bits below */
} SpangleParamDesc_v3;

/** Bits of SpangleParamDesc_v3.flags. */
#define SPANGLE_PARAM_TEXTURABLE                                     \
    1u /* FLOAT or COLOR only: the model reads per-point values from \
          SpangleShadingBatch_v3.param_values when given, so a scene may bind a texture to it */

/** One validated parameter value handed to create(). */
typedef struct SpangleParamValue_v3 {
    const char* name; /* same pointer text as the schema entry's name */
    SpangleParamType type;
    double number[3];   /* FLOAT/INT/BOOL: [0]; COLOR: RGB in the working space; VEC3: as written */
    const char* string; /* STRING: the chosen value; NULL otherwise */
} SpangleParamValue_v3;

/** The full parameter set: one value per schema entry, in schema order, defaults filled in. */
typedef struct SpangleParams_v3 {
    const SpangleParamValue_v3* values; /* count entries, in schema order */
    uint32_t count;                     /* equals the model's param_count */
} SpangleParams_v3;

/* ---------------------------------------------------------------- host services */

/** Log levels for SpangleHost_v3.log. */
typedef enum SpangleLogLevel {
    SPANGLE_LOG_DEBUG = 0,
    SPANGLE_LOG_INFO = 1,
    SPANGLE_LOG_WARNING = 2,
    SPANGLE_LOG_ERROR = 3
} SpangleLogLevel;

/** Services the host offers to a plugin. Valid from create() until destroy() of the instance. */
typedef struct SpangleHost_v3 {
    uint32_t abi_version;      /* SPANGLE_MATERIAL_ABI_VERSION of the host */
    void* context;             /* opaque, passed back to every call below */
    const char* working_space; /* name of the scene-linear working space (an OCIO colour space) */

    /** Writes one message to the host's log. */
    void (*log)(void* context, SpangleLogLevel level, const char* message);

    /** Converts count RGB triples in place from colour space `from_space` to the working space,
     *  through the scene's OCIO config. Returns 0 on success; otherwise writes a message of at
     *  most error_capacity bytes (NUL included) and returns non-zero, leaving rgb unspecified. */
    int (*convert_to_working)(void* context, const char* from_space, float* rgb, uint32_t count,
                              char* error, uint32_t error_capacity);

    /** Counter-based hash of (a, b): a pure function, the same on every thread and run. Plugins
     *  build their random numbers from it so that images do not depend on thread count. */
    uint64_t (*hash2)(uint64_t a, uint64_t b);
} SpangleHost_v3;

/** Bump allocator for per-batch scratch data (closures' variable-size parts). Memory handed out
 *  stays valid until the host has finished eval()/sample() on the closures of that batch. */
typedef struct SpangleArena_v3 {
    void* context;
    /** Returns `bytes` of memory aligned to `align` (a power of two <= 64), or NULL. */
    void* (*allocate)(void* context, size_t bytes, size_t align);
} SpangleArena_v3;

/* ---------------------------------------------------------------- batches */

/** Bits of SpangleShadingBatch_v3.flags. */
#define SPANGLE_SHADING_HAS_DIFFERENTIALS 1u /* du/dx..dv/dy come from real ray differentials */
#define SPANGLE_SHADING_BACKFACE                                    \
    2u /* the ray hit the back of the surface; the host flipped the \
          frame so that the geometric normal faces wo */
#define SPANGLE_SHADING_NO_UV                                              \
    4u /* the mesh has no uvs here (none at all, or a degenerate mapping): \
          u, v and their derivatives carry no layout */
#define SPANGLE_SHADING_ROUGHNESS_FLOOR                                      \
    8u /* path regularisation: roughness_floor[i] holds a GGX alpha that the \
          point's glossy lobes should not be sharper than (see the field) */

/** Shading points, structure of arrays, `count` entries each. Positions in world space (metres),
 *  wo in the local shading frame. When SPANGLE_SHADING_HAS_DIFFERENTIALS is clear for a point,
 *  its uv and position derivatives carry no pixel footprint and a footprint-based model must fall
 *  back to its smooth expectation. The object-space fields describe the same point in its
 *  object's own coordinates (before the object's transform), so that a pattern laid out there
 *  stays fixed to the object as it moves. */
typedef struct SpangleShadingBatch_v3 {
    uint32_t count;
    const float* p_x;
    const float* p_y;
    const float* p_z;
    const float* wo_x; /* local frame */
    const float* wo_y;
    const float* wo_z;
    const float* u; /* surface parameterisation */
    const float* v;
    const float* du_dx; /* screen-space uv derivatives, per pixel */
    const float* du_dy;
    const float* dv_dx;
    const float* dv_dy;
    const float* uv_area; /* |dp/du x dp/dv|: world area per unit uv area (m^2) */
    const float* obj_p_x; /* object-space position */
    const float* obj_p_y;
    const float* obj_p_z;
    const float* obj_n_x; /* object-space shading normal, unit length */
    const float* obj_n_y;
    const float* obj_n_z;
    const float* obj_dpdx_x; /* object-space footprint axes, per pixel */
    const float* obj_dpdx_y;
    const float* obj_dpdx_z;
    const float* obj_dpdy_x;
    const float* obj_dpdy_y;
    const float* obj_dpdy_z;
    const uint32_t* flags; /* SPANGLE_SHADING_* bits */
    const uint32_t*
        path_id; /* index of the path in the host's wavefront, for the plugin's hashing */
    /** One entry per schema parameter, in schema order (param_count of them), or NULL when no
     *  parameter varies. Entry k is NULL when parameter k is constant (its value is the one
     *  create() received); otherwise it holds count values (FLOAT) or count RGB triples (COLOR,
     *  interleaved, working space), already within the parameter's range. Only parameters marked
     *  SPANGLE_PARAM_TEXTURABLE are ever given here. */
    const float* const* param_values;
    /** Path regularisation (the host's [render] filter_glossy): for a point whose flags carry
     *  SPANGLE_SHADING_ROUGHNESS_FLOOR, a GGX alpha in (0, 0.5] below which the model should
     *  not let its glossy and mirror lobes go (a path that already scattered off a rough or
     *  diffuse surface sees a sharp lobe only by chance: caustics). Read it only for points
     *  with the bit: a host older than this field never sets it, and the field may then be
     *  absent. A model that ignores it stays correct, only noisier. */
    const float* roughness_floor;
} SpangleShadingBatch_v3;

/** Directions to evaluate: for query i, closure closure_index[i] and direction wi[i] (local
 *  frame). closure_index may be NULL, meaning query i uses closure i. */
typedef struct SpangleEvalBatch_v3 {
    uint32_t count;
    const uint32_t* closure_index;
    const float* wi_x;
    const float* wi_y;
    const float* wi_z;
    float* f_r; /* out: BSDF value, 1/sr */
    float* f_g;
    float* f_b;
    float* pdf; /* out: solid-angle pdf of sample() producing wi */
    /** out, may be NULL (then not asked for): the part of f that comes from discrete glints
     *  (a flake model's individual flakes), <= f per channel; the host sets them to 0 before
     *  the call, so a model without glints leaves them alone. */
    float* glint_r;
    float* glint_g;
    float* glint_b;
} SpangleEvalBatch_v3;

/** Bits of SpangleSampleBatch_v3.flags. An invalid sample has flags 0, f 0 and pdf 0. */
#define SPANGLE_SAMPLE_REFLECTION 1u
#define SPANGLE_SAMPLE_TRANSMISSION 2u
#define SPANGLE_SAMPLE_DIFFUSE 4u
#define SPANGLE_SAMPLE_GLOSSY 8u
#define SPANGLE_SAMPLE_SPECULAR 16u /* delta lobe: pdf and f are both delta-scaled */

/** Samples to draw: for query i, closure closure_index[i] (or i when NULL) with uniform numbers
 *  u0[i], u1[i], u2[i] in [0, 1). */
typedef struct SpangleSampleBatch_v3 {
    uint32_t count;
    const uint32_t* closure_index;
    const float* u0;
    const float* u1;
    const float* u2; /* lobe selection */
    float* wi_x;     /* out: local frame */
    float* wi_y;
    float* wi_z;
    float* f_r; /* out: BSDF value, 1/sr */
    float* f_g;
    float* f_b;
    float* pdf;      /* out: solid-angle pdf */
    uint32_t* flags; /* out: SPANGLE_SAMPLE_* bits, 0 for an invalid sample */
    float* eta;      /* out, may be NULL: for a transmission, eta_transmitted / eta_incident (the
                        host bends ray differentials with it); 1 otherwise */
    float* glint_r;  /* out, may be NULL: as in SpangleEvalBatch_v3, for the sampled wi */
    float* glint_g;
    float* glint_b;
} SpangleSampleBatch_v3;

/** One named statistic reported by a model instance for `spangle render --stats`. */
typedef struct SpangleStat_v3 {
    const char* name; /* static string */
    double value;
} SpangleStat_v3;

/* ---------------------------------------------------------------- the table */

/** One material model: its schema and its batch kernels. */
typedef struct SpangleMaterialModel_v3 {
    const char* name; /* e.g. "diffuse"; unique within the plugin */
    const char* doc;  /* one line */
    const SpangleParamDesc_v3* params;
    uint32_t param_count;
    uint32_t closure_size; /* bytes of per-shading-point closure prepare() writes, <= 4096 */

    /** Creates an instance from a full, validated parameter set. Returns NULL and writes a message
     *  (at most error_capacity bytes, NUL included) when the values are unusable together. */
    void* (*create)(const SpangleParams_v3* params, const SpangleHost_v3* host, char* error,
                    uint32_t error_capacity);
    /** Frees an instance made by create(). */
    void (*destroy)(void* instance);

    /** Writes batch->count closures of closure_size bytes each to `closures`, closure i at
     *  closures + i * closure_size (the array starts 16-byte aligned; every closure is when
     *  closure_size is a multiple of 16).
     *  Variable-size data goes to `arena`. */
    void (*prepare)(const void* instance, const SpangleShadingBatch_v3* batch, void* closures,
                    SpangleArena_v3* arena);
    /** Evaluates f and pdf for each query. */
    void (*eval)(const void* instance, const void* closures, SpangleEvalBatch_v3* queries);
    /** Samples wi with pdf for each query. */
    void (*sample)(const void* instance, const void* closures, SpangleSampleBatch_v3* queries);

    /** Optional (may be NULL): writes at most capacity statistics, returns how many exist. */
    uint32_t (*stats)(const void* instance, SpangleStat_v3* out, uint32_t capacity);
    /** Optional (may be NULL): SPANGLE_REQUIRES_* bits of what an instance needs from the
     *  meshes it shades; the host warns about an object that cannot provide it. */
    uint32_t (*requirements)(const void* instance);
} SpangleMaterialModel_v3;

/** Bits of SpangleMaterialModel_v3.requirements(). */
#define SPANGLE_REQUIRES_UV 1u /* a layout in uv: a mesh without usable uvs loses it */
/* A layout in object space (the rest pose of a deforming or posed mesh, where it has one):
 * triangles without area there lose it. _WITHOUT_UV: only on meshes without usable uvs (the
 * pattern is laid out in uv where there are some). */
#define SPANGLE_REQUIRES_OBJECT_SPACE 2u
#define SPANGLE_REQUIRES_OBJECT_SPACE_WITHOUT_UV 4u
/* The instance reads no footprint: not dudx, dudy, dvdx, dvdy, the object-space footprint
 * axes (odx*, ody*) nor the flag SPANGLE_SHADING_HAS_DIFFERENTIALS. When every material of a
 * scene says so and none has a texture or a normal or bump map, the host computes no footprints
 * (those fields are then 0 and the flag unset): less work per hit. A model without
 * requirements(), or without this bit, gets footprints, as before the bit existed. */
#define SPANGLE_IGNORES_FOOTPRINT 8u

/** The table a plugin returns. */
typedef struct SpangleMaterialPlugin_v3 {
    uint32_t abi_version; /* SPANGLE_MATERIAL_ABI_VERSION the plugin was built with */
    uint32_t struct_size; /* sizeof(SpangleMaterialPlugin_v3) in the plugin's build */
    const char* name;     /* e.g. "smooth"; the file is libspangle_<name>.so */
    const char* doc;      /* one line */
    const SpangleMaterialModel_v3* models;
    uint32_t model_count;
} SpangleMaterialPlugin_v3;

/** Signature of the entry point. */
typedef const SpangleMaterialPlugin_v3* (*SpangleMaterialEntry_v3)(uint32_t host_abi_version);

#ifdef __cplusplus
}
#endif

#endif /* SPANGLE_PLUGIN_H */
