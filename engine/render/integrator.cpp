#include "render/integrator.h"

#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>

#include "core/hash.h"
#include "render/arena.h"

namespace spangle {

namespace {

constexpr uint32_t kTileSize = 16;
constexpr uint32_t kSamplesPerWave = 16;  ///< samples of each tile pixel traced together
constexpr uint32_t kRouletteDepth = 3;    ///< bounces before Russian roulette starts

/** Random-number dimensions: 2 for the pixel, then kDimsPerBounce per bounce. */
enum Dim : uint32_t {
    kDimPixelX = 0,
    kDimPixelY = 1,
    kDimBounceBase = 2,
    kDimLightSelect = 0,
    kDimLightU = 1,
    kDimLightV = 2,
    kDimBsdf0 = 3,
    kDimBsdf1 = 4,
    kDimBsdf2 = 5,
    kDimRoulette = 6,
    kDimsPerBounce = 8
};

/** Offsets a ray origin off a surface along the geometric normal by a few float ulps, scaled to
 *  the coordinates' magnitude (Waechter and Binder, "A Fast and Robust Method for Avoiding
 *  Self-Intersection", Ray Tracing Gems, 2019). n must face the side the ray leaves towards. */
Vec3 offset_origin(Vec3 p, Vec3 n) {
    constexpr float kOrigin = 1.0f / 32.0f, kFloatScale = 1.0f / 65536.0f, kIntScale = 256.0f;
    float out[3];
    const float pc[3] = {p.x, p.y, p.z}, nc[3] = {n.x, n.y, n.z};
    for (int i = 0; i < 3; ++i) {
        const auto of = static_cast<int32_t>(kIntScale * nc[i]);
        int32_t bits;
        std::memcpy(&bits, &pc[i], sizeof(bits));
        bits += pc[i] < 0.0f ? -of : of;
        float moved;
        std::memcpy(&moved, &bits, sizeof(moved));
        out[i] = std::fabs(pc[i]) < kOrigin ? pc[i] + kFloatScale * nc[i] : moved;
    }
    return {out[0], out[1], out[2]};
}

float power_heuristic(float a, float b) {
    const float a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

/** The pinhole camera's frame. */
struct CameraFrame {
    Vec3 origin, forward, right, up;  ///< right and up scaled by the half-extent of the image plane
};

CameraFrame make_camera(const Camera& c, uint32_t width, uint32_t height) {
    CameraFrame f;
    f.origin = c.position;
    f.forward = normalize(c.look_at - c.position);
    const Vec3 right = normalize(cross(f.forward, c.up));
    const Vec3 up = cross(right, f.forward);
    const float tan_half = std::tan(0.5f * c.fov_deg * kPi / 180.0f);
    const float aspect = static_cast<float>(width) / static_cast<float>(height);
    f.right = right * (tan_half * aspect);
    f.up = up * tan_half;
    return f;
}

/** Everything known about a surface hit that shading needs. */
struct SurfacePoint {
    Vec3 p, ng, n, s, t;  ///< position; geometric normal, shading frame (n, s, t) facing wo
    float u = 0, v = 0;   ///< surface parameterisation
    float uv_area = 0;    ///< |dp/du x dp/dv|
    bool backface = false;
};

/** Resolves a hit on instance inst to a surface point oriented towards -d. */
SurfacePoint surface_at(const World& w, const Instance& inst, const Hit& h, Vec3 d) {
    const TriangleMesh& mesh = w.geometry.meshes[inst.mesh];
    const uint32_t i0 = mesh.indices[3 * h.prim], i1 = mesh.indices[3 * h.prim + 1],
                   i2 = mesh.indices[3 * h.prim + 2];
    const float b0 = 1.0f - h.b1 - h.b2;
    const Vec3 p0 = inst.to_world.apply_point(mesh.position(i0));
    const Vec3 p1 = inst.to_world.apply_point(mesh.position(i1));
    const Vec3 p2 = inst.to_world.apply_point(mesh.position(i2));
    SurfacePoint sp;
    sp.p = p0 * b0 + p1 * h.b1 + p2 * h.b2;
    const Vec3 e1 = p1 - p0, e2 = p2 - p0;
    Vec3 ng = cross(e1, e2);
    const float ng_len = length(ng);
    ng = ng_len > 0.0f ? ng / ng_len : Vec3(0, 0, 1);
    Vec3 n = ng;
    if (!mesh.normals.empty()) {
        const auto nrm = [&](uint32_t i) {
            return Vec3(mesh.normals[3 * i], mesh.normals[3 * i + 1], mesh.normals[3 * i + 2]);
        };
        const Vec3 ni =
            inst.normal_to_world.apply_vector(nrm(i0) * b0 + nrm(i1) * h.b1 + nrm(i2) * h.b2);
        const float len = length(ni);
        if (len > 0.0f && std::isfinite(len)) n = ni / len;
        if (dot(n, ng) < 0.0f) ng = -ng;  // the geometric normal follows the authored normals
    }
    float uv0[2] = {0, 0}, uv1[2] = {1, 0}, uv2[2] = {0, 1};
    if (!mesh.uvs.empty()) {
        for (int k = 0; k < 2; ++k) {
            uv0[k] = mesh.uvs[2 * i0 + static_cast<uint32_t>(k)];
            uv1[k] = mesh.uvs[2 * i1 + static_cast<uint32_t>(k)];
            uv2[k] = mesh.uvs[2 * i2 + static_cast<uint32_t>(k)];
        }
    }
    sp.u = uv0[0] * b0 + uv1[0] * h.b1 + uv2[0] * h.b2;
    sp.v = uv0[1] * b0 + uv1[1] * h.b1 + uv2[1] * h.b2;
    // dp/du from the triangle's uv mapping; degenerate uvs fall back to an arbitrary tangent.
    const float du1 = uv1[0] - uv0[0], dv1 = uv1[1] - uv0[1];
    const float du2 = uv2[0] - uv0[0], dv2 = uv2[1] - uv0[1];
    const float det = du1 * dv2 - dv1 * du2;
    Vec3 dpdu(0.0f);
    if (std::fabs(det) > 1e-20f) {
        const float inv = 1.0f / det;
        dpdu = (e1 * dv2 - e2 * dv1) * inv;
        const Vec3 dpdv = (e2 * du1 - e1 * du2) * inv;
        sp.uv_area = length(cross(dpdu, dpdv));
    }
    const bool back = dot(ng, d) > 0.0f;
    if (back) {
        ng = -ng;
        n = -n;
    }
    Vec3 s = dpdu - n * dot(n, dpdu);
    const float s_len = length(s);
    if (s_len > 1e-12f && std::isfinite(s_len)) {
        s = s / s_len;
        sp.t = cross(n, s);
    } else {
        make_basis(n, s, sp.t);
    }
    sp.ng = ng;
    sp.n = n;
    sp.s = s;
    sp.backface = back;
    return sp;
}

/** Per-thread buffers for one wave of paths; reused across tiles. */
struct Workspace {
    // Paths of the wave.
    std::vector<uint32_t> pixel, sample;
    std::vector<Vec3> org, dir, throughput, radiance;
    std::vector<float> prev_pdf;      ///< solid-angle pdf of the last BSDF sample
    std::vector<uint8_t> prev_delta;  ///< last bounce was a delta lobe
    std::vector<uint8_t> active;
    // Hits of the current bounce.
    std::vector<uint32_t> order;  ///< active hit paths sorted by material
    std::vector<uint32_t> material_of;
    std::vector<SurfacePoint> surf;
    // Plugin batches (SoA) for one material group.
    std::vector<float> px, py, pz, wox, woy, woz, u, v, dudx, dudy, dvdx, dvdy, uv_area;
    std::vector<uint32_t> flags, path_id;
    std::vector<float> f_r, f_g, f_b, pdf, wix, wiy, wiz, u0, u1, u2;
    std::vector<uint32_t> closure_index, sample_flags;
    std::vector<LightSample> light;
    std::vector<uint32_t> light_query;  ///< group slot of each eval query
    std::vector<std::byte> closures;
    ScratchArena arena;

    void resize_paths(std::size_t n) {
        for (auto* a : {&pixel, &sample}) a->resize(n);
        for (auto* a : {&org, &dir, &throughput, &radiance}) a->resize(n);
        prev_pdf.resize(n);
        prev_delta.resize(n);
        active.resize(n);
        material_of.resize(n);
        surf.resize(n);
    }
    void resize_group(std::size_t n) {
        for (auto* a :
             {&px,      &py,  &pz,  &wox, &woy, &woz, &u,   &v,   &dudx, &dudy, &dvdx, &dvdy,
              &uv_area, &f_r, &f_g, &f_b, &pdf, &wix, &wiy, &wiz, &u0,   &u1,   &u2})
            a->resize(n);
        for (auto* a : {&flags, &path_id, &closure_index, &sample_flags, &light_query})
            a->resize(n);
        light.resize(n);
    }
};

/** State shared by all tiles of one render. */
struct RenderJob {
    const World* world;
    CameraFrame cam;
    uint32_t width, height, spp, max_depth;
    uint64_t seed;
    std::vector<float>* image;
    std::atomic<uint64_t> camera_rays{0}, bounce_rays{0}, shadow_rays{0}, samples_done{0};
    std::atomic<uint64_t> nonfinite{0};
    std::atomic<uint64_t> first_bad{~0ull};  ///< (pixel << 24 | sample) of the first bad value
    std::mutex progress_mutex;
};

float rnd(const RenderJob& job, uint32_t pixel, uint32_t sample, uint32_t bounce, uint32_t dim) {
    return sample_1d(job.seed, pixel, sample, kDimBounceBase + bounce * kDimsPerBounce + dim);
}

/** Shades one material group: prepare, next-event estimation, then BSDF sampling. */
void shade_group(RenderJob& job, Workspace& ws, const MaterialInstance& mat, const uint32_t* paths,
                 uint32_t n, uint32_t bounce, uint64_t& shadow_rays) {
    const World& w = *job.world;
    ws.resize_group(n);
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        const SurfacePoint& sp = ws.surf[i];
        const Vec3 wo = -ws.dir[i];
        ws.px[k] = sp.p.x;
        ws.py[k] = sp.p.y;
        ws.pz[k] = sp.p.z;
        ws.wox[k] = dot(wo, sp.s);
        ws.woy[k] = dot(wo, sp.t);
        ws.woz[k] = dot(wo, sp.n);
        ws.u[k] = sp.u;
        ws.v[k] = sp.v;
        ws.dudx[k] = ws.dudy[k] = ws.dvdx[k] = ws.dvdy[k] = 0.0f;  // no ray differentials yet
        ws.uv_area[k] = sp.uv_area;
        ws.flags[k] = sp.backface ? SPANGLE_SHADING_BACKFACE : 0u;
        ws.path_id[k] = i;
    }
    const SpangleShadingBatch_v1 batch{n,
                                       ws.px.data(),
                                       ws.py.data(),
                                       ws.pz.data(),
                                       ws.wox.data(),
                                       ws.woy.data(),
                                       ws.woz.data(),
                                       ws.u.data(),
                                       ws.v.data(),
                                       ws.dudx.data(),
                                       ws.dudy.data(),
                                       ws.dvdx.data(),
                                       ws.dvdy.data(),
                                       ws.uv_area.data(),
                                       ws.flags.data(),
                                       ws.path_id.data()};
    const SpangleMaterialModel_v1& model = mat.model();
    ws.closures.resize(static_cast<std::size_t>(n) * model.closure_size + 16);
    void* closures = ws.closures.data();
    std::size_t space = ws.closures.size();
    closures = std::align(16, static_cast<std::size_t>(n) * model.closure_size, closures, space);
    ws.arena.reset();
    SpangleArena_v1 arena = ws.arena.api();
    model.prepare(mat.instance(), &batch, closures, &arena);

    // Next-event estimation towards the area lights.
    if (!w.lights.empty()) {
        uint32_t q = 0;
        for (uint32_t k = 0; k < n; ++k) {
            const uint32_t i = paths[k];
            const SurfacePoint& sp = ws.surf[i];
            const LightSample ls =
                w.lights.sample(sp.p, rnd(job, ws.pixel[i], ws.sample[i], bounce, kDimLightSelect),
                                rnd(job, ws.pixel[i], ws.sample[i], bounce, kDimLightU),
                                rnd(job, ws.pixel[i], ws.sample[i], bounce, kDimLightV));
            if (!(ls.pdf > 0.0f)) continue;
            ws.light[q] = ls;
            ws.light_query[q] = k;
            ws.closure_index[q] = k;
            ws.wix[q] = dot(ls.wi, sp.s);
            ws.wiy[q] = dot(ls.wi, sp.t);
            ws.wiz[q] = dot(ls.wi, sp.n);
            ++q;
        }
        SpangleEvalBatch_v1 eval{q,
                                 ws.closure_index.data(),
                                 ws.wix.data(),
                                 ws.wiy.data(),
                                 ws.wiz.data(),
                                 ws.f_r.data(),
                                 ws.f_g.data(),
                                 ws.f_b.data(),
                                 ws.pdf.data()};
        if (q > 0) model.eval(mat.instance(), closures, &eval);
        for (uint32_t j = 0; j < q; ++j) {
            const Vec3 f(ws.f_r[j], ws.f_g[j], ws.f_b[j]);
            if (max_component(f) <= 0.0f) continue;
            const uint32_t i = paths[ws.light_query[j]];
            const SurfacePoint& sp = ws.surf[i];
            const LightSample& ls = ws.light[j];
            const float cos_i = std::fabs(ws.wiz[j]);
            // Leave on the side of the geometric normal that wi points to.
            const Vec3 side = dot(ls.wi, sp.ng) >= 0.0f ? sp.ng : -sp.ng;
            const Vec3 o = offset_origin(sp.p, side);
            ++shadow_rays;
            if (w.accel && w.accel->occluded(o, ls.wi, ls.dist * (1.0f - 1e-4f))) continue;
            const float mis = power_heuristic(ls.pdf, ws.pdf[j]);
            ws.radiance[i] += ws.throughput[i] * f * ls.radiance * (cos_i * mis / ls.pdf);
        }
    }

    // Continue each path by sampling the BSDF.
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        ws.u0[k] = rnd(job, ws.pixel[i], ws.sample[i], bounce, kDimBsdf0);
        ws.u1[k] = rnd(job, ws.pixel[i], ws.sample[i], bounce, kDimBsdf1);
        ws.u2[k] = rnd(job, ws.pixel[i], ws.sample[i], bounce, kDimBsdf2);
    }
    SpangleSampleBatch_v1 sb{n,
                             nullptr,
                             ws.u0.data(),
                             ws.u1.data(),
                             ws.u2.data(),
                             ws.wix.data(),
                             ws.wiy.data(),
                             ws.wiz.data(),
                             ws.f_r.data(),
                             ws.f_g.data(),
                             ws.f_b.data(),
                             ws.pdf.data(),
                             ws.sample_flags.data()};
    model.sample(mat.instance(), closures, &sb);
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        const SurfacePoint& sp = ws.surf[i];
        const Vec3 f(ws.f_r[k], ws.f_g[k], ws.f_b[k]);
        const float pdf = ws.pdf[k];
        if (ws.sample_flags[k] == 0 || !(pdf > 0.0f) || max_component(f) <= 0.0f) {
            ws.active[i] = 0;
            continue;
        }
        const Vec3 wi = normalize(sp.s * ws.wix[k] + sp.t * ws.wiy[k] + sp.n * ws.wiz[k]);
        Vec3 t = ws.throughput[i] * f * (std::fabs(ws.wiz[k]) / pdf);
        if (bounce + 1 >= kRouletteDepth) {
            const float survive = std::min(0.95f, max_component(t));
            if (rnd(job, ws.pixel[i], ws.sample[i], bounce, kDimRoulette) >= survive) {
                ws.active[i] = 0;
                continue;
            }
            t *= 1.0f / survive;
        }
        ws.throughput[i] = t;
        const Vec3 side = dot(wi, sp.ng) >= 0.0f ? sp.ng : -sp.ng;
        ws.org[i] = offset_origin(sp.p, side);
        ws.dir[i] = wi;
        ws.prev_pdf[i] = pdf;
        ws.prev_delta[i] = (ws.sample_flags[k] & SPANGLE_SAMPLE_SPECULAR) ? 1 : 0;
    }
}

