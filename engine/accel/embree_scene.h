#pragma once
// Ownership of Embree objects and the scene's ray queries. Each distinct mesh is one bottom-level
// scene (BLAS); each object is an instance of it with its transform; quad lights are one extra
// triangle geometry in the top-level scene. Errors from Embree reach us through the device's
// error callback and become SpangleErrors.

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/progress.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** One placed mesh: which mesh, its material, its transform. */
struct Instance {
    uint32_t mesh = 0;           ///< index into GeometryStore::meshes
    uint32_t material = 0;       ///< index into the scene's materials
    Affine to_world;             ///< object to world
    Affine to_object;            ///< world to object (the inverse of to_world)
    Affine normal_to_world;      ///< inverse transpose of to_world's linear part (no translation)
    int32_t emitter = -1;        ///< first light-table entry of its triangles, or -1
    uint32_t object = 0;         ///< its [[object]] number in the scene file, from 0
    uint8_t shadow_catcher = 0;  ///< 1: shows only the shadows and reflections of others
    /** A moving instance (motion blur): to_world at evenly spaced times over the shutter (ray
     *  time 0 to 1), interpolated linearly in between; empty for one that stands still (to_world
     *  is then its placement at every time). */
    std::vector<Affine> motion;
    /** Not traced: its placement is singular (a scale of 0, as an animation passing through it
     *  has at one instant), so the object has no extent and rays could not enter its space. */
    bool hidden = false;
};

/** Where ray time `time` (in [0, 1]; clamped, 0 when not finite) falls among `steps` >= 2 evenly
 *  spaced time steps, as Embree's motion blur places it: between step `first` and the next, at
 *  fraction `s` of the way. Moving instances and the moving camera blend their steps by it. */
void motion_step(std::size_t steps, float time, std::size_t& first, float& s);

/** The instance at ray time `time` in [0, 1]: its transforms interpolated as Embree does
 *  (linearly between the two steps around the time), without its steps. `inst` itself when it
 *  does not move. */
Instance instance_at(const Instance& inst, float time);

/** What a ray hit. */
enum class HitKind : uint8_t {
    Instance,  ///< a triangle of an object's mesh
    Quad,      ///< a triangle of a quad light (prim / 2 = quad index)
    Sphere     ///< a sphere light (prim = sphere index)
};

/** A ray hit, resolved to what shading needs to look up. */
struct Hit {
    float t = 0.0f;                    ///< distance along the (unit) ray direction
    float b1 = 0.0f, b2 = 0.0f;        ///< barycentrics of vertices 1 and 2
    uint32_t prim = 0;                 ///< primitive index within its geometry
    int32_t instance = -1;             ///< instance index for HitKind::Instance, else -1
    HitKind kind = HitKind::Instance;  ///< what was hit
};

/** Whether a ray meets an instance's triangle where it crosses it: a cut-out (a leaf drawn on a
 *  quad with an alpha texture). The renderer supplies one per instance (RenderScene). */
struct CutOut {
    /** The coverage of triangle `prim` at barycentrics (b1, b2), in [0, 1]; null: opaque. It
     *  runs inside the ray tracer: it must be thread-safe and must not throw. */
    float (*coverage)(const void* self, uint32_t prim, float b1, float b2) = nullptr;
    const void* self = nullptr;  ///< what `coverage` reads
    /** >= 0: a hit counts where coverage >= cutoff (glTF's MASK); < 0: with probability
     *  coverage, decided by a hash of the ray and the triangle (pbrt's stochastic alpha), so
     *  the same ray decides alike whatever else is traced with it. */
    float cutoff = -1.0f;
};
/** One CutOut per instance, indexed as the instances; empty (or null): every surface opaque. */
using CutOuts = std::vector<CutOut>;

/** The share of rays `cut` lets meet triangle `prim` at (b1, b2), in expectation: 0 or 1 with a
 *  cutoff, the coverage by chance. What light sampling weighs an emitter's point by, so that
 *  its light is cut as the rays that meet it are. */
inline float met_share(const CutOut& cut, uint32_t prim, float b1, float b2) {
    if (!cut.coverage) return 1.0f;
    const float a = cut.coverage(cut.self, prim, b1, b2);
    if (cut.cutoff >= 0.0f) return a >= cut.cutoff ? 1.0f : 0.0f;
    return a >= 1.0f ? 1.0f : a > 0.0f ? a : 0.0f;
}

/** Which instance's triangle an area light's emitter triangle is, when that instance has a
 *  cut-out (instance -1: none). */
struct EmitterCut {
    int32_t instance = -1;
    uint32_t prim = 0;
};

/** An Embree device and committed scene. Not copyable; rtc handles released on destruction. */
class EmbreeScene {
public:
    EmbreeScene();
    ~EmbreeScene();
    EmbreeScene(const EmbreeScene&) = delete;
    EmbreeScene& operator=(const EmbreeScene&) = delete;

