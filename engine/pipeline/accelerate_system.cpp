// The accelerate system: every object with a mesh placed as an instance, and the Embree scene
// over the instances and the lights' shapes (quads, spheres).

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

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

/** Meshes smaller than this across (world units) are not found by rays. */
constexpr float kSmallestSeen = 1e-14f;

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
    // Standing still, it is traced through its mesh placed in world space when its axes are
    // nearly parallel (EmbreeScene), so only a placement singular in double hides it (one whose
    // float determinant alone vanished, rows [1,1,1], [1,1,1.0001], [1,1.0001,1], was hidden).
    if (inst.motion.empty() && !invertible(inst.to_world) &&
        !(std::fabs(inst.to_world.determinant_in_double()) > 0.0))
        inst.hidden = true;
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

Vec3 lower(Vec3 a, Vec3 b) {
    return Vec3(std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z));
}
Vec3 upper(Vec3 a, Vec3 b) {
    return Vec3(std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z));
}

/** Checks each placed mesh against what float coordinates can carry: beyond Embree's reach it
 *  is an error (the object vanished without a word); an object small against its distance
 *  from the origin is warned of (at 1e6 a unit sphere's points lie 1/16 apart and rays leave
 *  it by 256 of those steps: its shading broke up in stripes). `instances` are in the order of
 *  the TriangleMeshRef pool. */
void check_reach(const ecs::Registry& r, const std::vector<Instance>& instances,
                 const GeometryStore& geometry, const Logger* log) {
    const auto* meshes = r.find_pool<TriangleMeshRef>();
    if (!meshes) return;
    // Each mesh's own bounds, once.
    std::vector<std::array<Vec3, 2>> bounds(geometry.meshes.size());
    std::vector<uint8_t> known(geometry.meshes.size(), 0);
    std::size_t coarse = 0;  // objects small against their distance from the origin
    std::string first;       // the first of them, said
    for (std::size_t i = 0; i < meshes->size() && i < instances.size(); ++i) {
        const Instance& inst = instances[i];
        if (inst.hidden || inst.mesh >= geometry.meshes.size()) continue;
        const TriangleMesh& mesh = *geometry.meshes[inst.mesh];
        if (mesh.vertex_count() == 0) continue;
        std::array<Vec3, 2>& b = bounds[inst.mesh];
        if (!known[inst.mesh]) {
            b = {Vec3(std::numeric_limits<float>::max()), Vec3(-std::numeric_limits<float>::max())};
            for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
                const Vec3 p = mesh.position(static_cast<uint32_t>(v));
                b[0] = lower(b[0], p);
                b[1] = upper(b[1], p);
            }
            known[inst.mesh] = 1;
        }
        // The world box of the placed box's corners, over the shutter's steps.
        Vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
        const auto place = [&](const Affine& m) {
            for (int c = 0; c < 8; ++c) {
                const Vec3 p =
                    m.apply_point(Vec3((c & 1) ? b[1].x : b[0].x, (c & 2) ? b[1].y : b[0].y,
                                       (c & 4) ? b[1].z : b[0].z));
                lo = lower(lo, p);
                hi = upper(hi, p);
            }
        };
        if (inst.motion.empty()) place(inst.to_world);
        for (const Affine& m : inst.motion) place(m);
        const auto reach = [](Vec3 a, Vec3 z) {
            return std::max({std::fabs(a.x), std::fabs(a.y), std::fabs(a.z), std::fabs(z.x),
                             std::fabs(z.y), std::fabs(z.z)});
        };
        const ecs::Entity e = meshes->entities()[i];
        const bool has_info = r.has<ObjectInfo>(e);
        const ObjectInfo info = has_info ? r.get<ObjectInfo>(e) : ObjectInfo{};
        const FileLoc at = info.loc;
        const std::string name =
            !info.name.empty() ? fmt::format("object '{}'", info.name)
                               : fmt::format("[[object]] #{}", has_info ? info.index + 1 : i + 1);
        const float own = reach(b[0], b[1]), world = reach(lo, hi);
        if (!(own < kEmbreeReach) || !(world < kEmbreeReach))
            throw_error(at,
                        "{}: its points reach {:.3g} from the origin{}, and the ray tracer "
                        "(Embree) leaves out geometry beyond {:.2g}: scale the scene down",
                        name, std::max(own, world), own < kEmbreeReach ? "" : " in its own file",
                        kEmbreeReach);
        const float extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
        // Every point in one place (a cage of coincident vertices): nothing to see, said.
        if (!(extent > 0.0f) && log)
            log->warn("{}: {} has no extent (its points all lie at one place): it is not seen",
                      at.str(), name);
        // Triangles this small are not found by Embree's float tests (a sphere 2e-14 across
        // is seen, one 2e-15 across is not): said, not left invisible without a word.
        else if (extent < kSmallestSeen && log)
            log->warn(
                "{}: {} is {:.3g} across, smaller than the ray tracer (Embree) finds triangles "
                "({:.0g}): it is not seen; model it in smaller units (larger numbers)",
                at.str(), name, extent, kSmallestSeen);
        // Rays leave a surface by 256 float steps at its coordinates: past twice its size, its
        // shading and shadows break up (a unit sphere at 1e6 shaded in stripes; at 1e5 it is
        // fine).
        const float step = std::nextafter(world, std::numeric_limits<float>::max()) - world;
        if (extent > 0.0f && 256.0f * step > 2.0f * extent) {
            if (coarse == 0)
                first = fmt::format(
                    "{}: {} is {:.3g} across but lies {:.3g} from the origin, "
                    "where float coordinates are {:.3g} apart",
                    at.str(), name, extent, world, step);
            ++coarse;
        }
    }
    if (log && coarse > 0)
        log->warn(
            "{}{}: its shape, shading and shadows break up; move the scene nearer the "
            "origin",
            first,
            coarse > 1
                ? fmt::format(" (and {} more object{} so)", coarse - 1, coarse == 2 ? "" : "s")
                : std::string());
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
    check_reach(r, out.instances, out.geometry, w.log);
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
