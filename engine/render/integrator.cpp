#include "render/integrator.h"

#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <mutex>

#include "core/memory.h"
#include "core/sample_sum.h"
#include "render/arena.h"
#include "render/camera.h"
#include "render/sampler.h"
#include "render/surface.h"

namespace spangle {

namespace {

constexpr uint32_t kTileSize = 16;
constexpr uint32_t kSamplesPerWave = 8;  ///< samples of each tile pixel traced together
constexpr uint32_t kMaxBatch = 256;  ///< shading points per plugin call: bounds per-batch scratch

/** Per-path geometry layers of the first hit: coverage, albedo, normal, depth, position, the
 *  position in its object's space and the object's number (from 1; 0 = none). */
enum Aov : uint32_t {
    kAovA = 0,
    kAovAlbedo = 1,
    kAovN = 4,
    kAovZ = 7,
    kAovP = 8,
    kAovPobj = 11,
    kAovObject = 14,
    kAovCount = 15
};

/** Sobol dimension pairs: two for the camera, then kPairsPerBounce per bounce. */
enum Pair : uint32_t {
    kPairFilter = 0,
    kPairLens = 1,
    kPairBounceBase = 2,
    kPairLight = 0,     ///< light position (u1, u2)
    kPairBsdf = 1,      ///< BSDF direction (u0, u1)
    kPairSelect = 2,    ///< light selection, BSDF lobe choice
    kPairRoulette = 3,  ///< Russian roulette, spare
    kPairsPerBounce = 4,
    /** The path's time within the shutter (motion blur; first value). Far beyond the bounce
     *  pairs, so a scene without motion draws exactly the numbers it drew before. */
    kPairTime = 0x40000000u
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

/** Per-thread buffers for one wave of paths; reused across tiles. */
struct Workspace {
    // Paths of the wave.
    std::vector<uint32_t> pixel, sample;
    std::vector<uint64_t> key;  ///< sobol_pixel_key of the path's pixel
    std::vector<float> time;    ///< the path's time in the shutter, 0..1 (0 without motion)
    std::vector<RayDifferential> ray;
    std::vector<uint8_t> has_diff;  ///< the ray's differentials are real (camera or specular)
    std::vector<float> fp_width;    ///< footprint width at the ray origin (no differentials)
    std::vector<float> fp_spread;   ///< footprint growth per unit distance (no differentials)
    std::vector<Vec3> throughput, radiance;
    // Render layers (only with RenderOptions::layers): per path, the part of its throughput that
    // went through a glint at the first surface, its glint radiance, its radiance per light
    // group (groups values per path) and its first-hit geometry (kAovCount values per path).
    std::vector<Vec3> glint_throughput, glint, group_radiance;
    std::vector<float> aov;
    std::vector<Vec3> escaped_by_group;  ///< scratch: one escaped ray's light per group
    std::vector<float> g_r, g_g, g_b;    ///< scratch: the glint part of f per query
    std::vector<uint32_t> shadow_group;  ///< light group of each shadow ray's light
    std::vector<Vec3> shadow_glint;      ///< glint part of each shadow ray's contribution
    std::vector<float> prev_pdf;         ///< solid-angle pdf of the last BSDF sample
    std::vector<uint8_t> prev_delta;     ///< last bounce was a delta lobe (or the camera)
    std::vector<uint8_t> active;
    // Hits of the current bounce.
    struct PathHit {
        uint32_t path;
        Hit hit;
    };
    std::vector<PathHit> hits;          ///< the paths that hit a scattering surface, in path order
    std::vector<uint32_t> stream_path;  ///< the active paths, traced as one stream
    std::vector<Vec3> stream_o, stream_d;
    std::vector<float> stream_time;
    std::vector<Hit> stream_hit;
    std::vector<uint8_t> stream_found;
    std::vector<uint32_t> shadow_path;  ///< next-event queries of a group that need a ray
    std::vector<Vec3> shadow_contrib;   ///< their contributions if unoccluded
    std::vector<float> shadow_tmax;
    std::vector<uint32_t> order;  ///< active hit paths sorted by material
    std::vector<uint32_t> material_of;
    std::vector<SurfacePoint> surf;
    // Plugin batches (SoA) for one material group.
    std::vector<float> px, py, pz, wox, woy, woz, u, v, dudx, dudy, dvdx, dvdy, uv_area;
    std::vector<float> opx, opy, opz, onx, ony, onz, odxx, odxy, odxz, odyx, odyy, odyz;
    std::vector<uint32_t> flags, path_id;
    std::vector<float> f_r, f_g, f_b, pdf, wix, wiy, wiz, u0, u1, u2, eta;
    std::vector<float> u_select;  ///< light selection number of each shading point
    std::vector<uint32_t> closure_index, sample_flags;
    std::vector<LightSample> light;
    std::vector<uint32_t> light_query;  ///< group slot of each eval query
    std::vector<std::byte> closures;
    ScratchArena arena;
    // Textures of one material group: lookups, values per bound parameter, the map's values.
    TextureQuery tex_query;
    std::vector<std::vector<float>> tex_values;
    std::vector<const float*> param_values;  ///< one per schema entry (null: constant)
    std::vector<float> map_value, map_ds, map_dt;
    std::vector<float> gu, gv, gdudx, gdudy, gdvdx, gdvdy;  ///< the group's uvs, for the map

