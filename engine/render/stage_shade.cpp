// The shading stage: one material batch's shading points handed to its plugin (positions,
// frames, uvs and footprints, object-space frames; textured parameters looked up per point; the
// normal or bump map applied to the frames), prepared, and lit by next-event estimation with
// multiple importance sampling, the batch's shadow rays traced as one stream.

#include <algorithm>

#include "render/wave.h"

namespace spangle {
namespace {

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

/** Tilts sp's normal by a bump map's height slopes (hs, ht) along the image's axes: a height
 *  field in metres along the normal, its slope from the filtered texture's derivatives; with
 *  `blend` below 1 the normal is the surface's blended that far towards the bumped one (Cycles'
 *  Bump Strength: a strong bump softened, which a lower height cannot give). */
void bump(SurfacePoint& sp, const float* m, float hs, float ht, float blend) {
    const Vec3 nf = sp.backface ? -sp.n : sp.n;
    // Height h = height * value; dh/du and dh/dv through the uv transform (t = 1 - v').
    const float dhdu = hs * m[0] - ht * m[3];
    const float dhdv = hs * m[1] - ht * m[4];
    Vec3 nb = cross(sp.dpdu + nf * dhdu, sp.dpdv + nf * dhdv);
    // cross(dpdu, dpdv) points to either side, by the uvs' handedness.
    if (dot(cross(sp.dpdu, sp.dpdv), nf) < 0.0f) nb = -nb;
    if (blend < 1.0f) {
        const float len = length(nb);
        if (!(len > 0.0f) || !std::isfinite(len)) return;
        nb = nf + (nb / len - nf) * blend;
    }
    reframe(sp, nb);
}

/** Turns sp's normal to a normal map's texel v (OpenGL convention, green towards +v) scaled by
 *  `amount`, in the image's axes through uv transform m. */
void normal_map(SurfacePoint& sp, const float* m, const float* v, float amount) {
    const Vec3 nf = sp.backface ? -sp.n : sp.n;
    const float x = (2.0f * v[0] - 1.0f) * amount;
    const float y = (2.0f * v[1] - 1.0f) * amount;
    const float z = 2.0f * v[2] - 1.0f;
    // The image's axes on the surface: dp/du' and dp/dv' of the transformed uv' = M uv, made
    // orthogonal to n (a rotated or mirrored map tilts the way the image shows).
    const float det = m[0] * m[4] - m[1] * m[3];
    const Vec3 dpdu2 = (sp.dpdu * m[4] - sp.dpdv * m[3]) * (1.0f / det);
    const Vec3 dpdv2 = (sp.dpdv * m[0] - sp.dpdu * m[1]) * (1.0f / det);
    Vec3 tu = dpdu2 - nf * dot(nf, dpdu2);
    const float len = length(tu);
    if (!(len > 0.0f) || !std::isfinite(len)) return;
    tu = tu / len;
    Vec3 tv = cross(nf, tu);
    if (dot(tv, dpdv2) < 0.0f) tv = -tv;
    reframe(sp, tu * x + tv * y + nf * z);
}

/** Applies the material's normal or bump map to the batch's shading frames (tangent space from
 *  dp/du and dp/dv). */
void apply_map(const RenderScene& w, Workspace& ws, const MaterialInstance& mat,
               const uint32_t* paths, uint32_t n) {
    const TextureBinding& b = mat.map();
    for (auto* a : {&ws.gu, &ws.gv, &ws.gdudx, &ws.gdudy, &ws.gdvdx, &ws.gdvdy}) a->resize(n);
    for (uint32_t k = 0; k < n; ++k) {
        const SurfacePoint& sp = ws.paths.surf[paths[k]];
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
    const bool is_bump = mat.map_kind() == MapKind::Bump;
    ws.map_ds.resize(is_bump ? n : 0);
    ws.map_dt.resize(is_bump ? n : 0);
    // A two-channel normal map (X and Y only, as BC5-compressed maps are kept): z is rebuilt
    // from them (read as grey, every tilt was lost).
    const bool xy_only = !is_bump && c == 3 && b.texture->channels == 2;
    w.host->textures().lookup(*b.texture, b.ref, ws.tex_query, n, xy_only ? 2 : b.channels,
                              ws.map_value.data(), is_bump ? ws.map_ds.data() : nullptr,
                              is_bump ? ws.map_dt.data() : nullptr);
    if (xy_only)
        for (uint32_t k = n; k-- > 0;) {
            const float x = ws.map_value[2 * k], y = ws.map_value[2 * k + 1];
            const float tx = 2.0f * x - 1.0f, ty = 2.0f * y - 1.0f;
            ws.map_value[3 * k] = x;
            ws.map_value[3 * k + 1] = y;
            ws.map_value[3 * k + 2] =
                0.5f + 0.5f * std::sqrt(std::max(0.0f, 1.0f - tx * tx - ty * ty));
        }
    for (uint32_t k = 0; k < n; ++k) {
        SurfacePoint& sp = ws.paths.surf[paths[k]];
        if (!sp.has_uv) continue;  // no tangent space to read the map in
        if (is_bump)
            bump(sp, b.ref.uv, ws.map_ds[k] * b.ref.amount, ws.map_dt[k] * b.ref.amount,
                 b.ref.blend);
        else
            normal_map(sp, b.ref.uv, &ws.map_value[3 * k], b.ref.amount);
    }
}

/** The GGX alpha below which path regularisation keeps the lobes of a point whose path's least
 *  likely rough bounce had density min_pdf (0: no floor). A path that has only met mirrors (or
 *  none) keeps its sharp lobes; after a diffuse bounce (pdf <= 1/pi) the floor is about 0.4-0.5,
 *  after a glossy one of density well above filter_glossy none. The curve is Cycles' (its
 *  "filter glossy"), so that the two renderers' images can be compared like for like. */
float roughness_floor(float filter_glossy, float min_pdf) {
    if (!(filter_glossy > 0.0f) || !(min_pdf < filter_glossy)) return 0.0f;
    return 0.5f * std::sqrt(1.0f - min_pdf / filter_glossy);
}

/** Fills the batch's shading points from the paths' surfaces (the plugin ABI's arrays). */
void fill_points(const RenderJob& job, Workspace& ws, const uint32_t* paths, uint32_t n) {
    const PathBatch& p = ws.paths;
    ShadingBatch& b = ws.batch;
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        const SurfacePoint& sp = p.surf[i];
        const Vec3 wo = -p.ray[i].d;
        b.px[k] = sp.p.x;
        b.py[k] = sp.p.y;
        b.pz[k] = sp.p.z;
        b.wox[k] = dot(wo, sp.s);
        b.woy[k] = dot(wo, sp.t);
        b.woz[k] = dot(wo, sp.n);
        b.u[k] = sp.u;
        b.v[k] = sp.v;
        b.dudx[k] = sp.dudx;
        b.dudy[k] = sp.dudy;
        b.dvdx[k] = sp.dvdx;
        b.dvdy[k] = sp.dvdy;
        b.uv_area[k] = sp.uv_area;
        b.opx[k] = sp.p_obj.x;
        b.opy[k] = sp.p_obj.y;
        b.opz[k] = sp.p_obj.z;
        b.onx[k] = sp.ng_obj.x;
        b.ony[k] = sp.ng_obj.y;
        b.onz[k] = sp.ng_obj.z;
        b.odxx[k] = sp.dpdx_obj.x;
        b.odxy[k] = sp.dpdx_obj.y;
        b.odxz[k] = sp.dpdx_obj.z;
        b.odyx[k] = sp.dpdy_obj.x;
        b.odyy[k] = sp.dpdy_obj.y;
        b.odyz[k] = sp.dpdy_obj.z;
        b.rough_floor[k] = roughness_floor(job.filter_glossy, p.min_pdf[i]);
        b.flags[k] = (sp.backface ? SPANGLE_SHADING_BACKFACE : 0u) |
                     (p.has_diff[i] ? SPANGLE_SHADING_HAS_DIFFERENTIALS : 0u) |
                     (sp.has_uv ? 0u : SPANGLE_SHADING_NO_UV) |
                     (b.rough_floor[k] > 0.0f ? SPANGLE_SHADING_ROUGHNESS_FLOOR : 0u);
        b.path_id[k] = i;
    }
}

/** The plugin ABI's view of the batch's arrays. */
SpangleShadingBatch_v3 abi_batch(ShadingBatch& b, uint32_t n) {
    return SpangleShadingBatch_v3{n,
                                  b.px.data(),
                                  b.py.data(),
                                  b.pz.data(),
                                  b.wox.data(),
                                  b.woy.data(),
                                  b.woz.data(),
                                  b.u.data(),
                                  b.v.data(),
                                  b.dudx.data(),
                                  b.dudy.data(),
                                  b.dvdx.data(),
                                  b.dvdy.data(),
                                  b.uv_area.data(),
                                  b.opx.data(),
                                  b.opy.data(),
                                  b.opz.data(),
                                  b.onx.data(),
                                  b.ony.data(),
                                  b.onz.data(),
                                  b.odxx.data(),
                                  b.odxy.data(),
                                  b.odxz.data(),
                                  b.odyx.data(),
                                  b.odyy.data(),
                                  b.odyz.data(),
                                  b.flags.data(),
                                  b.path_id.data(),
                                  nullptr,
                                  b.rough_floor.data()};
}

/** Textured parameters: looked up per point (times the vertex colours where they are asked
 *  for), scaled, clamped into the parameter's range; returns the per-parameter value arrays for
 *  the plugin (one per schema entry, null for a constant). */
const float* const* lookup_textures(const RenderScene& w, Workspace& ws,
                                    const MaterialInstance& mat, const uint32_t* paths,
                                    uint32_t n) {
    ws.param_values.assign(mat.model().param_count, nullptr);
    ws.tex_values.resize(std::max(ws.tex_values.size(), mat.textures().size()));
    const ShadingBatch& b = ws.batch;
    for (std::size_t j = 0; j < mat.textures().size(); ++j) {
        const TextureBinding& t = mat.textures()[j];
        std::vector<float>& out = ws.tex_values[j];
        const auto c = static_cast<std::size_t>(t.channels);
        out.resize(n * c);
        if (t.texture) {
            texture_coordinates(t.ref, b.u.data(), b.v.data(), b.dudx.data(), b.dudy.data(),
                                b.dvdx.data(), b.dvdy.data(), n, ws.tex_query);
            if (t.picks) {
                // A number from a colour: its channel or luminance (pick . rgb).
                ws.map_value.resize(3 * static_cast<std::size_t>(n));
                w.host->textures().lookup(*t.texture, t.ref, ws.tex_query, n, 3,
                                          ws.map_value.data());
                for (uint32_t k = 0; k < n; ++k) {
                    const float* rgb = &ws.map_value[3 * k];
                    out[k] = t.pick[0] * rgb[0] + t.pick[1] * rgb[1] + t.pick[2] * rgb[2];
                }
            } else {
                w.host->textures().lookup(*t.texture, t.ref, ws.tex_query, n, t.channels,
                                          out.data());
            }
        } else {
            std::fill(out.begin(), out.end(), 1.0f);
        }
        // A colour image times vertex colours and a coloured `scale` (all linear Rec.709 but
        // the image): multiplied in Rec.709.
        if (t.rec709_product) {
            const Vec3 scale(t.ref.scale[0], t.ref.scale[1], t.ref.scale[2]);
            for (uint32_t k = 0; k < n; ++k) {
                const Vec3 f = t.ref.vertex_color ? ws.paths.surf[paths[k]].color * scale : scale;
                const Vec3 v = t.rec709.apply(Vec3(out[3 * k], out[3 * k + 1], out[3 * k + 2]), f);
                const float x[3] = {v.x, v.y, v.z};
                for (int i = 0; i < 3; ++i)
                    out[3 * k + static_cast<uint32_t>(i)] =
                        std::isnan(x[i]) ? t.lo : std::clamp(x[i], t.lo, t.hi);
            }
            ws.param_values[t.param] = out.data();
            continue;
        }
        // Vertex colours times `scale` (both linear Rec.709) into the working space, then
        // times the image (a data parameter: its channels are numbers).
        const bool vc_scaled = t.ref.vertex_color && c == 3;
        if (vc_scaled)
            for (uint32_t k = 0; k < n; ++k) {
                const Vec3 f = t.vertex_factor(ws.paths.surf[paths[k]].color);
                out[3 * k] *= f.x;
                out[3 * k + 1] *= f.y;
                out[3 * k + 2] *= f.z;
            }
        for (std::size_t i = 0; i < n * c; ++i) {
            const float x = vc_scaled ? out[i] : out[i] * t.ref.scale[i % c];
            out[i] = std::isnan(x) ? t.lo : std::clamp(x, t.lo, t.hi);
        }
        ws.param_values[t.param] = out.data();
    }
    return ws.param_values.data();
}

/** The plugin's closures for the batch, in ws.closures (16-byte aligned). */
void prepare(Workspace& ws, const MaterialInstance& mat, SpangleShadingBatch_v3& batch,
             uint32_t n) {
    const SpangleMaterialModel_v3& model = mat.model();
    ws.closures.resize(static_cast<std::size_t>(n) * model.closure_size + 16);
    void* closures = ws.closures.data();
    std::size_t space = ws.closures.size();
    closures = std::align(16, static_cast<std::size_t>(n) * model.closure_size, closures, space);
    ws.arena.reset();
    SpangleArena_v3 arena = ws.arena.api();
    call_plugin(mat.label(), "prepare",
                [&] { model.prepare(mat.instance(), &batch, closures, &arena); });
    ws.closure_data = closures;
}

/** One light sample per shading point, and the BSDF's value and pdf towards it; returns the
 *  number of queries (points whose light sample is valid). */
template <class Sink>
uint32_t sample_lights(const RenderJob& job, Workspace& ws, Sink& sink, const MaterialInstance& mat,
                       const uint32_t* paths, uint32_t n, uint32_t bounce) {
    ShadingBatch& b = ws.batch;
    uint32_t q = 0;
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t i = paths[k];
        const SurfacePoint& sp = ws.paths.surf[i];
        float lu, lv, sel;
        rnd3(ws.paths, i, bounce, kPairLight, lu, lv, sel);
        LightSample ls = job.scene->lights->sample(sp.p, sel, lu, lv);
        if (!(ls.pdf > 0.0f)) continue;
        // A point of a cut-out emitter shines by the share of rays that meet it there, as BSDF
        // rays see its light only where they meet it.
        const std::vector<EmitterCut>* cuts = job.scene->emitter_cuts;
        if (ls.area >= 0 && cuts && static_cast<std::size_t>(ls.area) < cuts->size()) {
            const EmitterCut& c = (*cuts)[static_cast<std::size_t>(ls.area)];
            if (c.instance >= 0) {
                const float met =
                    met_share((*job.scene->cut_outs)[static_cast<std::size_t>(c.instance)], c.prim,
                              ls.b1, ls.b2);
                if (!(met > 0.0f)) continue;
                ls.radiance = ls.radiance * met;
            }
        }
        b.light[q] = ls;
        b.light_query[q] = k;
        b.closure_index[q] = k;
        b.wix[q] = dot(ls.wi, sp.s);
        b.wiy[q] = dot(ls.wi, sp.t);
        b.wiz[q] = dot(ls.wi, sp.n);
        ++q;
    }
    SpangleEvalBatch_v3 eval{q,
                             b.closure_index.data(),
                             b.wix.data(),
                             b.wiy.data(),
                             b.wiz.data(),
                             b.f_r.data(),
                             b.f_g.data(),
                             b.f_b.data(),
                             b.pdf.data(),
                             nullptr,
                             nullptr,
                             nullptr};
    if (sink.wants_glints(bounce)) sink.glint_outputs(q, eval.glint_r, eval.glint_g, eval.glint_b);
    if (q > 0) {
        call_plugin(mat.label(), "eval",
                    [&] { mat.model().eval(mat.instance(), ws.closure_data, &eval); });
        check_evals(eval, q, mat.bad_output());
    }
    return q;
}

/** Shadow rays towards a point on a light's surface end this many times 2^-24 of the larger end
 *  coordinate (2 to 4 of its ulps) short of it, besides a relative 1e-4: enough for the light's
 *  own surface far from the origin (a sphere light at 1e4 and 1e5 and an emissive quad seen
 *  edge-on at 1e4 within 0.25% of the same scene at the origin; 0: 10% and 36% dark), little
 *  enough that an occluder 2.2 cm from a quad light at 1e5 (2.7 cm of margin) still casts its
 *  shadow (32 let occluders 5 cm from a light at 1e5 through). Occluders closer to a light
 *  than that are missed: ignoring the sampled light's own surface in the occlusion filter
 *  would need no margin. */
constexpr float kEndUlps = 4.0f;

/** The unoccluded contribution of each of the q light queries that can add light, and its
 *  shadow ray; the rays of the whole batch are traced as one stream, and the light of those
 *  that arrive is added. */
template <class Sink>
void trace_shadows(const RenderJob& job, Workspace& ws, Sink& sink, const uint32_t* paths,
                   uint32_t q, uint32_t bounce, uint64_t& shadow_rays) {
    const ShadingBatch& b = ws.batch;
    PathBatch& p = ws.paths;
    ws.stream_path.clear();
    ws.shadow_contrib.clear();
    ws.stream_o.clear();
    ws.stream_d.clear();
    ws.stream_time.clear();
    ws.shadow_tmax.clear();
    sink.begin_shadows();
    const float scale = offset_scale(job);
    for (uint32_t j = 0; j < q; ++j) {
        const Vec3 f(b.f_r[j], b.f_g[j], b.f_b[j]);
        if (max_component(f) <= 0.0f) continue;
        const uint32_t i = paths[b.light_query[j]];
        const SurfacePoint& sp = p.surf[i];
        const LightSample& ls = b.light[j];
        float mis = ls.delta ? 1.0f : power_heuristic(ls.pdf, b.pdf[j]);
        if (job.strategy == Strategy::NeeOnly) mis = 1.0f;
        if (job.strategy == Strategy::BsdfOnly && !ls.delta) mis = 0.0f;
        if (mis <= 0.0f) continue;
        ws.stream_path.push_back(i);
        const float weight = std::fabs(b.wiz[j]) * mis / ls.pdf;
        ws.shadow_contrib.push_back(p.throughput[i] * f * ls.radiance * weight);
        sink.shadow_query(bounce, j, i, p.throughput[i], f, ls.radiance, weight, ls.group);
        Vec3 side;
        const Vec3 from = leaving_point(sp, ls.wi, side);
        const Vec3 o = offset_origin(from, side, scale) + side * sp.p_error;
        // A light at a finite distance: the shadow ray runs from the offset origin to the light's
        // point itself and stops just short of it. Along wi from the offset origin it would pass
        // beside that point, and near a sphere light's (or any emitter's) silhouette meet the
        // light's own surface well before it: in small scenes, where the offset is large against
        // the light, a good share of light samples were blocked by their own light.
        Vec3 d = ls.wi;
        float tmax = 1e30f;
        if (std::isfinite(ls.dist)) {
            const Vec3 lp = sp.p + ls.wi * ls.dist;
            const Vec3 to = lp - o;
            const float len = length(to);
            tmax = 0.0f;
            if (len > 0.0f && std::isfinite(len)) {
                d = to / len;
                tmax = len * (1.0f - 1e-4f);
                // A light with a surface (a sphere, an emissive mesh): short also of the
                // rounding of both ends' coordinates. Far from the origin its point (and its
                // surface, as Embree meets it) is known to a few ulps of its coordinates, more
                // than the relative margin (a scene at 1e4 lost 10% of its sphere and mesh
                // lights' light to shadow rays ending inside them). Never shorter than half the
                // way: a point or spot light has no surface, and keeps its occluders.
                if (!ls.delta) {
                    const float mag = std::max({std::fabs(lp.x), std::fabs(lp.y), std::fabs(lp.z),
                                                std::fabs(o.x), std::fabs(o.y), std::fabs(o.z)});
                    tmax = std::max(tmax - kEndUlps * 0x1p-24f * mag, 0.5f * len);
                }
            }
        }
        ws.stream_o.push_back(o);
        ws.stream_d.push_back(d);
        ws.stream_time.push_back(p.time[i]);
        ws.shadow_tmax.push_back(tmax);
    }
    const std::size_t rays = ws.stream_path.size();
    shadow_rays += rays;
    ws.stream_found.assign(rays, 0);
    if (job.scene->accel)
        job.scene->accel->occluded_stream(ws.stream_o.data(), ws.stream_d.data(),
                                          ws.shadow_tmax.data(), rays, ws.stream_found.data(),
                                          job.motion ? ws.stream_time.data() : nullptr,
                                          job.scene->cut_outs);
    for (std::size_t r = 0; r < rays; ++r) {
        const uint32_t path = ws.stream_path[r];
        // A shadow catcher's own light is the plate's: only how much of it others shadow is
        // kept, for its alpha.
        if (p.catcher[path] == 1) {
            if (bounce == 0) sink.catcher_light(path, ws.shadow_contrib[r], !ws.stream_found[r]);
            continue;
        }
        if (ws.stream_found[r]) continue;
        const float kc = clamp_factor(job, ws.shadow_contrib[r], bounce + 1);
        const Vec3 c = ws.shadow_contrib[r] * kc;
        p.radiance[path] += c;
        sink.unoccluded(r, path, c, kc);
    }
}

}  // namespace

