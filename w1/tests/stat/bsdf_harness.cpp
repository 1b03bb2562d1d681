#include "bsdf_harness.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace spangle::test {

BsdfHarness::BsdfHarness(const std::string& plugin, const std::string& model,
                         const std::vector<std::pair<std::string, std::vector<double>>>& numbers,
                         const std::vector<std::pair<std::string, std::string>>& strings)
    : color_(shipped_config()) {
    color_.set_working_space("lin_rec709");
    host_ = std::make_unique<HostServices>(color_, quiet_log());
    plugin_ = PluginLoader(plugin_search_path({})).open(plugin, {});
    model_ = plugin_->model(model);
    if (!model_) throw std::runtime_error("no model " + model);
    // Build a Material as a scene would, so that validation (ranges, defaults) applies too.
    Material m;
    m.name = "under_test";
    m.plugin = plugin;
    m.model = model;
    for (const auto& [name, v] : numbers) {
        ParamEntry p;
        p.name = name;
        p.kind = v.size() == 3 ? ParamEntry::Kind::Color : ParamEntry::Kind::Number;
        // Typed as the schema declares it, as the scene parser would have typed the TOML value.
        for (uint32_t k = 0; k < model_->param_count; ++k) {
            if (name != model_->params[k].name) continue;
            if (model_->params[k].type == SPANGLE_PARAM_BOOL) p.kind = ParamEntry::Kind::Bool;
            if (model_->params[k].type == SPANGLE_PARAM_INT) p.is_integer = true;
        }
        for (std::size_t i = 0; i < v.size(); ++i) p.number[i] = v[i];
        p.text = "lin_rec709";
        m.params.push_back(p);
    }
    for (const auto& [name, s] : strings) {
        ParamEntry p;
        p.name = name;
        p.kind = ParamEntry::Kind::String;
        p.text = s;
        m.params.push_back(p);
    }
    const ValidatedParams params = validate_params(*model_, m, color_);
    const SpangleParams_v3 view = params.view();
    char error[512] = {0};
    instance_ = model_->create(&view, host_->api(), error, sizeof(error));
    if (!instance_) throw std::runtime_error(std::string("create failed: ") + error);
    closure_.resize(model_->closure_size + 64);
}

BsdfHarness::~BsdfHarness() {
    if (instance_) model_->destroy(instance_);
}

void BsdfHarness::prepare(Vec3 wo, bool backface) {
    Point p;
    p.has_differentials = false;
    prepare(wo, p, backface);
}

void BsdfHarness::prepare(Vec3 wo, const Point& pt, bool backface) {
    const float zero = 0.0f;
    const uint32_t flags = (backface ? SPANGLE_SHADING_BACKFACE : 0u) |
                           (pt.has_differentials ? SPANGLE_SHADING_HAS_DIFFERENTIALS : 0u) |
                           (pt.no_uv ? SPANGLE_SHADING_NO_UV : 0u) |
                           (pt.roughness_floor > 0.0f ? SPANGLE_SHADING_ROUGHNESS_FLOOR : 0u);
    const uint32_t id = 0;
    const SpangleShadingBatch_v3 b{1,
                                   &zero,
                                   &zero,
                                   &zero,
                                   &wo.x,
                                   &wo.y,
                                   &wo.z,
                                   &pt.u,
                                   &pt.v,
                                   &pt.dudx,
                                   &pt.dudy,
                                   &pt.dvdx,
                                   &pt.dvdy,
                                   &pt.uv_area,
                                   &pt.p_obj.x,
                                   &pt.p_obj.y,
                                   &pt.p_obj.z,
                                   &pt.n_obj.x,
                                   &pt.n_obj.y,
                                   &pt.n_obj.z,
                                   &pt.dpdx_obj.x,
                                   &pt.dpdx_obj.y,
                                   &pt.dpdx_obj.z,
                                   &pt.dpdy_obj.x,
                                   &pt.dpdy_obj.y,
                                   &pt.dpdy_obj.z,
                                   &flags,
                                   &id,
                                   nullptr,
                                   &pt.roughness_floor};
    arena_.reset();
    SpangleArena_v3 arena = arena_.api();
    model_->prepare(instance_, &b, closure_.data(), &arena);
}

void BsdfHarness::eval(const std::vector<Sample>& samples, std::vector<Vec3>& f,
                       std::vector<float>& pdf) const {
    std::vector<Vec3> wi;
    wi.reserve(samples.size());
    for (const Sample& s : samples) wi.push_back(s.wi);
    eval(wi, f, pdf);
}

BsdfHarness::Albedo BsdfHarness::albedo(uint32_t n, uint64_t seed, int channel,
                                        double transmission_scale) const {
    double sum = 0.0, sum2 = 0.0;
    for (const Sample& s : sample(n, seed)) {
        double w = 0.0;
        if (s.flags != 0 && s.pdf > 0.0f) {
            w = static_cast<double>(s.f[channel]) * std::fabs(s.wi.z) / s.pdf;
            if (s.flags & SPANGLE_SAMPLE_TRANSMISSION) w *= transmission_scale;
        }
        sum += w;
        sum2 += w * w;
    }
    Albedo a;
    a.mean = sum / n;
    a.se = std::sqrt(std::max(0.0, sum2 / n - a.mean * a.mean) / n);
    return a;
}

std::vector<BsdfHarness::Sample> BsdfHarness::sample(uint32_t n, uint64_t seed) const {
    std::vector<float> u0(n), u1(n), u2(n), x(n), y(n), z(n), r(n), g(n), b(n), pdf(n);
    std::vector<uint32_t> flags(n), idx(n, 0);
    for (uint32_t i = 0; i < n; ++i) {
        u0[i] = sample_1d(seed, i, 0, 0);
        u1[i] = sample_1d(seed, i, 0, 1);
        u2[i] = sample_1d(seed, i, 0, 2);
    }
    SpangleSampleBatch_v3 q{n,        idx.data(), u0.data(),    u1.data(), u2.data(),
                            x.data(), y.data(),   z.data(),     r.data(),  g.data(),
                            b.data(), pdf.data(), flags.data(), nullptr,   nullptr,
                            nullptr,  nullptr};
    model_->sample(instance_, closure_.data(), &q);
    std::vector<Sample> out(n);
    for (uint32_t i = 0; i < n; ++i)
        out[i] = {{x[i], y[i], z[i]}, {r[i], g[i], b[i]}, pdf[i], flags[i]};
    return out;
}

void BsdfHarness::eval(const std::vector<Vec3>& wi, std::vector<Vec3>& f,
                       std::vector<float>& pdf) const {
    const auto n = static_cast<uint32_t>(wi.size());
    std::vector<float> x(n), y(n), z(n), r(n), g(n), b(n);
    std::vector<uint32_t> idx(n, 0);
    pdf.assign(n, 0.0f);
    for (uint32_t i = 0; i < n; ++i) {
        x[i] = wi[i].x;
        y[i] = wi[i].y;
        z[i] = wi[i].z;
    }
    SpangleEvalBatch_v3 q{n,        idx.data(), x.data(),   y.data(), z.data(), r.data(),
                          g.data(), b.data(),   pdf.data(), nullptr,  nullptr,  nullptr};
    if (n > 0) model_->eval(instance_, closure_.data(), &q);
    f.resize(n);
    for (uint32_t i = 0; i < n; ++i) f[i] = {r[i], g[i], b[i]};
}

}  // namespace spangle::test