/** Traces one wave: `count` samples starting at `first_sample` for every pixel of the tile. */
void trace_wave(RenderJob& job, Workspace& ws, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1,
                uint32_t first_sample, uint32_t count) {
    const World& w = *job.world;
    const uint32_t tw = x1 - x0, th = y1 - y0;
    const std::size_t n = static_cast<std::size_t>(tw) * th * count;
    ws.resize_paths(n);
    std::size_t i = 0;
    for (uint32_t y = y0; y < y1; ++y)
        for (uint32_t x = x0; x < x1; ++x)
            for (uint32_t s = 0; s < count; ++s, ++i) {
                const uint32_t pix = y * job.width + x;
                const uint32_t smp = first_sample + s;
                // Box pixel filter: a uniform position inside the pixel.
                const float fx =
                    (static_cast<float>(x) + sample_1d(job.seed, pix, smp, kDimPixelX)) /
                    static_cast<float>(job.width);
                const float fy =
                    (static_cast<float>(y) + sample_1d(job.seed, pix, smp, kDimPixelY)) /
                    static_cast<float>(job.height);
                ws.pixel[i] = pix;
                ws.sample[i] = smp;
                ws.org[i] = job.cam.origin;
                ws.dir[i] = normalize(job.cam.forward + job.cam.right * (2.0f * fx - 1.0f) +
                                      job.cam.up * (1.0f - 2.0f * fy));
                ws.throughput[i] = Vec3(1.0f);
                ws.radiance[i] = Vec3(0.0f);
                ws.prev_pdf[i] = 0.0f;
                ws.prev_delta[i] = 1;  // camera rays see emitters with full weight
                ws.active[i] = 1;
            }
    uint64_t rays = 0, shadow = 0;
    const std::size_t material_count = w.materials.size();
    std::vector<uint32_t> group_start(material_count + 1);
    for (uint32_t bounce = 0; bounce <= job.max_depth; ++bounce) {
        ws.order.clear();
        std::fill(group_start.begin(), group_start.end(), 0u);
        for (std::size_t k = 0; k < n; ++k) {
            if (!ws.active[k]) continue;
            ++rays;
            Hit hit;
            if (!w.accel || !w.accel->intersect(ws.org[k], ws.dir[k], 1e30f, hit)) {
                ws.radiance[k] += ws.throughput[k] * w.environment;
                ws.active[k] = 0;
                continue;
            }
            // Emission seen by this ray, MIS-weighted against next-event estimation.
            int32_t emitter = -1;
            if (hit.instance < 0)
                emitter = static_cast<int32_t>(w.quad_light_first + hit.prim / 2);
            else if (w.instances[static_cast<std::size_t>(hit.instance)].emitter >= 0)
                emitter = w.instances[static_cast<std::size_t>(hit.instance)].emitter +
                          static_cast<int32_t>(hit.prim);
            if (emitter >= 0) {
                const auto e = static_cast<uint32_t>(emitter);
                const Vec3 le = w.lights.emitted(e, -ws.dir[k]);
                if (max_component(le) > 0.0f) {
                    const Vec3 q = ws.org[k] + ws.dir[k] * hit.t;
                    const float weight =
                        ws.prev_delta[k]
                            ? 1.0f
                            : power_heuristic(ws.prev_pdf[k], w.lights.pdf(e, ws.org[k], q));
                    ws.radiance[k] += ws.throughput[k] * le * weight;
                }
            }
            if (hit.instance < 0 || bounce == job.max_depth) {  // quad lights do not scatter
                ws.active[k] = 0;
                continue;
            }
            const Instance& inst = w.instances[static_cast<std::size_t>(hit.instance)];
            ws.surf[k] = surface_at(w, inst, hit, ws.dir[k]);
            ws.material_of[k] = inst.material;
            ++group_start[inst.material + 1];
        }
        // Counting sort of the surviving paths by material.
        for (std::size_t m = 0; m < material_count; ++m) group_start[m + 1] += group_start[m];
        ws.order.resize(group_start[material_count]);
        std::vector<uint32_t> cursor(group_start.begin(), group_start.end() - 1);
        for (std::size_t k = 0; k < n; ++k)
            if (ws.active[k]) ws.order[cursor[ws.material_of[k]]++] = static_cast<uint32_t>(k);
        for (std::size_t m = 0; m < material_count; ++m) {
            const uint32_t count_m = group_start[m + 1] - group_start[m];
            if (count_m == 0) continue;
            shade_group(job, ws, *w.materials[m], ws.order.data() + group_start[m], count_m, bounce,
                        shadow);
        }
    }
    job.camera_rays += n;
    job.bounce_rays += rays - n;
    job.shadow_rays += shadow;

    // Accumulate in a fixed order (pixel-major, then sample): the same sums on any thread count.
    std::vector<float>& img = *job.image;
    for (std::size_t k = 0; k < n; ++k) {
        Vec3 l = ws.radiance[k];
        if (!is_finite(l)) {
            ++job.nonfinite;
            const uint64_t key = (static_cast<uint64_t>(ws.pixel[k]) << 24) | ws.sample[k];
            uint64_t prev = job.first_bad.load();
            while (key < prev && !job.first_bad.compare_exchange_weak(prev, key)) {
            }
            l = Vec3(0.0f);
        }
        float* px = &img[3 * static_cast<std::size_t>(ws.pixel[k])];
        px[0] += l.x;
        px[1] += l.y;
        px[2] += l.z;
    }
}

}  // namespace