template <class Sink>
void shade(const RenderJob& job, Workspace& ws, Sink& sink, const MaterialInstance& mat,
           const uint32_t* paths, uint32_t n, uint32_t bounce, uint64_t& shadow_rays) {
    const RenderScene& w = *job.scene;
    ws.batch.resize(n);
    if (mat.map_kind() != MapKind::None) apply_map(w, ws, mat, paths, n);
    // Interpolated or mapped normals that would reflect wo into the surface are bent back.
    for (uint32_t k = 0; k < n; ++k)
        keep_reflection_above(ws.paths.surf[paths[k]], -ws.paths.ray[paths[k]].d);
    fill_points(job, ws, paths, n);
    SpangleShadingBatch_v3 batch = abi_batch(ws.batch, n);
    if (!mat.textures().empty()) batch.param_values = lookup_textures(w, ws, mat, paths, n);
    prepare(ws, mat, batch, n);
    if (w.lights->empty()) return;
    const uint32_t q = sample_lights(job, ws, sink, mat, paths, n, bounce);
    trace_shadows(job, ws, sink, paths, q, bounce, shadow_rays);
}

template void shade<NullSink>(const RenderJob&, Workspace&, NullSink&, const MaterialInstance&,
                              const uint32_t*, uint32_t, uint32_t, uint64_t&);
template void shade<LayerSink>(const RenderJob&, Workspace&, LayerSink&, const MaterialInstance&,
                               const uint32_t*, uint32_t, uint32_t, uint64_t&);

}  // namespace spangle