    /** Builds one BLAS per mesh, one instance per object, the quad light triangles
     *  (quad_vertices: 4 world-space corners per quad) and the sphere lights (x, y, z, radius).
     *  Called again (a reload), it keeps the BLAS of every mesh it already has (the same
     *  shared mesh object), releases the others and rebuilds the top level. `progress` (may
     *  be empty) is told how far the builds are, by triangles. Throws SpangleError. */
    void build(const GeometryStore& geometry, const std::vector<Instance>& instances,
               const std::vector<Vec3>& quad_vertices, const std::vector<float>& spheres,
               const WorkProgress& progress = {},
               const std::vector<uint8_t>& quad_see_through = {});

    /** Centre and radius of a sphere bounding everything in the scene (0 radius when empty). */
    void bounding_sphere(Vec3& center, float& radius) const;
    /** The scale of the scene's coordinates for offsetting ray origins near the world's origin
     *  (offset_origin): the largest coordinate magnitude of its bounds, at most 1 (1 when
     *  empty). Hit points are interpolated from vertices, so their error is relative to that
     *  magnitude: a fixed offset there would be far too large in a millimetre-sized scene. */
    float offset_scale() const { return offset_scale_; }

    /** Closest hit along o + t d for t in (0, tmax) at ray time `time` (in [0, 1] over the
     *  shutter: where moving instances are); false when nothing is hit. */
    bool intersect(Vec3 o, Vec3 d, float tmax, Hit& hit, float time = 0.0f,
                   const CutOuts* cut_outs = nullptr) const;
    /** Closest hits of n rays o[i] + t d[i], t in (0, 1e30), traced as one stream:
     *  found[i] says whether hits[i] is one. A ray's hit is the same bit for bit whatever else
     *  is in the stream (time[i]: the ray's time, as for intersect(); null: all at 0) (an
     *  incoherent stream: Embree's packets for coherent streams gave hits
     *  that changed in the last bits with the stream's make-up, so crops, passes and MPI bands
     *  could differ from the whole render; they saved no time here). It may differ from
     *  intersect()'s in the last bits (another Embree code path). */
    void intersect_stream(const Vec3* o, const Vec3* d, std::size_t n, Hit* hits, uint8_t* found,
                          const float* time = nullptr, const float* tnear = nullptr,
                          const CutOuts* cut_outs = nullptr) const;
    /** blocked[i] = whether something blocks o[i] + t d[i] for t in (0, tmax[i]), for n rays
     *  traced as one (incoherent) stream, at times time[i] (null: all at 0). A non-finite ray
     *  counts as blocked. */
    void occluded_stream(const Vec3* o, const Vec3* d, const float* tmax, std::size_t n,
                         uint8_t* blocked, const float* time = nullptr,
                         const CutOuts* cut_outs = nullptr) const;
    /** True when something blocks o + t d for t in (0, tmax) at ray time `time`. Each query
     *  lets rays through the instances' cut-outs when `cut_outs` is given. */
    bool occluded(Vec3 o, Vec3 d, float tmax, float time = 0.0f,
                  const CutOuts* cut_outs = nullptr) const;

    /** BLAS the last build() made and reused. */
    int blas_built() const { return built_; }
    int blas_reused() const { return reused_; }

    /** Geometry id of the quad lights in the top-level scene, for tests. */
    uint32_t quad_geometry() const { return quad_geom_; }
    /** Bytes Embree holds now and at most so far (its memory monitor). */
    std::size_t bytes() const {
        return static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, bytes_));
    }
    std::size_t peak_bytes() const {
        return static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, peak_bytes_));
    }

private:
    void check(const char* what) const;
    void resolve(const RTCRayHit& rh, Hit& hit) const;

    RTCDevice device_ = nullptr;
    RTCScene top_ = nullptr;
    std::vector<RTCScene> blas_;  ///< per mesh index of the last build
    /** BLAS by mesh, holding the mesh alive (Embree reads its vertex buffers). */
    std::map<const TriangleMesh*, std::pair<std::shared_ptr<const TriangleMesh>, RTCScene>>
        by_mesh_;
    /** Per instance of the last build: the BLAS of its mesh already placed in world space (in
     *  double), for a still placement whose axes are nearly parallel (see kBakeBelow in the
     *  .cpp); null for the others. */
    std::vector<RTCScene> baked_;
    int built_ = 0, reused_ = 0;
    uint32_t quad_geom_ = RTC_INVALID_GEOMETRY_ID;
    /** Per quad light: 1 when shadow rays pass through it (its geometry's occlusion filter
     *  reads this; none is set when every quad blocks). */
    std::vector<uint8_t> quad_see_through_;
    uint32_t sphere_geom_ = RTC_INVALID_GEOMETRY_ID;
    float offset_scale_ = 1.0f;
    std::atomic<std::ptrdiff_t> bytes_{0}, peak_bytes_{0};
    mutable std::string error_;  ///< last message from the error callback
};

}  // namespace spangle
