#include "accel/embree_scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>

#include "core/error.h"
#include "core/hash.h"

namespace spangle {

namespace {

void on_embree_error(void* user, RTCError code, const char* message) {
    auto* error = static_cast<std::string*>(user);
    *error = fmt::format("Embree error {}: {}", static_cast<int>(code), message ? message : "");
}

/** Adds a triangle geometry with copies of the given vertices and indices to scene. */
RTCGeometry add_triangles(RTCDevice device, RTCScene scene, const float* xyz, std::size_t vertices,
                          const uint32_t* indices, std::size_t triangles) {
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    // Embree may read 16 bytes at the last vertex; the buffer it allocates is padded for that.
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
        g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices));
    auto* i = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
        g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), triangles));
    if (v && i) {
        std::memcpy(v, xyz, vertices * 3 * sizeof(float));
        std::memcpy(i, indices, triangles * 3 * sizeof(uint32_t));
    }
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    return g;
}

/** The ray o + t d, t in (0, tmax), for Embree. Returns false for a non-finite ray (a
 *  numerical failure upstream), which is then left inactive (tfar < tnear) with finite values
 *  in place of its own: Embree must never see NaN or infinity. */
bool make_ray(Vec3 o, Vec3 d, float tmax, float time, RTCRay& r) {
    const bool finite = is_finite(o) && is_finite(d) && !std::isnan(tmax);
    r.org_x = finite ? o.x : 0.0f;
    r.org_y = finite ? o.y : 0.0f;
    r.org_z = finite ? o.z : 0.0f;
    r.dir_x = finite ? d.x : 0.0f;
    r.dir_y = finite ? d.y : 0.0f;
    r.dir_z = finite ? d.z : 1.0f;
    r.tnear = 0.0f;
    r.tfar = finite ? tmax : -1.0f;
    r.mask = 0xffffffffu;
    r.time = std::isfinite(time) ? std::clamp(time, 0.0f, 1.0f) : 0.0f;
    r.flags = 0;
    r.id = 0;
    return finite;
}

/** Gives r the identity the cut-outs' chance reads (cut_filter): a hash of its world-space
 *  origin and direction. Only queries that carry cut-outs pay for it. */
void identify(RTCRay& r) {
    const auto bits = [](float f) {
        uint32_t b;
        std::memcpy(&b, &f, sizeof b);
        return static_cast<uint64_t>(b);
    };
    r.id = static_cast<unsigned>(hash4(bits(r.org_x) | bits(r.org_y) << 32,
                                       bits(r.org_z) | bits(r.dir_x) << 32,
                                       bits(r.dir_y) | bits(r.dir_z) << 32, 0x637574u) >>
                                 32);
}

/** make_ray with an empty hit record. */
bool make_ray_hit(Vec3 o, Vec3 d, float tmax, float time, RTCRayHit& rh) {
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return make_ray(o, d, tmax, time, rh.ray);
}

/** An intersection context that carries the cut-outs to its filter. */
struct CutContext {
    RTCIntersectContext ctx;  ///< first: Embree hands the filter a pointer to it
    const CutOut* table = nullptr;
    std::size_t count = 0;
};

/** The context filter: drops the candidate hits a cut-out lets through. */
void cut_filter(const RTCFilterFunctionNArguments* args) {
    const auto* c = reinterpret_cast<const CutContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const unsigned inst = RTCHitN_instID(args->hit, args->N, i, 0);
        if (inst >= c->count) continue;  // a light's shape (no instance)
        const CutOut& cut = c->table[inst];
        if (!cut.coverage) continue;
        const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
        const float share = met_share(cut, prim, RTCHitN_u(args->hit, args->N, i),
                                      RTCHitN_v(args->hit, args->N, i));
        bool keep = share >= 1.0f;
        if (share > 0.0f && share < 1.0f) {
            // By chance, per ray and triangle: two half-covering layers on one ray let a
            // quarter through (one number per ray, as pbrt draws it, would let both or neither).
            // The ray is known by the hash of its world-space origin and direction that
            // identify() left in its id: Embree hands the filter the ray in the instance's
            // space, whose last bits depend on the CPU's kernels.
            const uint64_t ray = RTCRayN_id(args->ray, args->N, i);
            keep = to_unit_float(hash2(ray, static_cast<uint64_t>(inst) << 32 | prim)) < share;
        }
        if (!keep) args->valid[i] = 0;
    }
}

