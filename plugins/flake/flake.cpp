// The flake material plugin (model "flake"): base + stochastic mirror flakes + optional clear
// coat. This file is the material ABI around the model: batches in, closures and samples out,
// statistics for --stats. The parameters are in schema.h, the model in material.h and the files
// it names (the field, the discrete, counted and smooth lobes, the coat, the palette).

#include <spangle/plugin.h>

#include <chrono>
#include <cstring>
#include <initializer_list>
#include <new>
#include <string>

#include "../common/plugin_support.h"
#include "material.h"
#include "schema.h"

namespace {

using namespace spangle;
using namespace spangle::flake;
using plugin_support::set_error;

using Clock = std::chrono::steady_clock;
uint64_t ns_since(Clock::time_point t0) {
    return static_cast<uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count());
}

/** Whether parameter `name` differs from its schema default (the host fills in defaults, so a
 *  value set to the default cannot be told from one left out: it does nothing either way). */
bool changed(const SpangleParams_v3* p, const char* name) {
    const SpangleParamValue_v3* v = plugin_support::find_param(p, name);
    if (!v) return false;
    for (const SpangleParamDesc_v3& d : kParams) {
        if (std::strcmp(d.name, name) != 0) continue;
        if (d.type == SPANGLE_PARAM_STRING)
            return std::strcmp(v->string ? v->string : "",
                               d.default_string ? d.default_string : "") != 0;
        const int n = d.type == SPANGLE_PARAM_COLOR ? 3 : 1;
        for (int c = 0; c < n; ++c)
            if (v->number[c] != d.default_value[c]) return true;
        return false;
    }
    return false;
}

/** Warns about parameters set away from their defaults that the other parameters make inert
 *  (coat_ior while coat is off, flakes2_* at flakes2_weight 0, ...): the scene renders as if they
 *  were not there, which an artist tuning them would otherwise not learn. */
void warn_inert(const SpangleParams_v3* p, const SpangleHost_v3* host) {
    if (!host || !host->log) return;
    using plugin_support::param_number;
    using plugin_support::param_string;
    const auto check = [&](bool inert, std::initializer_list<const char*> names,
                           const char* because) {
        if (!inert) return;
        std::string set;
        for (const char* n : names)
            if (changed(p, n)) {
                if (!set.empty()) set += ", ";
                set += n;
            }
        if (set.empty()) return;
        const std::string msg = set + (set.find(',') == std::string::npos ? " has" : " have") +
                                " no effect: " + because;
        host->log(host->context, SPANGLE_LOG_WARNING, msg.c_str());
    };
    const std::string fresnel = param_string(p, "fresnel");
    check(param_number(p, "coat") == 0.0, {"coat_ior", "coat_roughness"},
          "the coat is off (coat = true adds it)");
    check(param_number(p, "film_thickness_max") == 0.0, {"film_thickness_min", "film_ior"},
          "the film is off (film_thickness_max > 0 adds it)");
    check(param_number(p, "color_table") == 0.0,
          {"table_size", "table_s", "table_l", "table_space", "hue_spread"},
          "the colour table is off (color_table = true turns it on)");
    check(param_number(p, "color_table") != 0.0, {"flake_color"},
          "the colour table gives the flakes their colours");
    check(param_number(p, "flakes2_weight") == 0.0,
          {"flakes2_density", "flakes2_color", "flakes2_roughness", "flakes2_gamma"},
          "there is no second population (flakes2_weight > 0 adds it)");
    check(fresnel != "conductor", {"preset"},
          "the preset is the metal of conductor flakes (fresnel = \"conductor\")");
    check(fresnel != "dielectric", {"flake_ior"},
          "flake_ior is the index of dielectric flakes (fresnel = \"dielectric\")");
    check(fresnel != "schlick", {"flake_f0"},
          "flake_f0 is the reflectance of Schlick flakes (fresnel = \"schlick\")");
    check(param_number(p, "flake_size") == 0.0, {"flake_shape"},
          "flakes are points (flake_size > 0 gives them an outline)");
    check(param_string(p, "algorithm") == "enumerate",
          {"exact_flakes", "stand_ins", "sparse_flakes"},
          "they steer the tree algorithm and this material enumerates");
}