    void resize_paths(std::size_t n) {
        for (auto* a : {&pixel, &sample, &material_of}) a->resize(n);
        key.resize(n);
        ray.resize(n);
        for (auto* a : {&has_diff, &prev_delta, &active}) a->resize(n);
        for (auto* a : {&fp_width, &fp_spread, &prev_pdf, &time}) a->resize(n);
        throughput.resize(n);
        radiance.resize(n);
        surf.resize(n);
    }
    void resize_layers(std::size_t n, uint32_t groups) {
        glint_throughput.assign(n, Vec3(0.0f));
        glint.assign(n, Vec3(0.0f));
        group_radiance.assign(n * groups, Vec3(0.0f));
        aov.assign(n * kAovCount, 0.0f);
        escaped_by_group.assign(groups, Vec3(0.0f));
    }
    void resize_group(std::size_t n) {
        for (auto* a : {&px,   &py,   &pz,   &wox,     &woy, &woz, &u,       &v,   &dudx,
                        &dudy, &dvdx, &dvdy, &uv_area, &f_r, &f_g, &f_b,     &pdf, &wix,
                        &wiy,  &wiz,  &u0,   &u1,      &u2,  &eta, &u_select})
            a->resize(n);
        for (auto* a :
             {&opx, &opy, &opz, &onx, &ony, &onz, &odxx, &odxy, &odxz, &odyx, &odyy, &odyz})
            a->resize(n);
        for (auto* a : {&flags, &path_id, &closure_index, &sample_flags, &light_query})
            a->resize(n);
        light.resize(n);
        for (auto* a : {&g_r, &g_g, &g_b}) a->resize(n);
    }
    /** Points a batch's glint outputs at g_r/g_g/g_b, zeroed for `count` queries (a model
     *  without glints leaves them so). */
    void glint_outputs(std::size_t count, float*& r, float*& g, float*& b) {
        for (auto* a : {&g_r, &g_g, &g_b})
            std::fill_n(a->begin(), static_cast<std::ptrdiff_t>(count), 0.0f);
        r = g_r.data();
        g = g_g.data();
        b = g_b.data();
    }
};

/** State shared by all tiles of one render. */
struct RenderJob {
    const RenderScene* scene;
    Strategy strategy;
    float clamp_indirect;  ///< 0 = off
    const CameraModel* camera;
    /** A camera moving while the shutter is open: its fields at evenly spaced times (empty:
     *  `camera` at every time). */
    const std::vector<Camera>* camera_steps = nullptr;
    /** Something moves while the shutter is open: every path draws a time. */
    bool motion = false;
    const FilterSampler* filter;
    uint32_t width, height, spp, max_depth, rr_depth;
    /** The crop window: film pixel (x, y) of the full frame is image pixel
     *  (x - crop_x0, y - crop_y0) of a crop_width-wide image. */
    uint32_t crop_x0 = 0, crop_y0 = 0, crop_width = 0;
    uint64_t seed;
    /** Pixels traced per stride x stride block (1: every pixel; >1: a preview pass, one path per
     *  block with its footprint widened to the block). */
    uint32_t stride = 1;
    /** The film: exact fixed-point sums, RGB per pixel (core/sample_sum.h); a preview pass
     *  adds floats into `image` instead (sums null). */
    std::vector<SampleSum>* sums = nullptr;
    std::vector<float>* image = nullptr;
    /** Render layers: on/off, light groups, values per pixel of the layer film, the film, and
     *  the camera's position and viewing direction (depth is measured along it). */
    bool layers = false;
    uint32_t groups = 0, layer_channels = 0;
    std::vector<float>* layer_image = nullptr;
    Vec3 camera_position, camera_forward;
    std::atomic<uint64_t> camera_rays{0}, bounce_rays{0}, shadow_rays{0}, samples_done{0};
    std::atomic<uint64_t> nonfinite{0};
    std::atomic<uint64_t> first_bad{~0ull};  ///< (pixel << 24 | sample) of the first bad value
    std::mutex progress_mutex;
};

void rnd2(const Workspace& ws, uint32_t path, uint32_t bounce, uint32_t pair, float& a, float& b) {
    sobol_2d_keyed(ws.key[path], ws.sample[path], kPairBounceBase + bounce * kPairsPerBounce + pair,
                   a, b);
}

/** The camera at shutter time `time` (0..1) of a moving camera: the fields of the two steps
 *  around it blended linearly. */
CameraModel camera_at(const RenderJob& job, float time) {
    const std::vector<Camera>& steps = *job.camera_steps;
    std::size_t i = 0;
    float s = 0.0f;
    motion_step(steps.size(), time, i, s);
    const Camera& a = steps[i];
    const Camera& b = steps[i + 1];
    const auto mix = [s](auto x, auto y) { return x + (y - x) * s; };
    return CameraModel(mix(a.position, b.position), mix(a.look_at, b.look_at), mix(a.up, b.up),
                       mix(a.fov_deg, b.fov_deg), mix(a.aperture, b.aperture),
                       mix(a.focus_distance, b.focus_distance), job.width, job.height);
}

/** The factor that caps the luminance of one indirect contribution c (a biased, optional
 *  firefly guard: light that reached the camera through `scatterings` >= 2 surface events);
 *  1 when it is under the cap. The render layers' parts of c are scaled by the same factor, so
 *  that they still add up to it. */
float clamp_factor(const RenderJob& job, Vec3 c, uint32_t scatterings) {
    if (job.clamp_indirect <= 0.0f || scatterings < 2) return 1.0f;
    const float lum = luminance(c);
    return lum > job.clamp_indirect ? job.clamp_indirect / lum : 1.0f;
}

/** Adds one contribution c of path k (after clamping) to its light group's layer, and its part
 *  that came through a glint at the first surface (clamped alike) to the glint layer. */
void add_to_layers(const RenderJob& job, Workspace& ws, std::size_t k, Vec3 c, uint32_t group,
                   Vec3 glint) {
    ws.group_radiance[k * job.groups + group] += c;
    ws.glint[k] += glint;
}

/** Bends the ray differentials of path i through a specular bounce (pbrt, section 10.1.3). */
void propagate_specular(Workspace& ws, uint32_t i, Vec3 wi, bool transmission, float eta_rel) {
    const SurfacePoint& sp = ws.surf[i];
    RayDifferential& r = ws.ray[i];
    const Vec3 wo = -r.d, n = sp.n;
    const Vec3 dndx = sp.dndu * sp.dudx + sp.dndv * sp.dvdx;
    const Vec3 dndy = sp.dndu * sp.dudy + sp.dndv * sp.dvdy;
    const Vec3 dwodx = -r.dx_d - wo, dwody = -r.dy_d - wo;
    const float ddndx = dot(dwodx, n) + dot(wo, dndx);
    const float ddndy = dot(dwody, n) + dot(wo, dndy);
    r.dx_o = sp.p + sp.dpdx;
    r.dy_o = sp.p + sp.dpdy;
    if (!transmission) {
        r.dx_d = wi - dwodx + (dndx * dot(wo, n) + n * ddndx) * 2.0f;
        r.dy_d = wi - dwody + (dndy * dot(wo, n) + n * ddndy) * 2.0f;
    } else {
        const float e = 1.0f / eta_rel;  // eta_incident / eta_transmitted
        const float cos_i = std::fabs(dot(wi, n));
        const float mu = e * dot(wo, n) - cos_i;
        const float k = cos_i > 0.0f ? e - e * e * dot(wo, n) / cos_i : 0.0f;
        r.dx_d = wi - dwodx * e + dndx * mu + n * (k * ddndx);
        r.dy_d = wi - dwody * e + dndy * mu + n * (k * ddndy);
    }
    if (!is_finite(r.dx_d) || !is_finite(r.dy_d) || !is_finite(r.dx_o) || !is_finite(r.dy_o))
        ws.has_diff[i] = 0;
}

/** Rebuilds sp's shading frame around a new normal (front side of the surface: `nf`). */
void reframe(SurfacePoint& sp, Vec3 nf) {
    const float len = length(nf);
    if (!(len > 0.0f) || !std::isfinite(len)) return;
    Vec3 n = nf / len;
    if (sp.backface) n = -n;
    if (!(dot(n, sp.n) > 1e-3f)) return;  // a map cannot turn the normal past the surface
    shading_frame(n, sp.s, sp.s, sp.t);
    sp.n = n;
}

/** Applies the material's normal or bump map to the group's shading frames: tangent space from
 *  dp/du and dp/dv (normal map: OpenGL convention, green towards +v; bump map: a height field
 *  in metres along the normal, its slope from the filtered texture's derivatives). */
void apply_map(const RenderScene& w, Workspace& ws, const MaterialInstance& mat,
               const uint32_t* paths, uint32_t n) {
    const TextureBinding& b = mat.map();
    for (auto* a : {&ws.gu, &ws.gv, &ws.gdudx, &ws.gdudy, &ws.gdvdx, &ws.gdvdy}) a->resize(n);
    for (uint32_t k = 0; k < n; ++k) {
        const SurfacePoint& sp = ws.surf[paths[k]];
        ws.gu[k] = sp.u;
        ws.gv[k] = sp.v;
        ws.gdudx[k] = sp.dudx;
        ws.gdudy[k] = sp.dudy;
        ws.gdvdx[k] = sp.dvdx;
        ws.gdvdy[k] = sp.dvdy;
    }
    texture_coordinates(b.ref, ws.gu.data(), ws.gv.data(), ws.gdudx.data(), ws.gdudy.data(),
                        ws.gdvdx.data(), ws.gdvdy.data(), n, ws.tex_query);
    const auto c = static_cast<std::size_t>(b.channels);
    ws.map_value.resize(n * c);
    const bool bump = mat.map_kind() == MapKind::Bump;
    ws.map_ds.resize(bump ? n : 0);
    ws.map_dt.resize(bump ? n : 0);
    w.host->textures().lookup(*b.texture, b.ref, ws.tex_query, n, b.channels, ws.map_value.data(),
                              bump ? ws.map_ds.data() : nullptr, bump ? ws.map_dt.data() : nullptr);
    const float* m = b.ref.uv;
    for (uint32_t k = 0; k < n; ++k) {
        SurfacePoint& sp = ws.surf[paths[k]];
        if (!sp.has_uv) continue;  // no tangent space to read the map in
        const Vec3 nf = sp.backface ? -sp.n : sp.n;
        if (bump) {
            // Height h = height * value; dh/du and dh/dv through the uv transform (t = 1 - v').
            const float hs = ws.map_ds[k] * b.ref.amount, ht = ws.map_dt[k] * b.ref.amount;
            const float dhdu = hs * m[0] - ht * m[3];
            const float dhdv = hs * m[1] - ht * m[4];
            Vec3 nb = cross(sp.dpdu + nf * dhdu, sp.dpdv + nf * dhdv);
            // cross(dpdu, dpdv) points to either side, by the uvs' handedness.
            if (dot(cross(sp.dpdu, sp.dpdv), nf) < 0.0f) nb = -nb;
            reframe(sp, nb);
        } else {
            const float* v = &ws.map_value[3 * k];
            const float x = (2.0f * v[0] - 1.0f) * b.ref.amount;
            const float y = (2.0f * v[1] - 1.0f) * b.ref.amount;
            const float z = 2.0f * v[2] - 1.0f;
            // The image's axes on the surface: dp/du' and dp/dv' of the transformed uv' = M uv,
            // made orthogonal to n (a rotated or mirrored map tilts the way the image shows).
            const float det = m[0] * m[4] - m[1] * m[3];
            const Vec3 dpdu2 = (sp.dpdu * m[4] - sp.dpdv * m[3]) * (1.0f / det);
            const Vec3 dpdv2 = (sp.dpdv * m[0] - sp.dpdu * m[1]) * (1.0f / det);
            Vec3 tu = dpdu2 - nf * dot(nf, dpdu2);
            const float len = length(tu);
            if (!(len > 0.0f) || !std::isfinite(len)) continue;
            tu = tu / len;
            Vec3 tv = cross(nf, tu);
            if (dot(tv, dpdv2) < 0.0f) tv = -tv;
            reframe(sp, tu * x + tv * y + nf * z);
        }
    }
}

/** Shades one material group: prepare, next-event estimation, then BSDF sampling. */
void shade_group(RenderJob& job, Workspace& ws, const MaterialInstance& mat, const uint32_t* paths,
                 uint32_t n, uint32_t bounce, uint64_t& shadow_rays) {
    const RenderScene& w = *job.scene;
    ws.resize_group(n);
    // The glint part of f matters for the glint layer at the first surface only (later on, the
    // glint throughput of a path carries it).
    const bool first_surface = job.layers && bounce == 0;
    if (mat.map_kind() != MapKind::None) apply_map(w, ws, mat, paths, n);
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        const SurfacePoint& sp = ws.surf[i];
        const Vec3 wo = -ws.ray[i].d;
        ws.px[k] = sp.p.x;
        ws.py[k] = sp.p.y;
        ws.pz[k] = sp.p.z;
        ws.wox[k] = dot(wo, sp.s);
        ws.woy[k] = dot(wo, sp.t);
        ws.woz[k] = dot(wo, sp.n);
        ws.u[k] = sp.u;
        ws.v[k] = sp.v;
        ws.dudx[k] = sp.dudx;
        ws.dudy[k] = sp.dudy;
        ws.dvdx[k] = sp.dvdx;
        ws.dvdy[k] = sp.dvdy;
        ws.uv_area[k] = sp.uv_area;
        ws.opx[k] = sp.p_obj.x;
        ws.opy[k] = sp.p_obj.y;
        ws.opz[k] = sp.p_obj.z;
        ws.onx[k] = sp.ng_obj.x;
        ws.ony[k] = sp.ng_obj.y;
        ws.onz[k] = sp.ng_obj.z;
        ws.odxx[k] = sp.dpdx_obj.x;
        ws.odxy[k] = sp.dpdx_obj.y;
        ws.odxz[k] = sp.dpdx_obj.z;
        ws.odyx[k] = sp.dpdy_obj.x;
        ws.odyy[k] = sp.dpdy_obj.y;
        ws.odyz[k] = sp.dpdy_obj.z;
        ws.flags[k] = (sp.backface ? SPANGLE_SHADING_BACKFACE : 0u) |
                      (ws.has_diff[i] ? SPANGLE_SHADING_HAS_DIFFERENTIALS : 0u) |
                      (sp.has_uv ? 0u : SPANGLE_SHADING_NO_UV);
        ws.path_id[k] = i;
    }
    SpangleShadingBatch_v3 batch{n,
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
                                 ws.opx.data(),
                                 ws.opy.data(),
                                 ws.opz.data(),
                                 ws.onx.data(),
                                 ws.ony.data(),
                                 ws.onz.data(),
                                 ws.odxx.data(),
                                 ws.odxy.data(),
                                 ws.odxz.data(),
                                 ws.odyx.data(),
                                 ws.odyy.data(),
                                 ws.odyz.data(),
                                 ws.flags.data(),
                                 ws.path_id.data(),
                                 nullptr};
    const SpangleMaterialModel_v3& model = mat.model();
    if (!mat.textures().empty()) {
        // Textured parameters: looked up per point, scaled, clamped into the parameter's range.
        ws.param_values.assign(model.param_count, nullptr);
        ws.tex_values.resize(std::max(ws.tex_values.size(), mat.textures().size()));
        for (std::size_t j = 0; j < mat.textures().size(); ++j) {
            const TextureBinding& b = mat.textures()[j];
            texture_coordinates(b.ref, ws.u.data(), ws.v.data(), ws.dudx.data(), ws.dudy.data(),
                                ws.dvdx.data(), ws.dvdy.data(), n, ws.tex_query);
            std::vector<float>& out = ws.tex_values[j];
            const auto c = static_cast<std::size_t>(b.channels);
            out.resize(n * c);
            w.host->textures().lookup(*b.texture, b.ref, ws.tex_query, n, b.channels, out.data());
            for (std::size_t i = 0; i < n * c; ++i) {
                const float x = out[i] * b.ref.scale[i % c];
                out[i] = std::isnan(x) ? b.lo : std::clamp(x, b.lo, b.hi);
            }
            ws.param_values[b.param] = out.data();
        }
        batch.param_values = ws.param_values.data();
    }
    ws.closures.resize(static_cast<std::size_t>(n) * model.closure_size + 16);
    void* closures = ws.closures.data();
    std::size_t space = ws.closures.size();
    closures = std::align(16, static_cast<std::size_t>(n) * model.closure_size, closures, space);
    ws.arena.reset();
    SpangleArena_v3 arena = ws.arena.api();
    model.prepare(mat.instance(), &batch, closures, &arena);