/** A context for one query: the cut-outs' filter when any instance has one. */
void init_context(CutContext& c, const CutOuts* cut_outs, bool incoherent) {
    rtcInitIntersectContext(&c.ctx);
    if (incoherent) c.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;  // see the header
    if (!cut_outs || cut_outs->empty()) return;
    c.table = cut_outs->data();
    c.count = cut_outs->size();
    c.ctx.filter = cut_filter;
}

/** A new scene that takes the intersection context's filter (the cut-outs'). */
RTCScene new_scene(RTCDevice device) {
    RTCScene s = rtcNewScene(device);
    rtcSetSceneFlags(s, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    return s;
}

/** Embree's 3x4 row-major matrix of an affine transform. */
void to_embree(const Affine& a, float (&xfm)[12]) {
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) xfm[4 * r + c] = a.m[r][c];
        xfm[4 * r + 3] = a.t[r];
    }
}

}  // namespace

void motion_step(std::size_t steps, float time, std::size_t& first, float& s) {
    const auto segments = static_cast<float>(steps - 1);
    const float f = std::clamp(std::isfinite(time) ? time : 0.0f, 0.0f, 1.0f) * segments;
    const float i = std::min(std::floor(f), segments - 1.0f);
    first = static_cast<std::size_t>(i);
    s = f - i;
}

Instance instance_at(const Instance& inst, float time) {
    if (inst.motion.size() < 2) return inst;
    std::size_t i = 0;
    float s = 0.0f;
    motion_step(inst.motion.size(), time, i, s);
    const Affine& a = inst.motion[i];
    const Affine& b = inst.motion[i + 1];
    Instance out;  // without the steps: this runs at every hit on a moving object
    out.mesh = inst.mesh;
    out.material = inst.material;
    out.emitter = inst.emitter;
    out.object = inst.object;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) out.to_world.m[r][c] = (1.0f - s) * a.m[r][c] + s * b.m[r][c];
    }
    out.to_world.t = a.t * (1.0f - s) + b.t * s;
    out.normal_to_world = out.to_world.normal_matrix();
    out.to_object = out.to_world.inverse();
    return out;
}

EmbreeScene::EmbreeScene() {
    device_ = rtcNewDevice(nullptr);
    if (!device_)
        throw_error("cannot create an Embree device (error {})",
                    static_cast<int>(rtcGetDeviceError(nullptr)));
    rtcSetDeviceErrorFunction(device_, on_embree_error, &error_);
    rtcSetDeviceMemoryMonitorFunction(
        device_,
        [](void* user, ssize_t bytes, bool) {
            auto* self = static_cast<EmbreeScene*>(user);
            const std::ptrdiff_t now = self->bytes_ += bytes;
            std::ptrdiff_t peak = self->peak_bytes_.load();
            while (now > peak && !self->peak_bytes_.compare_exchange_weak(peak, now)) {
            }
            return true;
        },
        this);
}

EmbreeScene::~EmbreeScene() {
    if (top_) rtcReleaseScene(top_);
    for (RTCScene s : baked_)
        if (s) rtcReleaseScene(s);
    for (auto& [mesh, entry] : by_mesh_) rtcReleaseScene(entry.second);
    if (device_) rtcReleaseDevice(device_);
}

void EmbreeScene::check(const char* what) const {
    if (!error_.empty()) throw_error("{} failed: {}", what, error_);
}