void* flake_create(const SpangleParams_v3* p, const SpangleHost_v3* host, char* error,
                   uint32_t cap) {
    auto* m = new (std::nothrow) Material;
    if (!m) {
        set_error(error, cap, "out of memory");
        return nullptr;
    }
    std::string why;
    if (!init_material(*m, p, host, why)) {
        set_error(error, cap, why);
        delete m;
        return nullptr;
    }
    // Only for a material made: a refused one's error says what to change (film_thickness_min
    // alone was warned inert, then refused for the same reason).
    warn_inert(p, host);
    return m;
}

void flake_destroy(void* instance) {
    delete static_cast<Material*>(instance);
}

void flake_prepare(const void* inst, const SpangleShadingBatch_v3* b, void* closures,
                   SpangleArena_v3* arena) {
    const auto t0 = Clock::now();
    const Material& m = *static_cast<const Material*>(inst);
    auto* out = static_cast<Closure*>(closures);
    PointStats st;
    // Schema entries 0 and 1: base_color and flake_weight, the two a texture may vary.
    const float* base = b->param_values ? b->param_values[0] : nullptr;
    const float* weight = b->param_values ? b->param_values[1] : nullptr;
    for (uint32_t i = 0; i < b->count; ++i) {
        PointInput in;
        for (int c = 0; c < 3; ++c) in.base[c] = base ? base[3 * i + c] : m.base[c];
        in.weight = weight ? weight[i] : m.flake_weight;
        in.wo = {b->wo_x[i], b->wo_y[i], b->wo_z[i]};
        in.u = b->u[i];
        in.v = b->v[i];
        in.du_dx = b->du_dx[i];
        in.du_dy = b->du_dy[i];
        in.dv_dx = b->dv_dx[i];
        in.dv_dy = b->dv_dy[i];
        in.uv_area = b->uv_area[i];
        in.p_obj = {b->obj_p_x[i], b->obj_p_y[i], b->obj_p_z[i]};
        in.n_obj = {b->obj_n_x[i], b->obj_n_y[i], b->obj_n_z[i]};
        in.dpdx_obj = {b->obj_dpdx_x[i], b->obj_dpdx_y[i], b->obj_dpdx_z[i]};
        in.dpdy_obj = {b->obj_dpdy_x[i], b->obj_dpdy_y[i], b->obj_dpdy_z[i]};
        in.flags = b->flags[i];
        in.roughness_floor = plugin_support::roughness_floor(b, i);
        prepare_point(m, in, out[i], arena, st);
    }
    m.points += b->count;
    m.discrete += st.discrete;
    m.blended += st.blended;
    m.smooth_only += st.smooth;
    m.truncated += st.truncated;
    m.flakes_cached += st.cached;
    m.flakes_aggregated += st.aggregated;
    m.aggregates += st.aggregates;
    m.sparse_enumerated += st.sparse_enumerated;
    m.sparse_faded += st.sparse_faded;
    m.lambda_milli_sum += st.lambda_milli;
    m.lambda_count += st.lambda_count;
    m.ns_prepare += ns_since(t0);
}

void flake_eval(const void* inst, const void* closures, SpangleEvalBatch_v3* q) {
    const auto t0 = Clock::now();
    const Material& m = *static_cast<const Material*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        float f[3], pdf, glint[3];
        eval_material(m, cl[q->closure_index ? q->closure_index[i] : i],
                      {q->wi_x[i], q->wi_y[i], q->wi_z[i]}, f, pdf, q->glint_r ? glint : nullptr);
        if (q->glint_r) {
            q->glint_r[i] = glint[0];
            q->glint_g[i] = glint[1];
            q->glint_b[i] = glint[2];
        }
        q->f_r[i] = f[0];
        q->f_g[i] = f[1];
        q->f_b[i] = f[2];
        q->pdf[i] = pdf;
    }
    m.ns_eval += ns_since(t0);
}

