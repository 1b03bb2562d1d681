// The intersection stage: every active path's ray traced as one stream; light picked up where a
// ray escapes or meets an emitter (weighted by MIS against next-event estimation); the surfaces
// the paths go on from reconstructed (position, frames, uvs, footprints) and the paths sorted by
// material for shading.

#include <algorithm>

#include "render/wave.h"

namespace spangle {
namespace {

/** Emission a ray picks up at a light it hits, MIS-weighted against next-event estimation;
 *  `group` is the light's light group. */
Vec3 emission_at_hit(const RenderScene& w, Strategy strategy, const PathBatch& p, std::size_t k,
                     const Hit& hit, uint32_t& group) {
    const RayDifferential& r = p.ray[k];
    const Vec3 q = r.o + r.d * hit.t;
    group = 0;
    if (hit.kind == HitKind::Sphere) {
        const SphereEmitter& s = w.lights->sphere(hit.prim);
        group = s.group;
        if (dot(q - s.center, r.d) >= 0.0f) return Vec3(0.0f);  // seen from inside
        const float weight = bsdf_hit_weight(strategy, p.prev_delta[k] != 0, p.prev_pdf[k],
                                             w.lights->sphere_pdf(hit.prim, r.o));
        return s.radiance * weight;
    }
    int32_t emitter = -1;
    if (hit.kind == HitKind::Quad)
        emitter = static_cast<int32_t>(w.quad_light_first + hit.prim / 2);
    else if ((*w.instances)[static_cast<std::size_t>(hit.instance)].emitter >= 0)
        emitter = (*w.instances)[static_cast<std::size_t>(hit.instance)].emitter +
                  static_cast<int32_t>(hit.prim);
    if (emitter < 0) return Vec3(0.0f);
    const auto e = static_cast<uint32_t>(emitter);
    group = w.lights->area(e).group;
    const Vec3 le = w.lights->area_emitted(e, -r.d, hit.b1, hit.b2);
    if (max_component(le) <= 0.0f) return Vec3(0.0f);
    const float weight = bsdf_hit_weight(strategy, p.prev_delta[k] != 0, p.prev_pdf[k],
                                         w.lights->area_pdf(e, r.o, q));
    return le * weight;
}

/** Traces the rays of every active path as one stream: ws.stream_path lists them and
 *  ws.stream_hit / stream_found hold what they hit. Each hit is the ray's own, whatever the
 *  stream holds (so a pixel's value does not depend on the tile, pass or crop it was traced
 *  in). */
void trace_active(const RenderJob& job, Workspace& ws, std::size_t n) {
    const PathBatch& p = ws.paths;
    ws.stream_path.clear();
    ws.stream_o.clear();
    ws.stream_d.clear();
    ws.stream_time.clear();
    for (std::size_t k = 0; k < n; ++k) {
        if (!p.active[k]) continue;
        ws.stream_path.push_back(static_cast<uint32_t>(k));
        ws.stream_o.push_back(p.ray[k].o);
        ws.stream_d.push_back(p.ray[k].d);
        ws.stream_time.push_back(p.time[k]);
    }
    const std::size_t traced = ws.stream_path.size();
    ws.stream_hit.resize(traced);
    ws.stream_found.assign(traced, 0);
    if (job.scene->accel)
        job.scene->accel->intersect_stream(ws.stream_o.data(), ws.stream_d.data(), traced,
                                           ws.stream_hit.data(), ws.stream_found.data(),
                                           job.motion ? ws.stream_time.data() : nullptr, nullptr,
                                           job.scene->cut_outs);
}

/** Path k's ray escaped: the constant environment and every light at infinity. A camera ray
 *  sees none of it with a transparent background, and puts it in the background layer when
 *  that is kept apart; a shadow catcher's path that met no other object adds nothing (its
 *  light is the plate's). */
template <class Sink>
void escape(const RenderJob& job, Workspace& ws, Sink& sink, std::size_t k, uint32_t bounce) {
    const RenderScene& w = *job.scene;
    PathBatch& p = ws.paths;
    p.active[k] = 0;
    if ((bounce == 0 && !job.camera_sees_environment) || p.catcher[k] == 1) return;
    const Vec3 esc = w.lights->escaped(p.ray[k].d, p.prev_pdf[k], p.prev_delta[k] != 0,
                                       job.strategy, sink.escape_buffer());
    const Vec3 c = p.throughput[k] * (w.environment + esc);
    if (bounce == 0 && job.background_apart) {
        sink.background(k, c);
        return;
    }
    const float kc = clamp_factor(job, c, bounce);
    p.radiance[k] += c * kc;
    sink.escaped(k, bounce, p.throughput[k], w.environment, w.environment_group, kc);
}

/** The light `hit` emits towards path k (MIS-weighted), added to its radiance and told to the
 *  sink: what meet() adds at any surface and pass_light() at a see-through quad light. */
template <class Sink>
void add_emission(const RenderJob& job, PathBatch& p, Sink& sink, std::size_t k, const Hit& hit,
                  uint32_t bounce) {
    uint32_t group = 0;
    const Vec3 e = emission_at_hit(*job.scene, job.strategy, p, k, hit, group);
    const Vec3 c = p.throughput[k] * e;
    const float kc = clamp_factor(job, c, bounce);
    p.radiance[k] += c * kc;
    sink.emitted(k, bounce, c, kc, group, e);
}

/** Path k's ray hit something: the light it emits towards the path. Returns whether the path
 *  goes on from a surface (lights do not scatter; nor does the last bounce). */
template <class Sink>
bool meet(const RenderJob& job, Workspace& ws, Sink& sink, std::size_t k, const Hit& hit,
          uint32_t bounce) {
    PathBatch& p = ws.paths;
    // A camera ray on a shadow catcher starts a catcher path; one that then meets another
    // object carries that object's reflection from there on.
    const bool on_catcher =
        hit.kind == HitKind::Instance &&
        (*job.scene->instances)[static_cast<std::size_t>(hit.instance)].shadow_catcher != 0;
    if (bounce == 0 && on_catcher) p.catcher[k] = 1;
    if (p.catcher[k] == 1 && bounce > 0 && hit.kind == HitKind::Instance && !on_catcher)
        p.catcher[k] = 2;
    if (bounce == 0) sink.camera_hit(k, p.ray[k], hit.t);
    if (p.catcher[k] != 1) add_emission(job, p, sink, k, hit, bounce);
    if (hit.kind != HitKind::Instance || bounce == job.max_depth) {
        p.active[k] = 0;
        return false;
    }
    return true;
}

/** Whether `hit` is on a quad light that lets every ray through (QuadLight::transparent). */
bool see_through(const RenderScene& w, const Hit& hit) {
    return hit.kind == HitKind::Quad &&
           w.lights->area(w.quad_light_first + hit.prim / 2).transparent;
}

/** Path k's ray met a transparent quad light: the light it picks up there (MIS-weighted, as at
 *  any light; none for a camera ray, which does not see it), before it goes on. */
template <class Sink>
void pass_light(const RenderJob& job, Workspace& ws, Sink& sink, std::size_t k, const Hit& hit,
                uint32_t bounce) {
    PathBatch& p = ws.paths;
    if (bounce == 0 || p.catcher[k] == 1) return;
    add_emission(job, p, sink, k, hit, bounce);
}

/** Starts the fetch of the mesh data of hit h (its triangle's vertices) into the cache. */
void prefetch_vertices(const RenderScene& w, const Workspace& ws, std::size_t h) {
    const Hit& hit = ws.hits[h].hit;
    const TriangleMesh& m =
        w.geometry->mesh((*w.instances)[static_cast<std::size_t>(hit.instance)].mesh);
    const uint32_t* tri = &m.indices[3 * static_cast<std::size_t>(hit.prim)];
    for (int c = 0; c < 3; ++c) {
        const std::size_t v = tri[c];
        __builtin_prefetch(&m.positions[3 * v]);
        if (!m.normals.empty()) __builtin_prefetch(&m.normals[3 * v]);
        if (!m.uvs.empty()) __builtin_prefetch(&m.uvs[2 * v]);
    }
}

/** Turns every hit into its surface point, footprint and material, counting the paths of each
 *  material into ws.group_start[m + 1]. It is memory latency, not arithmetic, that dominates
 *  turning a hit into a surface point: the mesh data of hits a few paths ahead is fetched while
 *  the current one is worked on. */
template <class Sink>
void resolve_surfaces(const RenderJob& job, Workspace& ws, Sink& sink, uint32_t bounce) {
    const RenderScene& w = *job.scene;
    PathBatch& p = ws.paths;
    const std::size_t hit_count = ws.hits.size();
    constexpr std::size_t kAhead = 4;
    for (std::size_t h = 0; h < std::min(kAhead, hit_count); ++h) prefetch_vertices(w, ws, h);
    for (std::size_t h = 0; h < hit_count; ++h) {
        if (h + 2 * kAhead < hit_count) {
            const Hit& far = ws.hits[h + 2 * kAhead].hit;
            const TriangleMesh& m =
                w.geometry->mesh((*w.instances)[static_cast<std::size_t>(far.instance)].mesh);
            __builtin_prefetch(&m.indices[3 * static_cast<std::size_t>(far.prim)]);
        }
        if (h + kAhead < hit_count) prefetch_vertices(w, ws, h + kAhead);
        const uint32_t k = ws.hits[h].path;
        const Hit& hit = ws.hits[h].hit;
        const Instance& placed = (*w.instances)[static_cast<std::size_t>(hit.instance)];
        // A moving instance is where it was at the path's time.
        Instance moved;
        if (!placed.motion.empty()) moved = instance_at(placed, p.time[k]);
        const Instance& inst = placed.motion.empty() ? placed : moved;
        const TriangleMesh& mesh = w.geometry->mesh(inst.mesh);
        p.surf[k] = surface_at(mesh, inst, hit, p.ray[k].o, p.ray[k].d);
        if (bounce == 0)
            sink.first_surface(k, p.surf[k].p_obj, inst.object, inst.material,
                               inst.shadow_catcher != 0);
        if (job.footprints) {
            bool has_diff = p.has_diff[k] != 0;
            footprint_at(p.surf[k], p.ray[k], has_diff, p.fp_width[k] + p.fp_spread[k] * hit.t);
            object_footprint(p.surf[k], inst, mesh, hit.prim);
            p.has_diff[k] = has_diff ? 1 : 0;
        } else {
            p.has_diff[k] = 0;  // nothing reads footprints: none is computed or carried
        }
        p.material[k] = inst.material;
        ++ws.group_start[inst.material + 1];
    }
}

/** Counting sort of the paths still active by material into ws.order: material m's paths are
 *  ws.order[group_start[m], group_start[m + 1]). */
void sort_by_material(Workspace& ws, std::size_t n, std::size_t material_count) {
    std::vector<uint32_t>& start = ws.group_start;
    for (std::size_t m = 0; m < material_count; ++m) start[m + 1] += start[m];
    ws.order.resize(start[material_count]);
    std::vector<uint32_t> cursor(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < n; ++k)
        if (ws.paths.active[k]) ws.order[cursor[ws.paths.material[k]]++] = static_cast<uint32_t>(k);
}

}  // namespace

template <class Sink>
void intersect(RenderJob& job, Workspace& ws, Sink& sink, std::size_t n, uint32_t bounce,
               uint64_t& rays) {
    const std::size_t material_count = job.scene->materials->size();
    ws.group_start.assign(material_count + 1, 0u);
    ws.hits.clear();
    trace_active(job, ws, n);
    // Rays that met a transparent quad light go on past it (from the same origin, beyond the
    // light): up to kThrough lights in a row.
    constexpr int kThrough = 8;
    thread_local std::vector<uint32_t> again, next;
    thread_local std::vector<float> again_t, next_t;
    again.clear();
    again_t.clear();
    const auto take = [&](std::size_t k, bool found, const Hit& hit, int depth) {
        ++rays;
        if (!found)
            escape(job, ws, sink, k, bounce);
        else if (see_through(*job.scene, hit) && depth < kThrough) {
            pass_light(job, ws, sink, k, hit, bounce);
            next.push_back(static_cast<uint32_t>(k));
            next_t.push_back(hit.t);
        } else if (meet(job, ws, sink, k, hit, bounce))
            ws.hits.push_back({static_cast<uint32_t>(k), hit});
    };
    next.clear();
    next_t.clear();
    for (std::size_t j = 0; j < ws.stream_path.size(); ++j)
        take(ws.stream_path[j], ws.stream_found[j] != 0, ws.stream_hit[j], 0);
    for (int depth = 1; !next.empty(); ++depth) {
        again.swap(next);
        again_t.swap(next_t);
        next.clear();
        next_t.clear();
        const PathBatch& p = ws.paths;
        const std::size_t m = again.size();
        ws.stream_o.resize(m);
        ws.stream_d.resize(m);
        ws.stream_time.resize(m);
        ws.stream_hit.resize(m);
        ws.stream_found.assign(m, 0);
        thread_local std::vector<float> tnear;
        tnear.resize(m);
        for (std::size_t i = 0; i < m; ++i) {
            ws.stream_o[i] = p.ray[again[i]].o;
            ws.stream_d[i] = p.ray[again[i]].d;
            ws.stream_time[i] = p.time[again[i]];
            tnear[i] = again_t[i] * (1.0f + 1e-5f) + 1e-6f;
        }
        job.scene->accel->intersect_stream(
            ws.stream_o.data(), ws.stream_d.data(), m, ws.stream_hit.data(), ws.stream_found.data(),
            job.motion ? ws.stream_time.data() : nullptr, tnear.data(), job.scene->cut_outs);
        for (std::size_t i = 0; i < m; ++i)
            take(again[i], ws.stream_found[i] != 0, ws.stream_hit[i], depth);
    }
    resolve_surfaces(job, ws, sink, bounce);
    sort_by_material(ws, n, material_count);
}

template void intersect<NullSink>(RenderJob&, Workspace&, NullSink&, std::size_t, uint32_t,
                                  uint64_t&);
template void intersect<LayerSink>(RenderJob&, Workspace&, LayerSink&, std::size_t, uint32_t,
                                   uint64_t&);

}  // namespace spangle