namespace {

/** Progress of one build() over its BLAS (by triangles) and the top level (one more share the
 *  size of the instances), fed by Embree's progress monitor, which may call from several of its
 *  threads at once. */
struct BuildProgress {
    const WorkProgress* report = nullptr;
    std::string what;
    double total = 0.0;  ///< triangles to build, plus one per instance for the top level
    double done = 0.0;   ///< of total, in structures finished
    double part = 0.0;   ///< the structure being built now, of total
    double shown = -1.0;
    std::mutex mutex;

    /** The structure now being built is `fraction` done. */
    void at(double fraction) {
        std::lock_guard<std::mutex> lock(mutex);
        const double f = total > 0.0 ? std::min(1.0, (done + part * fraction) / total) : 1.0;
        if (f < shown + 0.001 && f < 1.0) return;  // only forward, not on every call
        shown = f;
        (*report)(what, f);
    }
    static bool monitor(void* self, double fraction) {
        static_cast<BuildProgress*>(self)->at(std::clamp(fraction, 0.0, 1.0));
        return true;  // never cancels
    }
    /** Starts a structure of `size` (triangles or instances) in `scene`. */
    void begin(RTCScene scene, double size) {
        done += part;
        part = size;
        if (report && *report) rtcSetSceneProgressMonitorFunction(scene, monitor, this);
    }
};

/** Embree carries a ray into an instance's space through the float inverse of its placement,
 *  whose determinant is a difference of products of the entries. Where the axes are nearly
 *  parallel (a rotated object flattened to 1e-5 of its size: the determinant 3e-5 of the
 *  products) that inverse is off by percents: a flattened cube showed its hidden edges as dark
 *  seams, at 1e-6 it was noise, and nearer still Embree aborted on a ray that was not finite.
 *  Below this share (Affine::determinant_share) a still instance's mesh is placed in world
 *  space in double and traced without a transform: the same triangles, barycentrics and
 *  distances, so shading (which places the hit itself) is unchanged. */
constexpr double kBakeBelow = 1e-3;

/** Whether an instance is traced through a mesh placed in world space (see kBakeBelow). */
bool bake(const Instance& inst) {
    return inst.motion.size() < 2 && !inst.hidden && inst.to_world.determinant_share() < kBakeBelow;
}

/** A BLAS of `mesh` with its vertices placed by `xf` in double. */
RTCScene baked_blas(RTCDevice device, const TriangleMesh& mesh, const Affine& xf) {
    std::vector<float> xyz(mesh.positions.size());
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
        const double p[3] = {mesh.positions[3 * v], mesh.positions[3 * v + 1],
                             mesh.positions[3 * v + 2]};
        for (int r = 0; r < 3; ++r)
            xyz[3 * v + static_cast<std::size_t>(r)] = static_cast<float>(
                static_cast<double>(xf.m[r][0]) * p[0] + static_cast<double>(xf.m[r][1]) * p[1] +
                static_cast<double>(xf.m[r][2]) * p[2] + static_cast<double>(xf.t[r]));
    }
    RTCScene s = new_scene(device);
    RTCGeometry g = add_triangles(device, s, xyz.data(), mesh.vertex_count(), mesh.indices.data(),
                                  mesh.triangle_count());
    rtcReleaseGeometry(g);
    return s;
}

/** The top level, not yet committed: an instance per object (ids in order), then the quad lights'
 *  triangles and the sphere lights (their geometry ids returned, or RTC_INVALID_GEOMETRY_ID).
 *  An instance with a baked BLAS (non-null in `baked`) is that BLAS, untransformed. */
