#include "coat.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <thread>
#include <vector>

#include "table_cache.h"

namespace spangle::flake {

namespace {

constexpr int kGrid = 96;                  ///< visible-normal quadrature per side
constexpr float kQuadratureBound = 2e-3f;  ///< measured error bound of that quadrature

float coat_node_cos(int i) {
    const float x = static_cast<float>(i) / static_cast<float>(Coat::kNodes - 1);
    return std::max(1e-6f, x * x);
}

/** The rough coat's albedo at cos_theta: E over visible normals of F G2 / G1, midpoint rule. */
double rough_albedo(float cos_theta, float ior, float alpha) {
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta)), 0.0f, cos_theta};
    const float g1 = mf::ggx_g1(wo, alpha, alpha);
    double sum = 0.0;
    for (int a = 0; a < kGrid; ++a)
        for (int b = 0; b < kGrid; ++b) {
            const float u0 = (static_cast<float>(a) + 0.5f) / kGrid,
                        u1 = (static_cast<float>(b) + 0.5f) / kGrid;
            const V3 h = mf::ggx_sample_visible(wo, alpha, alpha, u0, u1);
            const V3 wi = mf::reflect(wo, h);
            if (!(wi.z > 0.0f)) continue;
            sum += static_cast<double>(mf::fresnel_dielectric(mf::dot(wo, h), ior) *
                                       mf::ggx_g2(wo, wi, alpha, alpha) / g1);
        }
    return sum / (kGrid * kGrid);
}

}  // namespace

void Coat::init(bool on_, float ior_, float roughness, const TableCache* cache) {
    on = on_;
    ior = ior_;
    smooth = roughness < mf::kDeltaAlpha;
    alpha = std::max(mf::kDeltaAlpha, roughness);
    e_avg = 0.0f;
    if (!on) return;
    if (smooth) {
        set_average();
        return;
    }
    TableKey key("rough coat albedo");
    key.add(ior);
    key.add(alpha);
    std::vector<uint8_t> bytes;
    if (cache && cache->load(key, bytes) && bytes.size() == sizeof(albedo)) {
        std::memcpy(albedo, bytes.data(), sizeof(albedo));
        set_average();
        return;
    }
    // The nodes are independent: one thread each (the result does not depend on their number).
    const int threads = table_threads();
    std::vector<std::thread> pool;
    for (int w = 0; w < threads; ++w)
        pool.emplace_back([&, w] {
            for (int i = w; i < kNodes; i += threads)
                albedo[i] =
                    std::min(1.0f, static_cast<float>(rough_albedo(coat_node_cos(i), ior, alpha)) +
                                       kQuadratureBound);
        });
    for (auto& t : pool) t.join();
    set_average();
    if (cache) {
        bytes.resize(sizeof(albedo));
        std::memcpy(bytes.data(), albedo, sizeof(albedo));
        cache->store(key, bytes);
    }
}

void Coat::set_average() {
    // The integral of albedo_at() as it reads (steps for a rough coat, Fresnel for a smooth
    // one): midpoints fine enough that its error is far below a float's.
    constexpr int kN = 8192;
    double sum = 0.0;
    for (int i = 0; i < kN; ++i) {
        const float mu = (static_cast<float>(i) + 0.5f) / kN;
        sum += 2.0 * static_cast<double>(albedo_at(mu)) * static_cast<double>(mu) / kN;
    }
    e_avg = static_cast<float>(std::min(sum, 0.999));
}

float Coat::albedo_at(float cos_theta) const {
    if (!on) return 0.0f;
    if (smooth) return mf::fresnel_dielectric(cos_theta, ior);
    const float x = std::sqrt(std::clamp(cos_theta, 0.0f, 1.0f)) * (kNodes - 1);
    const int i = std::min(static_cast<int>(x), kNodes - 2);
    return std::max(albedo[i], albedo[i + 1]);
}

void Coat::eval_rough(V3 wo, V3 wi, float& f, float& pdf) const {
    f = pdf = 0.0f;
    if (!(wo.z > 0.0f) || !(wi.z > 0.0f)) return;
    const V3 h = mf::normalize(wo + wi);
    const float d = mf::ggx_d(h, alpha, alpha);
    f = mf::fresnel_dielectric(mf::dot(wo, h), ior) * d * mf::ggx_g2(wo, wi, alpha, alpha) /
        (4.0f * wo.z * wi.z);
    pdf = mf::ggx_reflection_pdf(wo, h, alpha, alpha);
}

bool Coat::sample_rough(V3 wo, float u0, float u1, V3& wi) const {
    wi = mf::ggx_sample_reflection(wo, alpha, alpha, u0, u1);
    return wi.z > 0.0f;
}

CoatFloors::CoatFloors(const Coat& own, const TableCache& cache)
    : own_(own), cache_(cache.dir(), cache.max_bytes()) {}

const Coat& CoatFloors::at(float floor) const {
    if (!own_.on || !(floor > own_.roughness())) return own_;
    int k = 0;
    while (k + 1 < kCount && kLevels[k] < floor) ++k;
    if (!own_.smooth && kLevels[k] <= own_.alpha) return own_;
    std::call_once(once_[k], [&] { coats_[k].init(true, own_.ior, kLevels[k], &cache_); });
    return coats_[k];
}

}  // namespace spangle::flake