    // Random numbers of this bounce, shared by light and BSDF sampling.
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        float sel, lobe;
        rnd2(ws, i, bounce, kPairSelect, sel, lobe);
        ws.u2[k] = lobe;
        ws.u_select[k] = sel;
    }

    // Next-event estimation towards the lights.
    if (!w.lights->empty()) {
        uint32_t q = 0;
        for (uint32_t k = 0; k < n; ++k) {
            const uint32_t i = paths[k];
            const SurfacePoint& sp = ws.surf[i];
            float lu, lv;
            rnd2(ws, i, bounce, kPairLight, lu, lv);
            const LightSample ls = w.lights->sample(sp.p, ws.u_select[k], lu, lv);
            if (!(ls.pdf > 0.0f)) continue;
            ws.light[q] = ls;
            ws.light_query[q] = k;
            ws.closure_index[q] = k;
            ws.wix[q] = dot(ls.wi, sp.s);
            ws.wiy[q] = dot(ls.wi, sp.t);
            ws.wiz[q] = dot(ls.wi, sp.n);
            ++q;
        }
        SpangleEvalBatch_v3 eval{q,
                                 ws.closure_index.data(),
                                 ws.wix.data(),
                                 ws.wiy.data(),
                                 ws.wiz.data(),
                                 ws.f_r.data(),
                                 ws.f_g.data(),
                                 ws.f_b.data(),
                                 ws.pdf.data(),
                                 nullptr,
                                 nullptr,
                                 nullptr};
        if (first_surface) ws.glint_outputs(q, eval.glint_r, eval.glint_g, eval.glint_b);
        if (q > 0) model.eval(mat.instance(), closures, &eval);
        // The unoccluded contribution of each query, then its shadow ray; the rays of the
        // whole group are traced as one stream.
        ws.shadow_path.clear();
        ws.shadow_contrib.clear();
        ws.stream_o.clear();
        ws.stream_d.clear();
        ws.stream_time.clear();
        ws.shadow_tmax.clear();
        ws.shadow_group.clear();
        ws.shadow_glint.clear();
        for (uint32_t j = 0; j < q; ++j) {
            const Vec3 f(ws.f_r[j], ws.f_g[j], ws.f_b[j]);
            if (max_component(f) <= 0.0f) continue;
            const uint32_t i = paths[ws.light_query[j]];
            const SurfacePoint& sp = ws.surf[i];
            const LightSample& ls = ws.light[j];
            float mis = ls.delta ? 1.0f : power_heuristic(ls.pdf, ws.pdf[j]);
            if (job.strategy == Strategy::NeeOnly) mis = 1.0f;
            if (job.strategy == Strategy::BsdfOnly && !ls.delta) mis = 0.0f;
            if (mis <= 0.0f) continue;
            // Leave on the side of the geometric normal that wi points to.
            const Vec3 side = dot(ls.wi, sp.ng) >= 0.0f ? sp.ng : -sp.ng;
            ws.shadow_path.push_back(i);
            const float weight = std::fabs(ws.wiz[j]) * mis / ls.pdf;
            ws.shadow_contrib.push_back(ws.throughput[i] * f * ls.radiance * weight);
            if (job.layers) {
                ws.shadow_group.push_back(ls.group);
                ws.shadow_glint.push_back(
                    (first_surface ? ws.throughput[i] * Vec3(ws.g_r[j], ws.g_g[j], ws.g_b[j])
                                   : ws.glint_throughput[i] * f) *
                    ls.radiance * weight);
            }
            ws.stream_o.push_back(offset_origin(sp.p, side));
            ws.stream_d.push_back(ls.wi);
            ws.stream_time.push_back(ws.time[i]);
            ws.shadow_tmax.push_back(std::isfinite(ls.dist) ? ls.dist * (1.0f - 1e-4f) : 1e30f);
        }
        const std::size_t rays = ws.shadow_path.size();
        shadow_rays += rays;
        ws.stream_found.assign(rays, 0);
        if (w.accel)
            w.accel->occluded_stream(ws.stream_o.data(), ws.stream_d.data(), ws.shadow_tmax.data(),
                                     rays, ws.stream_found.data(),
                                     job.motion ? ws.stream_time.data() : nullptr);
        for (std::size_t r = 0; r < rays; ++r) {
            if (ws.stream_found[r]) continue;
            const float kc = clamp_factor(job, ws.shadow_contrib[r], bounce + 1);
            const Vec3 c = ws.shadow_contrib[r] * kc;
            ws.radiance[ws.shadow_path[r]] += c;
            if (job.layers)
                add_to_layers(job, ws, ws.shadow_path[r], c, ws.shadow_group[r],
                              ws.shadow_glint[r] * kc);
        }
    }