RTCScene make_top_level(RTCDevice device, const std::vector<RTCScene>& blas,
                        const std::vector<RTCScene>& baked, const std::vector<Instance>& instances,
                        const std::vector<Vec3>& quad_vertices, const std::vector<float>& spheres,
                        uint32_t& quad_geom, uint32_t& sphere_geom) {
    quad_geom = sphere_geom = RTC_INVALID_GEOMETRY_ID;
    RTCScene top = new_scene(device);
    for (std::size_t i = 0; i < instances.size(); ++i) {
        const Instance& inst = instances[i];
        RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, baked[i] ? baked[i] : blas[inst.mesh]);
        float xfm[12];
        if (baked[i]) {
            to_embree(Affine{}, xfm);
            rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, xfm);
        } else if (inst.motion.size() >= 2) {
            // A moving instance: one transform per time step (Embree blends them by ray time).
            rtcSetGeometryTimeStepCount(g, static_cast<unsigned>(inst.motion.size()));
            for (std::size_t k = 0; k < inst.motion.size(); ++k) {
                to_embree(inst.motion[k], xfm);
                rtcSetGeometryTransform(g, static_cast<unsigned>(k), RTC_FORMAT_FLOAT3X4_ROW_MAJOR,
                                        xfm);
            }
        } else {
            to_embree(inst.to_world, xfm);
            rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, xfm);
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(top, g);  // ids are attachment order: instance i has id i
        if (inst.hidden) rtcDisableGeometry(g);
        rtcReleaseGeometry(g);
    }
    if (!quad_vertices.empty()) {
        std::vector<float> xyz;
        std::vector<uint32_t> idx;
        for (std::size_t q = 0; q < quad_vertices.size() / 4; ++q) {
            for (int k = 0; k < 4; ++k) {
                const Vec3 p = quad_vertices[4 * q + static_cast<std::size_t>(k)];
                xyz.insert(xyz.end(), {p.x, p.y, p.z});
            }
            const auto b = static_cast<uint32_t>(4 * q);
            idx.insert(idx.end(), {b, b + 1, b + 2, b, b + 2, b + 3});
        }
        quad_geom = static_cast<uint32_t>(instances.size());
        RTCGeometry g =
            add_triangles(device, top, xyz.data(), xyz.size() / 3, idx.data(), idx.size() / 3);
        rtcReleaseGeometry(g);
    }
    if (!spheres.empty()) {
        const std::size_t n = spheres.size() / 4;
        RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
        auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
            g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), n));
        if (v) std::memcpy(v, spheres.data(), spheres.size() * sizeof(float));
        rtcCommitGeometry(g);
        sphere_geom = rtcAttachGeometry(top, g);
        rtcReleaseGeometry(g);
    }
    return top;
}

}  // namespace