void render_image(World& world, const Camera& camera, const Film& film) {
    const auto t0 = std::chrono::steady_clock::now();
    RenderJob job;
    job.world = &world;
    job.width = film.width;
    job.height = film.height;
    job.spp = world.options.spp_override ? world.options.spp_override : film.spp;
    job.max_depth = film.max_depth;
    job.seed = film.seed;
    job.cam = make_camera(camera, film.width, film.height);
    world.width = film.width;
    world.height = film.height;
    world.image.assign(static_cast<std::size_t>(film.width) * film.height * 3, 0.0f);
    job.image = &world.image;

    const uint32_t tiles_x = (film.width + kTileSize - 1) / kTileSize;
    const uint32_t tiles_y = (film.height + kTileSize - 1) / kTileSize;
    const uint64_t total = static_cast<uint64_t>(film.width) * film.height * job.spp;
    tbb::enumerable_thread_specific<Workspace> workspaces;
    const int threads =
        world.options.threads > 0 ? world.options.threads : tbb::this_task_arena::max_concurrency();
    tbb::task_arena arena(threads);
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<uint32_t>(0, tiles_x * tiles_y, 1),
                          [&](const tbb::blocked_range<uint32_t>& r) {
                              Workspace& ws = workspaces.local();
                              for (uint32_t tile = r.begin(); tile != r.end(); ++tile) {
                                  const uint32_t x0 = (tile % tiles_x) * kTileSize,
                                                 y0 = (tile / tiles_x) * kTileSize;
                                  const uint32_t x1 = std::min(x0 + kTileSize, film.width);
                                  const uint32_t y1 = std::min(y0 + kTileSize, film.height);
                                  for (uint32_t s = 0; s < job.spp; s += kSamplesPerWave) {
                                      const uint32_t count = std::min(kSamplesPerWave, job.spp - s);
                                      trace_wave(job, ws, x0, y0, x1, y1, s, count);
                                      const uint64_t done = job.samples_done +=
                                          static_cast<uint64_t>(x1 - x0) * (y1 - y0) * count;
                                      if (world.options.progress) {
                                          std::lock_guard<std::mutex> lock(job.progress_mutex);
                                          world.options.progress(done, total);
                                      }
                                  }
                              }
                          });
    });

    const float inv_spp = 1.0f / static_cast<float>(job.spp);
    for (float& x : world.image) x *= inv_spp;
    RenderStats& st = world.stats;
    st.camera_rays = job.camera_rays;
    st.bounce_rays = job.bounce_rays;
    st.shadow_rays = job.shadow_rays;
    st.samples = total;
    st.nonfinite = job.nonfinite;
    if (st.nonfinite > 0) {
        const uint64_t key = job.first_bad;
        const auto pix = static_cast<uint32_t>(key >> 24);
        st.first_bad_pixel_x = pix % film.width;
        st.first_bad_pixel_y = pix / film.width;
        st.first_bad_sample = static_cast<uint32_t>(key & 0xffffff);
    }
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace spangle