    // Continue each path by sampling the BSDF.
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        rnd2(ws, i, bounce, kPairBsdf, ws.u0[k], ws.u1[k]);
        ws.eta[k] = 1.0f;
    }
    SpangleSampleBatch_v3 sb{n,
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
                             ws.sample_flags.data(),
                             ws.eta.data(),
                             nullptr,
                             nullptr,
                             nullptr};
    if (first_surface) ws.glint_outputs(n, sb.glint_r, sb.glint_g, sb.glint_b);
    model.sample(mat.instance(), closures, &sb);
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        const SurfacePoint& sp = ws.surf[i];
        const Vec3 f(ws.f_r[k], ws.f_g[k], ws.f_b[k]);
        const float pdf = ws.pdf[k];
        const uint32_t sflags = ws.sample_flags[k];
        float* aov = job.layers ? &ws.aov[static_cast<std::size_t>(i) * kAovCount] : nullptr;
        if (first_surface) {
            aov[kAovN] = sp.n.x;
            aov[kAovN + 1] = sp.n.y;
            aov[kAovN + 2] = sp.n.z;
        }
        if (sflags == 0 || !(pdf > 0.0f) || max_component(f) <= 0.0f) {
            ws.active[i] = 0;
            continue;
        }
        const Vec3 wi = normalize(sp.s * ws.wix[k] + sp.t * ws.wiy[k] + sp.n * ws.wiz[k]);
        const float cos_pdf = std::fabs(ws.wiz[k]) / pdf;
        Vec3 t = ws.throughput[i] * f * cos_pdf;
        // The glint throughput: at the first surface the glint part of this sample's weight,
        // later the path's glint part carried on like the throughput.
        Vec3 gt(0.0f);
        if (first_surface) {
            gt = ws.throughput[i] * Vec3(ws.g_r[k], ws.g_g[k], ws.g_b[k]) * cos_pdf;
            // The sample weight f cos / pdf estimates the directional albedo.
            const Vec3 albedo = f * cos_pdf;
            aov[kAovAlbedo] = albedo.x;
            aov[kAovAlbedo + 1] = albedo.y;
            aov[kAovAlbedo + 2] = albedo.z;
        } else if (job.layers) {
            gt = ws.glint_throughput[i] * f * cos_pdf;
        }
        if (bounce + 1 >= job.rr_depth) {
            const float survive = std::min(0.95f, max_component(t));
            float u_rr, spare;
            rnd2(ws, i, bounce, kPairRoulette, u_rr, spare);
            if (u_rr >= survive) {
                ws.active[i] = 0;
                continue;
            }
            t *= 1.0f / survive;
            gt *= 1.0f / survive;
        }
        ws.throughput[i] = t;
        if (job.layers) ws.glint_throughput[i] = gt;
        const bool delta = (sflags & SPANGLE_SAMPLE_SPECULAR) != 0;
        if (delta && ws.has_diff[i]) {
            propagate_specular(ws, i, wi, (sflags & SPANGLE_SAMPLE_TRANSMISSION) != 0, ws.eta[k]);
        } else if (!delta) {
            // A rough bounce spreads the footprint beyond what differentials describe: from here
            // on it is a cone whose spread follows the lobe's width (about 1 / sqrt(pdf)).
            ws.has_diff[i] = 0;
            ws.fp_width[i] = sp.footprint;
            ws.fp_spread[i] = std::max(ws.fp_spread[i], 1.0f / std::sqrt(std::max(pdf, 1e-6f)));
        } else {
            ws.fp_width[i] = sp.footprint;
        }
        const Vec3 side = dot(wi, sp.ng) >= 0.0f ? sp.ng : -sp.ng;
        ws.ray[i].o = offset_origin(sp.p, side);
        ws.ray[i].d = wi;
        ws.prev_pdf[i] = pdf;
        ws.prev_delta[i] = delta ? 1 : 0;
    }
}