void EmbreeScene::build(const GeometryStore& geometry, const std::vector<Instance>& instances,
                        const std::vector<Vec3>& quad_vertices, const std::vector<float>& spheres,
                        const WorkProgress& progress,
                        const std::vector<uint8_t>& quad_see_through) {
    BuildProgress meter;
    meter.report = &progress;
    {
        std::size_t new_meshes = 0;
        for (const auto& ptr : geometry.meshes)
            if (!by_mesh_.count(ptr.get())) {
                meter.total += static_cast<double>(ptr->triangle_count());
                ++new_meshes;
            }
        meter.total += static_cast<double>(instances.size() + quad_vertices.size() / 4 + 1);
        meter.what = fmt::format("building BVHs ({} mesh{}, {} instance{})", new_meshes,
                                 new_meshes == 1 ? "" : "es", instances.size(),
                                 instances.size() == 1 ? "" : "s");
    }
    built_ = reused_ = 0;
    decltype(by_mesh_) next;
    blas_.clear();
    for (const auto& ptr : geometry.meshes) {
        if (auto it = next.find(ptr.get()); it != next.end()) {
            blas_.push_back(it->second.second);
            continue;
        }
        if (auto it = by_mesh_.find(ptr.get()); it != by_mesh_.end()) {
            next.emplace(ptr.get(), it->second);
            blas_.push_back(it->second.second);
            by_mesh_.erase(it);
            ++reused_;
            continue;
        }
        const TriangleMesh& mesh = *ptr;
        RTCScene s = new_scene(device_);
        next.emplace(ptr.get(), std::make_pair(ptr, s));
        blas_.push_back(s);
        ++built_;
        RTCGeometry g = add_triangles(device_, s, mesh.positions.data(), mesh.vertex_count(),
                                      mesh.indices.data(), mesh.triangle_count());
        rtcReleaseGeometry(g);
        meter.begin(s, static_cast<double>(mesh.triangle_count()));
        rtcCommitScene(s);
        check("building a mesh's acceleration structure");
    }
    for (auto& [mesh, entry] : by_mesh_) rtcReleaseScene(entry.second);
    by_mesh_ = std::move(next);
    if (top_) rtcReleaseScene(top_);
    top_ = nullptr;
    for (RTCScene s : baked_)
        if (s) rtcReleaseScene(s);
    baked_.assign(instances.size(), nullptr);
    for (std::size_t i = 0; i < instances.size(); ++i) {
        if (!bake(instances[i]) || instances[i].mesh >= geometry.meshes.size()) continue;
        const TriangleMesh& mesh = *geometry.meshes[instances[i].mesh];
        baked_[i] = baked_blas(device_, mesh, instances[i].to_world);
        meter.total += static_cast<double>(mesh.triangle_count());
        meter.begin(baked_[i], static_cast<double>(mesh.triangle_count()));
        rtcCommitScene(baked_[i]);
        check("building a flattened object's acceleration structure");
    }
    top_ = make_top_level(device_, blas_, baked_, instances, quad_vertices, spheres, quad_geom_,
                          sphere_geom_);
    quad_see_through_ = quad_see_through;
    if (quad_geom_ != RTC_INVALID_GEOMETRY_ID &&
        std::find(quad_see_through_.begin(), quad_see_through_.end(), 1) !=
            quad_see_through_.end()) {
        // Transparent quad lights: shadow rays ignore their triangles (intersection rays still
        // meet them, and the path tracer goes on through them).
        RTCGeometry g = rtcGetGeometry(top_, quad_geom_);
        rtcSetGeometryUserData(g, quad_see_through_.data());
        rtcSetGeometryOccludedFilterFunction(g, [](const RTCFilterFunctionNArguments* args) {
            const auto* through = static_cast<const uint8_t*>(args->geometryUserPtr);
            for (unsigned i = 0; i < args->N; ++i) {
                if (args->valid[i] != -1) continue;
                const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
                if (through[prim / 2]) args->valid[i] = 0;
            }
        });
        rtcCommitGeometry(g);
    }
    meter.begin(top_, static_cast<double>(instances.size() + quad_vertices.size() / 4 + 1));
    rtcCommitScene(top_);
    check("building the scene's acceleration structure");
    offset_scale_ = 1.0f;
    RTCBounds b;
    rtcGetSceneBounds(top_, &b);
    if (b.upper_x >= b.lower_x) {
        const float m =
            std::max({std::fabs(b.lower_x), std::fabs(b.lower_y), std::fabs(b.lower_z),
                      std::fabs(b.upper_x), std::fabs(b.upper_y), std::fabs(b.upper_z)});
        if (std::isfinite(m) && m > 0.0f) offset_scale_ = std::min(1.0f, m);
    }
    if (progress) meter.at(1.0);
}

void EmbreeScene::bounding_sphere(Vec3& center, float& radius) const {
    center = Vec3(0.0f);
    radius = 0.0f;
    if (!top_) return;
    RTCBounds b;
    rtcGetSceneBounds(top_, &b);
    if (!(b.upper_x >= b.lower_x)) return;  // empty scene
    const Vec3 lo(b.lower_x, b.lower_y, b.lower_z), hi(b.upper_x, b.upper_y, b.upper_z);
    center = (lo + hi) * 0.5f;
    radius = 0.5f * length(hi - lo);
}