void flake_sample(const void* inst, const void* closures, SpangleSampleBatch_v3* q) {
    const auto t0 = Clock::now();
    const Material& m = *static_cast<const Material*>(inst);
    const auto* cl = static_cast<const Closure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        V3 wi;
        float f[3], pdf;
        uint32_t flags;
        float glint[3];
        sample_material(m, cl[q->closure_index ? q->closure_index[i] : i], q->u0[i], q->u1[i],
                        q->u2[i], wi, f, pdf, flags, q->glint_r ? glint : nullptr);
        if (q->glint_r) {
            q->glint_r[i] = glint[0];
            q->glint_g[i] = glint[1];
            q->glint_b[i] = glint[2];
        }
        q->wi_x[i] = wi.x;
        q->wi_y[i] = wi.y;
        q->wi_z[i] = wi.z;
        q->f_r[i] = f[0];
        q->f_g[i] = f[1];
        q->f_b[i] = f[2];
        q->pdf[i] = pdf;
        q->flags[i] = flags;
        if (q->eta) q->eta[i] = 1.0f;
    }
    m.ns_sample += ns_since(t0);
}

uint32_t flake_stats(const void* inst, SpangleStat_v3* out, uint32_t capacity) {
    const Material& m = *static_cast<const Material*>(inst);
    const double points = static_cast<double>(m.points.load());
    const double per = points > 0 ? 1.0 / points : 0.0;
    const auto per_point = [&](const std::atomic<uint64_t>& x) {
        return static_cast<double>(x.load()) * per;
    };
    const SpangleStat_v3 s[] = {
        {"shading points", points},
        {"mean expected flakes per footprint (lambda)",
         m.lambda_count ? static_cast<double>(m.lambda_milli_sum.load()) * 1e-3 /
                              static_cast<double>(m.lambda_count.load())
                        : 0.0},
        {"flakes in reflection caches per shading point", per_point(m.flakes_cached)},
        {"flakes counted in aggregates per shading point", per_point(m.flakes_aggregated)},
        {"aggregates per shading point", per_point(m.aggregates)},
        {"fraction discrete", per_point(m.discrete)},
        {"fraction blended", per_point(m.blended)},
        {"fraction smooth", per_point(m.smooth_only)},
        {"fraction beyond the algorithm's bound (smooth)", per_point(m.truncated)},
        {"fraction enumerated for sparse lobes (tree, sparse_flakes)",
         per_point(m.sparse_enumerated)},
        {"fraction fading from counted to enumerated (tree)", per_point(m.sparse_faded)},
        {"ns per point in prepare", per_point(m.ns_prepare)},
        {"ns per point in eval", per_point(m.ns_eval)},
        {"ns per point in sample", per_point(m.ns_sample)},
        {"smooth lobe tables built (ms, 0: read from the table cache)", m.smooth.build_ms},
        {"smooth lobe tables read from the table cache", m.smooth.from_cache ? 1.0 : 0.0},
    };
    const auto n = static_cast<uint32_t>(sizeof(s) / sizeof(s[0]));
    for (uint32_t i = 0; i < std::min(n, capacity); ++i) out[i] = s[i];
    return n;
}

uint32_t flake_requirements(const void* inst) {
    const Material& m = *static_cast<const Material*>(inst);
    switch (m.space) {
        case Material::Space::Uv:
        case Material::Space::World:
            return SPANGLE_REQUIRES_UV;
        case Material::Space::Object:
            return SPANGLE_REQUIRES_OBJECT_SPACE;
        default:  // auto: object space where a triangle has no usable uvs
            return SPANGLE_REQUIRES_OBJECT_SPACE_WITHOUT_UV;
    }
}

const SpangleMaterialModel_v3 kModels[] = {
    {"flake",
     "stochastic mirror flakes over a diffuse base, optional clear coat (Atanasov and Koylazov "
     "2016)",
     kParams, kParamCount, sizeof(Closure), flake_create, flake_destroy, flake_prepare, flake_eval,
     flake_sample, flake_stats, flake_requirements},
};

const SpangleMaterialPlugin_v3 kPlugin = {
    SPANGLE_MATERIAL_ABI_VERSION,
    sizeof(SpangleMaterialPlugin_v3),
    "flake",
    "stochastic mirror flakes: glitter, metallic car paint, sparkling snow",
    kModels,
    1,
};

}  // namespace

extern "C" SPANGLE_PLUGIN_EXPORT const SpangleMaterialPlugin_v3* spangle_material_plugin(
    uint32_t host_abi_version) {
    return host_abi_version == SPANGLE_MATERIAL_ABI_VERSION ? &kPlugin : nullptr;
}
