// The accelerate system: every object with a mesh placed as an instance, and the Embree scene
// over the instances and the lights' shapes (quads, spheres).

#include <cmath>

#include "core/memory.h"
#include "pipeline/systems.h"

namespace spangle {
namespace {

/** Whether a placement can be inverted safely: its linear part's determinant is finite and not
 *  negligible against its columns' lengths (a scale of 1e-6 along one axis still is). */
bool invertible(const Affine& a) {
    const float det = a.determinant();
    float norms = 1.0f;
    for (int c = 0; c < 3; ++c)
        norms *= std::sqrt(a.m[0][c] * a.m[0][c] + a.m[1][c] * a.m[1][c] + a.m[2][c] * a.m[2][c]);
    return std::isfinite(det) && std::isfinite(norms) && norms > 0.0f &&
           std::fabs(det) > 1e-15f * norms;
}

/** Makes an instance safe to trace. Embree blends a moving instance's steps linearly, so a step
 *  that is singular, or two steps whose determinants differ in sign (a mirror flip within the
 *  shutter: the blend passes through a flat object), would send rays into a singular space
 *  (Embree asserts); such an instance stands still at its frame placement for this frame. An
 *  instance whose placement is singular then (an animated scale crossing 0 at this frame) is
 *  hidden: it has no extent. */
void make_traceable(Instance& inst) {
    bool moving_ok = !inst.motion.empty();
    for (std::size_t k = 0; k < inst.motion.size() && moving_ok; ++k)
        moving_ok =
            invertible(inst.motion[k]) && (k == 0 || (inst.motion[k].determinant() > 0.0f) ==
                                                         (inst.motion[k - 1].determinant() > 0.0f));
    if (!inst.motion.empty() && !moving_ok) inst.motion.clear();
    if (inst.motion.empty() && !invertible(inst.to_world)) inst.hidden = true;
}

/** The instances of every object with a mesh, in TriangleMeshRef order; meshes indexed as in
 *  `geometry` (loaded ones, then subdivided ones). */
std::vector<Instance> place_instances(const ecs::Registry& r, uint32_t loaded_count) {
    std::vector<Instance> out;
    const auto* meshes = r.find_pool<TriangleMeshRef>();
    if (!meshes) return out;
    for (std::size_t i = 0; i < meshes->size(); ++i) {
        const ecs::Entity e = meshes->entities()[i];
        const TriangleMeshRef ref = meshes->columns().get(i);
        Instance inst;
        inst.mesh = ref.source == MeshSource::File ? ref.mesh : loaded_count + ref.mesh;
        inst.material = r.get<MaterialRef>(e).material;
        inst.to_world = r.get<Transform>(e).to_world;
        inst.normal_to_world = inst.to_world.normal_matrix();
        inst.to_object = inst.to_world.inverse();
        if (r.has<EmitterRef>(e)) inst.emitter = r.get<EmitterRef>(e).first;
        if (r.has<Motion>(e)) inst.motion = r.get<Motion>(e).steps;
        if (r.has<ObjectInfo>(e)) {
            inst.object = r.get<ObjectInfo>(e).index;
            inst.shadow_catcher = r.get<ObjectInfo>(e).shadow_catcher;
        }
        make_traceable(inst);
        out.push_back(std::move(inst));
    }
    return out;
}

/** Refuses a first BVH build that would not fit in memory: Embree's BVH, with its build-time
 *  peak, takes about 150 bytes per triangle on top of the meshes already loaded. */
void check_bvh_memory(const GeometryStore& geometry) {
    double triangles = 0.0;
    for (const auto& m : geometry.meshes) triangles += static_cast<double>(m->triangle_count());
    constexpr double kBvhBytesPerTriangle = 150.0;
    if (const uint64_t have = memory_short_for(triangles * kBvhBytesPerTriangle))
        throw_error(
            "the scene's {:.0f} triangles need about {} more for the ray-tracing structure, but "
            "only {} of memory is available: lower subdivision levels or use meshes with fewer "
            "triangles",
            triangles, format_bytes(triangles * kBvhBytesPerTriangle),
            format_bytes(static_cast<double>(have)));
}

void system_accelerate(ecs::Registry& r, World& w) {
    SceneGeometry out;
    uint32_t loaded = 0;
    if (const auto* m = w.products.find<LoadedMeshes>()) {
        out.geometry.meshes = m->meshes;
        loaded = static_cast<uint32_t>(m->meshes.size());
    }
    if (const auto* m = w.products.find<SubdividedMeshes>())
        out.geometry.meshes.insert(out.geometry.meshes.end(), m->meshes.begin(), m->meshes.end());
    out.instances = place_instances(r, loaded);
    std::vector<Vec3> quads;
    std::vector<uint8_t> quad_through;  // per quad: shadow rays pass it
    if (const auto* pool = r.find_pool<QuadLight>())
        for (std::size_t i = 0; i < pool->size(); ++i) {
            const QuadLight q = pool->columns().get(i);
            quads.insert(quads.end(), {q.corner, q.corner + q.edge1, q.corner + q.edge1 + q.edge2,
                                       q.corner + q.edge2});
            quad_through.push_back(q.transparent ? 1 : 0);
        }
    std::vector<float> spheres;
    if (const auto* pool = r.find_pool<SphereLight>())
        for (std::size_t i = 0; i < pool->size(); ++i) {
            const SphereLight l = pool->columns().get(i);
            spheres.insert(spheres.end(), {l.center.x, l.center.y, l.center.z, l.radius});
        }
    // A reload hands the live scene's EmbreeScene over: build() reuses the bottom-level
    // structure of every mesh it already has and rebuilds only the top level.
    const SceneGeometry* live = w.previous ? w.previous->products.find<SceneGeometry>() : nullptr;
    if (live) {
        out.accel = live->accel;
    } else {
        check_bvh_memory(out.geometry);
        out.accel = std::make_shared<EmbreeScene>();
    }
    out.accel->build(out.geometry, out.instances, quads, spheres, w.options.work_progress,
                     quad_through);
    if (w.cache) {
        const EmbreeScene& a = *out.accel;
        if (a.blas_reused() > 0) w.cache->reused["mesh BVHs"] += a.blas_reused();
        if (a.blas_built() > 0)
            w.cache->built.push_back(
                fmt::format("{} mesh BVH{}", a.blas_built(), a.blas_built() == 1 ? "" : "s"));
        w.cache->built.push_back("top-level BVH");
    }
    w.products.put(std::move(out));
}

}  // namespace

ecs::System<World> accelerate_system() {
    return ecs::system<World>("accelerate", system_accelerate)
        .needs_any<TriangleMeshRef, QuadLight, SphereLight>()
        .reading<LoadedMeshes, SubdividedMeshes, MaterialRef, Transform, Motion, ObjectInfo,
                 EmitterRef>()
        .writing<SceneGeometry>();
}

}  // namespace spangle