bool EmbreeScene::intersect(Vec3 o, Vec3 d, float tmax, Hit& hit, float time,
                            const CutOuts* cut_outs) const {
    RTCRayHit rh{};
    if (!make_ray_hit(o, d, tmax, time, rh)) return false;  // a non-finite ray misses
    CutContext c;
    init_context(c, cut_outs, false);
    if (c.table) identify(rh.ray);
    rtcIntersect1(top_, &c.ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    resolve(rh, hit);
    return true;
}

void EmbreeScene::intersect_stream(const Vec3* o, const Vec3* d, std::size_t n, Hit* hits,
                                   uint8_t* found, const float* time, const float* tnear,
                                   const CutOuts* cut_outs) const {
    thread_local std::vector<RTCRayHit> rays;
    rays.resize(n);
    for (std::size_t i = 0; i < n; ++i) {  // a non-finite ray misses
        make_ray_hit(o[i], d[i], 1e30f, time ? time[i] : 0.0f, rays[i]);
        if (tnear && std::isfinite(tnear[i])) rays[i].ray.tnear = std::max(0.0f, tnear[i]);
    }
    CutContext c;
    init_context(c, cut_outs, true);  // ray by ray: see the header
    if (c.table)
        for (std::size_t i = 0; i < n; ++i) identify(rays[i].ray);
    if (n > 0)
        rtcIntersect1M(top_, &c.ctx, rays.data(), static_cast<unsigned>(n), sizeof(RTCRayHit));
    for (std::size_t i = 0; i < n; ++i) {
        found[i] = rays[i].hit.geomID != RTC_INVALID_GEOMETRY_ID ? 1 : 0;
        if (found[i]) resolve(rays[i], hits[i]);
    }
}

void EmbreeScene::occluded_stream(const Vec3* o, const Vec3* d, const float* tmax, std::size_t n,
                                  uint8_t* blocked, const float* time,
                                  const CutOuts* cut_outs) const {
    thread_local std::vector<RTCRay> rays;
    rays.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        // A non-finite ray lets no light through: marked blocked here, inactive in Embree.
        if (!make_ray(o[i], d[i], tmax[i], time ? time[i] : 0.0f, rays[i]))
            rays[i].tfar = -std::numeric_limits<float>::infinity();
    }
    CutContext c;
    init_context(c, cut_outs, true);
    if (c.table)
        for (std::size_t i = 0; i < n; ++i) identify(rays[i]);
    if (n > 0) rtcOccluded1M(top_, &c.ctx, rays.data(), static_cast<unsigned>(n), sizeof(RTCRay));
    for (std::size_t i = 0; i < n; ++i)
        blocked[i] = rays[i].tfar == -std::numeric_limits<float>::infinity() ? 1 : 0;
}

void EmbreeScene::resolve(const RTCRayHit& rh, Hit& hit) const {
    hit.t = rh.ray.tfar;
    hit.b1 = rh.hit.u;
    hit.b2 = rh.hit.v;
    hit.prim = rh.hit.primID;
    if (rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID) {
        hit.instance = static_cast<int32_t>(rh.hit.instID[0]);
        hit.kind = HitKind::Instance;
    } else {
        hit.instance = -1;
        hit.kind = rh.hit.geomID == sphere_geom_ ? HitKind::Sphere : HitKind::Quad;
    }
}

bool EmbreeScene::occluded(Vec3 o, Vec3 d, float tmax, float time, const CutOuts* cut_outs) const {
    RTCRay r{};
    if (!make_ray(o, d, tmax, time, r)) return true;  // a non-finite ray lets no light through
    CutContext c;
    init_context(c, cut_outs, false);
    if (c.table) identify(r);
    rtcOccluded1(top_, &c.ctx, &r);
    return r.tfar == -std::numeric_limits<float>::infinity();
}

}  // namespace spangle