/** Emission a ray picks up at a light it hits, MIS-weighted against next-event estimation. */
Vec3 emission_at_hit(const RenderScene& w, Strategy strategy, const Workspace& ws, std::size_t k,
                     const Hit& hit, uint32_t& group) {
    const RayDifferential& r = ws.ray[k];
    const Vec3 q = r.o + r.d * hit.t;
    group = 0;
    if (hit.kind == HitKind::Sphere) {
        const SphereEmitter& s = w.lights->sphere(hit.prim);
        group = s.group;
        if (dot(q - s.center, r.d) >= 0.0f) return Vec3(0.0f);  // seen from inside
        const float weight = bsdf_hit_weight(strategy, ws.prev_delta[k] != 0, ws.prev_pdf[k],
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
    const Vec3 le = w.lights->area_emitted(e, -r.d);
    if (max_component(le) <= 0.0f) return Vec3(0.0f);
    const float weight = bsdf_hit_weight(strategy, ws.prev_delta[k] != 0, ws.prev_pdf[k],
                                         w.lights->area_pdf(e, r.o, q));
    return le * weight;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/** The image index of full-frame pixel `pix` (the same index without a crop window). */
std::size_t film_index(const RenderJob& job, uint32_t pix) {
    const uint32_t x = pix % job.width, y = pix / job.width;
    return static_cast<std::size_t>(y - job.crop_y0) * job.crop_width + (x - job.crop_x0);
}

/** Traces one wave: `count` samples starting at `first_sample` for every pixel of the tile. */
void trace_wave(RenderJob& job, Workspace& ws, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1,
                uint32_t first_sample, uint32_t count) {
    const RenderScene& w = *job.scene;
    const uint32_t st = job.stride;
    const uint32_t tw = (x1 - x0 + st - 1) / st, th = (y1 - y0 + st - 1) / st;
    const std::size_t n = static_cast<std::size_t>(tw) * th * count;
    ws.resize_paths(n);
    const float scale = static_cast<float>(st);
    std::size_t i = 0;
    for (uint32_t y = y0; y < y1; y += st)
        for (uint32_t x = x0; x < x1; x += st)
            for (uint32_t s = 0; s < count; ++s, ++i) {
                // The pixel that holds the block's value (the pixel itself when st == 1).
                const uint32_t pix =
                    std::min(y + st / 2, y1 - 1) * job.width + std::min(x + st / 2, x1 - 1);
                const uint32_t smp = first_sample + s;
                float fu, fv, lu, lv, tu = 0.0f, spare;
                const uint64_t key = sobol_pixel_key(job.seed, pix);
                sobol_2d_keyed(key, smp, kPairFilter, fu, fv);
                sobol_2d_keyed(key, smp, kPairLens, lu, lv);
                if (job.motion) sobol_2d_keyed(key, smp, kPairTime, tu, spare);
                // Filter importance sampling: the sample lands where the filter puts it.
                const float fx = static_cast<float>(x) + scale * (0.5f + job.filter->sample(fu));
                const float fy = static_cast<float>(y) + scale * (0.5f + job.filter->sample(fv));
                ws.pixel[i] = pix;
                ws.key[i] = key;
                ws.sample[i] = smp;
                ws.time[i] = tu;
                float pixel_angle = job.camera->pixel_angle();
                if (job.camera_steps) {  // a moving camera (2 or more steps)
                    const CameraModel cam = camera_at(job, tu);
                    ws.ray[i] = cam.generate(fx, fy, lu, lv);
                    pixel_angle = cam.pixel_angle();
                } else {
                    ws.ray[i] = job.camera->generate(fx, fy, lu, lv);
                }
                if (st > 1) {  // a preview path stands for the whole block: so does its footprint
                    RayDifferential& r = ws.ray[i];
                    r.dx_o = r.o + (r.dx_o - r.o) * scale;
                    r.dx_d = r.d + (r.dx_d - r.d) * scale;
                    r.dy_o = r.o + (r.dy_o - r.o) * scale;
                    r.dy_d = r.d + (r.dy_d - r.d) * scale;
                }
                ws.has_diff[i] = 1;
                ws.fp_width[i] = 0.0f;
                ws.fp_spread[i] = pixel_angle * scale;
                ws.throughput[i] = Vec3(1.0f);
                ws.radiance[i] = Vec3(0.0f);
                ws.prev_pdf[i] = 0.0f;
                ws.prev_delta[i] = 1;  // camera rays see emitters with full weight
                ws.active[i] = 1;
            }
    if (job.layers) ws.resize_layers(n, job.groups);
    uint64_t rays = 0, shadow = 0;
    const std::size_t material_count = w.materials->size();
    std::vector<uint32_t> group_start(material_count + 1);
    for (uint32_t bounce = 0; bounce <= job.max_depth; ++bounce) {
        std::fill(group_start.begin(), group_start.end(), 0u);
        // Trace every active path first, then resolve the hits: the second loop can fetch the
        // mesh data of hits a few paths ahead while it works on the current one (it is memory
        // latency, not arithmetic, that dominates turning a hit into a surface point).
        ws.hits.clear();
        ws.stream_path.clear();
        ws.stream_o.clear();
        ws.stream_d.clear();
        ws.stream_time.clear();
        for (std::size_t k = 0; k < n; ++k) {
            if (!ws.active[k]) continue;
            ws.stream_path.push_back(static_cast<uint32_t>(k));
            ws.stream_o.push_back(ws.ray[k].o);
            ws.stream_d.push_back(ws.ray[k].d);
            ws.stream_time.push_back(ws.time[k]);
        }
        const std::size_t traced = ws.stream_path.size();
        ws.stream_hit.resize(traced);
        ws.stream_found.assign(traced, 0);
        // One stream per bounce; each hit is the ray's own, whatever the stream holds (so a
        // pixel's value does not depend on the tile, pass or crop it was traced in).
        if (w.accel)
            w.accel->intersect_stream(ws.stream_o.data(), ws.stream_d.data(), traced,
                                      ws.stream_hit.data(), ws.stream_found.data(),
                                      job.motion ? ws.stream_time.data() : nullptr);
        for (std::size_t j = 0; j < traced; ++j) {
            const std::size_t k = ws.stream_path[j];
            ++rays;
            const Hit& hit = ws.stream_hit[j];
            if (!ws.stream_found[j]) {
                Vec3* by_group = nullptr;
                if (job.layers) {
                    std::fill(ws.escaped_by_group.begin(), ws.escaped_by_group.end(), Vec3(0.0f));
                    by_group = ws.escaped_by_group.data();
                }
                const Vec3 esc = w.lights->escaped(ws.ray[k].d, ws.prev_pdf[k],
                                                   ws.prev_delta[k] != 0, job.strategy, by_group);
                const Vec3 c = ws.throughput[k] * (w.environment + esc);
                const float kc = clamp_factor(job, c, bounce);
                ws.radiance[k] += c * kc;
                if (job.layers) {
                    // The constant environment and each light at infinity, to their groups;
                    // after the first surface, the part that came through a glint too.
                    const Vec3 gt = bounce > 0 ? ws.glint_throughput[k] * kc : Vec3(0.0f);
                    add_to_layers(job, ws, k, ws.throughput[k] * w.environment * kc,
                                  w.environment_group, gt * w.environment);
                    for (uint32_t g = 0; g < job.groups; ++g)
                        add_to_layers(job, ws, k, ws.throughput[k] * ws.escaped_by_group[g] * kc, g,
                                      gt * ws.escaped_by_group[g]);
                }
                ws.active[k] = 0;
                continue;
            }
            uint32_t group = 0;
            const Vec3 e = emission_at_hit(w, job.strategy, ws, k, hit, group);
            const Vec3 c = ws.throughput[k] * e;
            const float kc = clamp_factor(job, c, bounce);
            ws.radiance[k] += c * kc;
            if (job.layers) {
                add_to_layers(job, ws, k, c * kc, group,
                              bounce > 0 ? ws.glint_throughput[k] * e * kc : Vec3(0.0f));
                if (bounce == 0) {
                    // The camera ray hit something: coverage, depth along the view, position.
                    float* aov = &ws.aov[k * kAovCount];
                    const Vec3 p = ws.ray[k].o + ws.ray[k].d * hit.t;
                    aov[kAovA] = 1.0f;
                    aov[kAovZ] = dot(p - job.camera_position, job.camera_forward);
                    aov[kAovP] = p.x;
                    aov[kAovP + 1] = p.y;
                    aov[kAovP + 2] = p.z;
                }
            }
            if (hit.kind != HitKind::Instance ||
                bounce == job.max_depth) {  // lights do not scatter
                ws.active[k] = 0;
                continue;
            }
            ws.hits.push_back({static_cast<uint32_t>(k), hit});
        }
        const std::size_t hit_count = ws.hits.size();
        const auto prefetch_vertices = [&](std::size_t h) {
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
        };
        constexpr std::size_t kAhead = 4;
        for (std::size_t h = 0; h < std::min(kAhead, hit_count); ++h) prefetch_vertices(h);
        for (std::size_t h = 0; h < hit_count; ++h) {
            if (h + 2 * kAhead < hit_count) {
                const Hit& far = ws.hits[h + 2 * kAhead].hit;
                const TriangleMesh& m =
                    w.geometry->mesh((*w.instances)[static_cast<std::size_t>(far.instance)].mesh);
                __builtin_prefetch(&m.indices[3 * static_cast<std::size_t>(far.prim)]);
            }
            if (h + kAhead < hit_count) prefetch_vertices(h + kAhead);
            const uint32_t k = ws.hits[h].path;
            const Hit& hit = ws.hits[h].hit;
            const Instance& placed = (*w.instances)[static_cast<std::size_t>(hit.instance)];
            // A moving instance is where it was at the path's time.
            Instance moved;
            if (!placed.motion.empty()) moved = instance_at(placed, ws.time[k]);
            const Instance& inst = placed.motion.empty() ? placed : moved;
            ws.surf[k] = surface_at(w.geometry->mesh(inst.mesh), inst, hit, ws.ray[k].d);
            if (job.layers && bounce == 0) {  // where on which object the camera ray landed
                float* aov = &ws.aov[static_cast<std::size_t>(k) * kAovCount];
                aov[kAovPobj] = ws.surf[k].p_obj.x;
                aov[kAovPobj + 1] = ws.surf[k].p_obj.y;
                aov[kAovPobj + 2] = ws.surf[k].p_obj.z;
                aov[kAovObject] = static_cast<float>(inst.object + 1);
            }
            bool has_diff = ws.has_diff[k] != 0;
            footprint_at(ws.surf[k], ws.ray[k], has_diff, ws.fp_width[k] + ws.fp_spread[k] * hit.t);
            object_footprint(ws.surf[k], inst);
            ws.has_diff[k] = has_diff ? 1 : 0;
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
            for (uint32_t off = 0; off < count_m; off += kMaxBatch)
                shade_group(job, ws, *(*w.materials)[m], ws.order.data() + group_start[m] + off,
                            std::min(kMaxBatch, count_m - off), bounce, shadow);
        }
    }
    job.camera_rays += n;
    job.bounce_rays += rays - n;
    job.shadow_rays += shadow;

    // Accumulate in a fixed order (pixel-major, then sample). The film's sums are exact, so
    // they are the same however the samples are split (threads, passes, --spp-range parts).
    for (std::size_t k = 0; k < n; ++k) {
        Vec3 l = ws.radiance[k];
        const bool finite = is_finite(l);
        if (!finite) {
            ++job.nonfinite;
            const uint64_t key = (static_cast<uint64_t>(ws.pixel[k]) << 24) | ws.sample[k];
            uint64_t prev = job.first_bad.load();
            while (key < prev && !job.first_bad.compare_exchange_weak(prev, key)) {
            }
            l = Vec3(0.0f);
        }
        const std::size_t at = film_index(job, ws.pixel[k]);
        if (job.sums) {
            SampleSum* px = &(*job.sums)[3 * at];
            px[0] += to_sample_sum(l.x);
            px[1] += to_sample_sum(l.y);
            px[2] += to_sample_sum(l.z);
        } else {
            float* px = &(*job.image)[3 * at];
            px[0] += l.x;
            px[1] += l.y;
            px[2] += l.z;
        }
        if (!job.layers) continue;
        // The layers: [A, albedo, N, Z, P] of the first hit, the glints, each light group. A
        // path whose radiance was dropped drops its light layers too (they add up to it).
        float* lp = &(*job.layer_image)[at * job.layer_channels];
        const float* aov = &ws.aov[k * kAovCount];
        for (uint32_t c = 0; c < kAovCount; ++c)
            if (std::isfinite(aov[c])) lp[c] += aov[c];
        if (!finite) continue;
        const auto add3 = [](float* to, Vec3 v) {
            if (!is_finite(v)) return;
            to[0] += v.x;
            to[1] += v.y;
            to[2] += v.z;
        };
        add3(lp + kAovCount, ws.glint[k]);
        for (uint32_t g = 0; g < job.groups; ++g)
            add3(lp + kAovCount + 3 + 3 * g, ws.group_radiance[k * job.groups + g]);
    }
}

}  // namespace

CropWindow crop_within(const CropWindow& crop, uint32_t width, uint32_t height) {
    if (crop.whole()) return CropWindow{0, 0, width, height};
    if (!(crop.x0 < crop.x1 && crop.x1 <= width && crop.y0 < crop.y1 && crop.y1 <= height))
        throw_error(
            "crop window {},{},{},{} is not inside the {}x{} image (it needs x0 < x1 <= width "
            "and y0 < y1 <= height)",
            crop.x0, crop.y0, crop.x1, crop.y1, width, height);
    return crop;
}

std::vector<uint32_t> pass_ends(uint32_t spp) {
    std::vector<uint32_t> out;
    for (uint64_t end = 1; end < spp; end *= 2) out.push_back(static_cast<uint32_t>(end));
    out.push_back(spp);
    return out;
}

uint32_t preview_stride(uint32_t width, uint32_t height) {
    uint32_t stride = 1;
    while (stride < kTileSize && std::max(width, height) / (2 * stride) >= 160) stride *= 2;
    return stride;
}

std::vector<std::string> layer_channel_names(const std::vector<std::string>& light_groups) {
    std::vector<std::string> out = {"A",        "albedo.R", "albedo.G", "albedo.B", "N.X",
                                    "N.Y",      "N.Z",      "Z",        "P.X",      "P.Y",
                                    "P.Z",      "Pobj.X",   "Pobj.Y",   "Pobj.Z",   "object",
                                    "glints.R", "glints.G", "glints.B"};
    for (const std::string& g : light_groups)
        for (const char* c : {"R", "G", "B"}) out.push_back(fmt::format("lightgroup_{}.{}", g, c));
    return out;
}

void check_film_memory(uint32_t width, uint32_t height, uint32_t spp, const RenderOptions& options,
                       uint32_t layer_channels) {
    // Per pixel: the film (RGB fixed-point sums, 48 bytes) and the image (RGB floats); a copy
    // of the sums to roll a stopped pass back to (from the second pass on); the copy each pass
    // shows; the preview pass's image. Writing adds only strips. The render layers have a film
    // and a roll-back copy of their own.
    const bool passes = options.progressive && spp > 1;
    const double layers = 4.0 * layer_channels * (passes && options.stop ? 2.0 : 1.0);
    const double per_pixel =
        60.0 + (passes && options.stop ? 48.0 : 0.0) + (passes && options.on_pass ? 12.0 : 0.0) +
        (options.preview_pass && options.on_pass && spp > 1 ? 12.0 : 0.0) + layers;
    const double need = per_pixel * width * height;
    if (const uint64_t have = memory_short_for(need))
        throw_error(
            "a {}x{} image needs about {} to render ({} bytes per pixel), but "
            "only {} of memory is available: lower the resolution ([render] "
            "width and height, or --size){}",
            width, height, format_bytes(need), per_pixel, format_bytes(static_cast<double>(have)),
            passes && options.on_pass ? ", or turn off --pass-output" : "");
}

void render_image(const RenderScene& scene, const RenderOptions& options, const Camera& camera,
                  const Film& film, const std::vector<Camera>& camera_steps, RenderResult& world) {
    const auto t0 = std::chrono::steady_clock::now();
    const CameraModel cam(camera.position, camera.look_at, camera.up, camera.fov_deg,
                          camera.aperture, camera.focus_distance, film.width, film.height);
    const FilterSampler filter(film.filter);
    RenderJob job;
    job.scene = &scene;
    job.strategy = options.strategy;
    job.clamp_indirect = film.clamp_indirect;
    job.camera = &cam;
    if (camera_steps.size() >= 2) job.camera_steps = &camera_steps;
    job.motion = job.camera_steps != nullptr ||
                 std::any_of(scene.instances->begin(), scene.instances->end(),
                             [](const Instance& i) { return !i.motion.empty(); });
    job.filter = &filter;
    job.width = film.width;
    job.height = film.height;
    job.spp = options.spp_override ? options.spp_override : film.spp;
    // --spp-range: samples [first_sample, job.spp) of the frame's.
    uint32_t first_sample = 0;
    if (options.spp_end > 0) {
        if (!(options.spp_first < options.spp_end && options.spp_end <= job.spp))
            throw_error(
                "sample range {}..{} is not inside the frame's {} samples per pixel (it needs "
                "A < B <= spp)",
                options.spp_first, options.spp_end, job.spp);
        first_sample = options.spp_first;
        job.spp = options.spp_end;
    }
    job.max_depth = film.max_depth;
    job.rr_depth = film.rr_depth;
    job.seed = film.seed;
    // The crop window (the whole image without one).
    const CropWindow& crop = options.crop;
    const CropWindow win = crop_within(crop, film.width, film.height);
    const uint32_t cx0 = win.x0, cy0 = win.y0, cx1 = win.x1, cy1 = win.y1;
    const uint32_t cw = cx1 - cx0, ch = cy1 - cy0;
    job.crop_x0 = cx0;
    job.crop_y0 = cy0;
    job.crop_width = cw;
    world.width = cw;
    world.height = ch;
    world.window = ImageWindow{cx0, cy0, film.width, film.height};
    world.layers.clear();
    world.layer_names.clear();
    if (options.layers) {
        std::vector<std::string> groups =
            scene.light_groups ? *scene.light_groups : std::vector<std::string>{};
        if (groups.empty()) groups.push_back("default");
        world.layer_names = layer_channel_names(groups);
        job.layers = true;
        job.groups = static_cast<uint32_t>(groups.size());
        job.layer_channels = static_cast<uint32_t>(world.layer_names.size());
        job.camera_position = camera.position;
        job.camera_forward = normalize(camera.look_at - camera.position);
    }
    check_film_memory(cw, ch, job.spp - first_sample, options, job.layer_channels);
    world.sums.assign(static_cast<std::size_t>(cw) * ch * 3, SampleSum(0));
    job.sums = &world.sums;
    world.layers.assign(static_cast<std::size_t>(cw) * ch * job.layer_channels, 0.0f);
    job.layer_image = &world.layers;

    // The full frame's tile grid, the tiles that meet the window, clipped to it.
    const uint32_t tile_x0 = cx0 / kTileSize, tile_y0 = cy0 / kTileSize;
    const uint32_t tiles_x = (cx1 + kTileSize - 1) / kTileSize - tile_x0;
    const uint32_t tiles_y = (cy1 + kTileSize - 1) / kTileSize - tile_y0;
    const uint64_t total = static_cast<uint64_t>(cw) * ch * (job.spp - first_sample);
    tbb::enumerable_thread_specific<Workspace> workspaces;
    const int threads =
        options.threads > 0 ? options.threads : tbb::this_task_arena::max_concurrency();
    tbb::task_arena arena(threads);
    const auto& stop = options.stop;
    std::atomic<bool> stopped{false};
    // Passes of doubling sample counts. Every pixel adds its samples in sample order whatever
    // the passes, so the sums after the last pass are those of a one-pass render, bit for bit.
    // A pass interrupted by a stop request is rolled back to the sums before it.
    std::vector<SampleSum> before;
    std::vector<float> layers_before;
    uint32_t reached = first_sample, passes = 0;
    const auto run_tiles = [&](uint32_t first, uint32_t end, bool count_progress) {
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<uint32_t>(0, tiles_x * tiles_y, 1),
                              [&](const tbb::blocked_range<uint32_t>& r) {
                                  Workspace& ws = workspaces.local();
                                  for (uint32_t tile = r.begin(); tile != r.end(); ++tile) {
                                      const uint32_t tx = (tile_x0 + tile % tiles_x) * kTileSize,
                                                     ty = (tile_y0 + tile / tiles_x) * kTileSize;
                                      const uint32_t x0 = std::max(tx, cx0), y0 = std::max(ty, cy0);
                                      const uint32_t x1 = std::min(tx + kTileSize, cx1);
                                      const uint32_t y1 = std::min(ty + kTileSize, cy1);
                                      for (uint32_t s = first; s < end; s += kSamplesPerWave) {
                                          if (stopped.load(std::memory_order_relaxed)) return;
                                          if (stop && stop()) {
                                              stopped = true;
                                              return;
                                          }
                                          const uint32_t count = std::min(kSamplesPerWave, end - s);
                                          trace_wave(job, ws, x0, y0, x1, y1, s, count);
                                          if (!count_progress) continue;
                                          const uint64_t done = job.samples_done +=
                                              static_cast<uint64_t>(x1 - x0) * (y1 - y0) * count;
                                          if (options.progress) {
                                              std::lock_guard<std::mutex> lock(job.progress_mutex);
                                              options.progress(done, total);
                                          }
                                      }
                                  }
                              });
        });
    };
    // A preview pass: one path per block of pixels, shown before the first full pass. It is
    // not part of the image: its values are thrown away once shown.
    const uint32_t stride =
        options.preview_pass && options.on_pass && job.spp - first_sample > 1 && crop.whole()
            ? preview_stride(film.width, film.height)
            : 1;
    if (stride > 1) {
        std::vector<float> preview(world.sums.size(), 0.0f);
        job.sums = nullptr;
        job.image = &preview;
        job.stride = stride;
        const bool layers = job.layers;
        job.layers = false;  // the preview pass shows the beauty only
        run_tiles(first_sample, first_sample + 1, false);
        job.layers = layers;
        job.sums = &world.sums;
        job.image = nullptr;
        job.stride = 1;
        if (!stopped) {
            // Every pixel takes the value of its block's traced pixel.
            for (uint32_t y = 0; y < film.height; ++y) {
                const uint32_t sy = std::min((y / stride) * stride + stride / 2, film.height - 1);
                for (uint32_t x = 0; x < film.width; ++x) {
                    const uint32_t sx =
                        std::min((x / stride) * stride + stride / 2, film.width - 1);
                    const std::size_t to = 3 * (static_cast<std::size_t>(y) * film.width + x);
                    const std::size_t from = 3 * (static_cast<std::size_t>(sy) * film.width + sx);
                    if (to != from)
                        for (std::size_t c = 0; c < 3; ++c) preview[to + c] = preview[from + c];
                }
            }
            options.on_pass(PassImage{preview, film.width, film.height, 0, job.spp - first_sample,
                                      stride, seconds_since(t0), world.window});
        }
    }
    std::vector<uint32_t> ends = options.progressive
                                     ? pass_ends(job.spp - first_sample)
                                     : std::vector<uint32_t>{job.spp - first_sample};
    for (uint32_t& e : ends) e += first_sample;
    // The image: the mean of the samples summed so far.
    const auto means = [&](std::vector<float>& to, uint32_t count) {
        to.resize(world.sums.size());
        for (std::size_t i = 0; i < to.size(); ++i) to[i] = sample_mean(world.sums[i], count);
    };
    for (const uint32_t end : ends) {
        const uint32_t first = reached;
        // The first pass starts from black: rolling it back needs no copy.
        if (stop && reached > first_sample) {
            before = world.sums;
            layers_before = world.layers;
        }
        if (!stopped) run_tiles(first, end, true);
        if (stopped) {
            if (reached > first_sample) {
                world.sums.swap(before);
                world.layers.swap(layers_before);
            } else {
                std::fill(world.sums.begin(), world.sums.end(), SampleSum(0));
                std::fill(world.layers.begin(), world.layers.end(), 0.0f);
            }
            break;
        }
        reached = end;
        ++passes;
        if (options.on_pass && end < job.spp) {
            std::vector<float> shown;
            means(shown, end - first_sample);
            options.on_pass(PassImage{shown, cw, ch, end - first_sample, job.spp - first_sample, 1,
                                      seconds_since(t0), world.window});
        }
    }

    const uint32_t samples = reached - first_sample;
    means(world.image, samples);
    const float inv_spp = samples > 0 ? 1.0f / static_cast<float>(samples) : 0.0f;
    if (job.layers) {
        // Coverage, albedo, glints and light groups: averages over all samples. Depth, position,
        // object-space position and object number: averages over the samples whose camera ray
        // hit something (0 where none did: alpha 0), so that edges are not pulled towards the
        // origin (an object number between two integers marks a pixel shared by objects). The
        // normal: normalised.
        const std::size_t lc = job.layer_channels;
        for (std::size_t p = 0; p < world.layers.size(); p += lc) {
            float* v = &world.layers[p];
            const float hits = v[kAovA];
            const float inv_hits = hits > 0.0f ? 1.0f / hits : 0.0f;
            for (std::size_t c = 0; c < lc; ++c) {
                const bool per_hit = c == kAovZ || (c >= kAovP && c <= kAovObject);
                const bool normal = c >= kAovN && c < kAovN + 3;
                if (!normal) v[c] *= per_hit ? inv_hits : inv_spp;
            }
            // The normal: the direction of the summed normals of the shaded hits (a camera
            // ray that hit a light adds none), unit length, 0 where none was shaded.
            const float len = std::sqrt(v[kAovN] * v[kAovN] + v[kAovN + 1] * v[kAovN + 1] +
                                        v[kAovN + 2] * v[kAovN + 2]);
            const float inv_len = len > 0.0f && std::isfinite(len) ? 1.0f / len : 0.0f;
            for (std::size_t c = kAovN; c < kAovN + 3; ++c) v[c] *= inv_len;
        }
    }
    RenderStats& st = world.stats;
    st.camera_rays = job.camera_rays;
    st.bounce_rays = job.bounce_rays;
    st.shadow_rays = job.shadow_rays;
    st.samples = static_cast<uint64_t>(cw) * ch * samples;
    st.spp_reached = samples;
    st.spp_target = job.spp - first_sample;
    st.spp_frame = options.spp_override ? options.spp_override : film.spp;
    st.passes = passes;
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
