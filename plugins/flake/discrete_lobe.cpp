#include "discrete_lobe.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <thread>

#include "table_cache.h"

namespace spangle::flake {

void flush_entries(V3 wo, float alpha, EntryBatch& b, std::vector<CacheEntry>& out) {
    constexpr uint32_t kSize = EntryBatch::kSize;
    const uint32_t n = std::min(b.n, kSize);
    b.n = 0;
    // Normals, the cosine with wo, the mirror direction's height and the weight: four at a time.
    alignas(64) float mx[kSize], my[kSize], mz[kSize], cos_om[kSize], rz[kSize], w[kSize];
    for (uint32_t i = 0; i < n; ++i) flake_normal_of(alpha, b.s[i], b.t[i], mx[i], my[i], mz[i]);
    for (uint32_t i = 0; i < n; ++i) {
        cos_om[i] = wo.x * mx[i] + wo.y * my[i] + wo.z * mz[i];
        rz[i] = mz[i] * (2.0f * cos_om[i]) - wo.z;
        w[i] = cos_om[i] / mz[i];
    }
    // The rest per flake (its Fresnel table and colour are its own), into a block of its own,
    // every flake written and the cursor moved past those kept: whether a flake faces away or
    // reflects under the horizon is a coin toss near grazing, and a branch on it was
    // mispredicted as often. The block is appended in one copy. (A flake is skipped where
    // cos_om <= 0 or rz <= 0, written so: one whose wo is not a number is kept, as it was.)
    CacheEntry kept_entries[kSize];
    uint32_t kept = 0, marked = 0;
    for (uint32_t i = 0; i < n; ++i) {
        const bool keep = !((cos_om[i] <= 0.0f) | (rz[i] <= 0.0f));
        const float c2 = 2.0f * cos_om[i];
        float f[3];
        b.fresnel[i]->eval(cos_om[i], f);
        float rgb[3];
        for (int c = 0; c < 3; ++c) rgb[c] = w[i] * b.col[i][c] * f[c];
        CacheEntry& e = kept_entries[kept];
        e.r = {mx[i] * c2 - wo.x, my[i] * c2 - wo.y, rz[i]};
        const float scale = b.scale[i];
        for (int c = 0; c < 3; ++c) e.rgb[c] = rgb[c] * scale;
        e.lum = std::max(0.0f, luminance(rgb)) * scale;
        e.w = w[i] * scale;
        marked += (keep & b.marked[i]) ? 1u : 0u;
        kept += keep ? 1u : 0u;
    }
    b.entered_marked += marked;
    out.insert(out.end(), kept_entries, kept_entries + kept);
}

Cone::Cone(float gamma_rad) {
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
    threshold = 4.0f * sin2_half;
    solid_angle = 4.0f * mf::kPi * sin2_half;
}

void cone_sums(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float rgb[3], float& lum) {
    rgb[0] = rgb[1] = rgb[2] = lum = 0.0f;
    for (uint32_t j = 0; j < lobe.count; ++j) {
        const CacheEntry& e = lobe.entries[j];
        const float dx = wi.x - e.r.x, dy = wi.y - e.r.y, dz = wi.z - e.r.z;
        if (dx * dx + dy * dy + dz * dz > cone.threshold) continue;
        rgb[0] += e.rgb[0];
        rgb[1] += e.rgb[1];
        rgb[2] += e.rgb[2];
        lum += e.lum;
    }
}

void eval_discrete(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float norm, float f[3],
                   float& pdf) {
    f[0] = f[1] = f[2] = 0.0f;
    pdf = 0.0f;
    if (lobe.count == 0 || !(norm > 0.0f) || wi.z <= 0.0f) return;
    float sum[3], lum;
    cone_sums(lobe, cone, wi, sum, lum);
    const float k = 1.0f / (norm * cone.solid_angle * wi.z);
    for (int c = 0; c < 3; ++c) f[c] = sum[c] * k;
    pdf = lobe.lum_sum > 0.0f ? lum / (lobe.lum_sum * cone.solid_angle) : 0.0f;
}

V3 sample_cone(V3 r, float sin2_half, float c0, float c1) {
    // cos(theta) = 1 - c0 (1 - cos gamma), with 1 - cos gamma = 2 sin^2(gamma/2).
    const float one_minus_cos = c0 * 2.0f * sin2_half;
    const float cos_t = 1.0f - one_minus_cos;
    const float sin_t = std::sqrt(std::max(0.0f, one_minus_cos * (2.0f - one_minus_cos)));
    const float phi = 2.0f * mf::kPi * c1;
    // Orthonormal basis around r (Duff et al. 2017).
    const float sign = std::copysign(1.0f, r.z);
    const float a = -1.0f / (sign + r.z), b = r.x * r.y * a;
    const V3 s{1.0f + sign * r.x * r.x * a, sign * b, -sign * r.x};
    const V3 t{b, sign + r.y * r.y * a, -r.y};
    return mf::normalize(s * (sin_t * std::cos(phi)) + t * (sin_t * std::sin(phi)) + r * cos_t);
}

bool sample_discrete(const DiscreteLobe& lobe, const Cone& cone, float u0, float u1, float u2,
                     V3& wi) {
    if (lobe.count == 0 || !(lobe.lum_sum > 0.0f)) return false;
    // Binary search, bounded by the table; u0 = 0 and u0 -> 1 both land on valid entries.
    const float target = u0 * lobe.lum_sum;
    const float* it = std::upper_bound(lobe.cdf, lobe.cdf + lobe.count, target);
    const auto j = static_cast<uint32_t>(std::min<std::ptrdiff_t>(it - lobe.cdf, lobe.count - 1));
    wi = sample_cone(lobe.entries[j].r, cone.sin2_half, u1, u2);
    return wi.z > 0.0f;
}

double cache_share_exact(float alpha, float cos_o) {
    const double c = std::clamp(static_cast<double>(cos_o), 0.0, 1.0);
    if (!(c > 0.0)) return 0.5;
    const double s = std::sqrt(std::max(0.0, 1.0 - c * c));
    const double a2 = static_cast<double>(alpha) * static_cast<double>(alpha);
    // Even in phi: the half turn [0, pi], its ends weighted 1/2.
    constexpr int kSteps = 512;
    double sum = 0.0;
    for (int i = 0; i <= kSteps; ++i) {
        const double phi = std::numbers::pi * i / kSteps;
        const double x = s * std::cos(phi);
        const double a = std::sqrt(x * x + c * c);
        // T = tan(pi/4 + delta/2) = (a + x) / c, written without cancellation where x < 0.
        const double t = x >= 0.0 ? (a + x) / c : c / (a - x);
        const double term = t * t / (a2 + t * t);
        sum += (i == 0 || i == kSteps) ? 0.5 * term : term;
    }
    return sum / kSteps;
}

void CacheShare::init(float alpha) {
    for (int i = 0; i < kNodes; ++i)
        at_node[i] = static_cast<float>(
            cache_share_exact(alpha, static_cast<float>(i) / static_cast<float>(kNodes - 1)));
}

float CacheShare::at(float cos_o) const {
    return interpolate_nodes(at_node, kNodes, cos_o);
}

}  // namespace spangle::flake

namespace spangle::flake {

namespace {

/** The flakes that enter a view's cache, by quadrature over the disk of flake_normal() (uniform
 *  in rho^2 and phi, the half turn: the view is in the xz plane), gathered into bins of w
 *  (log-spaced): each bin's probability, E[w] and E[w a] over it. */
struct WeightBins {
    static constexpr int kBins = 64;
    double q[kBins] = {}, qw[kBins] = {}, qwa[kBins][3] = {};
    double plain[3] = {}, mass = 0;  ///< E[a] and the probability of entering, over the bins
};

void gather_bins(float alpha, const FresnelTable& fresnel, bool shadowing, V3 wo, WeightBins& b) {
    // Per ring of tilt theta the flakes that enter are those of azimuth |phi| < phi_c, where
    // cos(phi_c) = -cot(2 theta) cos_o / sin_o (cache_share_exact's condition solved for phi),
    // so the midpoint rule in phi runs over [0, phi_c] and cuts nothing. In tan(theta) = T every
    // flake of a ring enters below T1 = (sqrt(1 + c^2) - 1) / c and none above
    // T2 = (sqrt(1 + c^2) + 1) / c (c = cot theta_o); with T = alpha rho / v, v = sqrt(1 - rho^2)
    // the unstretched normal's height, those are v1 = alpha / sqrt(T1^2 + alpha^2) and v2 < v1.
    // Rings: [v1, 1] by the midpoint rule, [v2, v1] (where phi_c falls from pi to 0 with square-
    // root ends) by v = v2 + (v1 - v2) (1 - cos(pi x)) / 2; each ring's mass is 2 v dv (rho^2 is
    // uniform). A fixed grid in rho^2 and phi integrated w (which grows as 1 / v at the rim) and
    // the cut with 1-2% errors at grazing views.
    constexpr int kFull = 16, kBand = 24, kPhi = 32;
    struct Ring {
        double v, mass;
    };
    Ring rings[kFull + kBand];
    const double a = static_cast<double>(alpha);
    const double cot_o = static_cast<double>(wo.z) / std::max(1e-12, static_cast<double>(wo.x));
    const double root = std::sqrt(1.0 + cot_o * cot_o);
    const double t1 = cot_o / (root + 1.0), t2 = (root + 1.0) / cot_o;
    const double v1 = a / std::sqrt(t1 * t1 + a * a), v2 = a / std::sqrt(t2 * t2 + a * a);
    for (int i = 0; i < kFull; ++i) {
        const double v = v1 + (1.0 - v1) * (i + 0.5) / kFull;
        rings[i] = {v, 2.0 * v * (1.0 - v1) / kFull};
    }
    for (int i = 0; i < kBand; ++i) {
        const double x = (i + 0.5) / kBand;
        const double v = v2 + (v1 - v2) * 0.5 * (1.0 - std::cos(std::numbers::pi * x));
        const double dv = (v1 - v2) * 0.5 * std::numbers::pi * std::sin(std::numbers::pi * x);
        rings[kFull + i] = {v, 2.0 * v * dv / kBand};
    }
    struct Point {
        double q, w, a[3];
    };
    std::vector<Point> pts;
    pts.reserve((kFull + kBand) * kPhi);
    double w_lo = INFINITY, w_hi = 0.0;
    for (const Ring& ring : rings) {
        const double v = ring.v;
        if (!(v > 0.0) || !(ring.mass > 0.0)) continue;
        const double rho2 = std::max(0.0, 1.0 - v * v);
        const double tan_t = a * std::sqrt(rho2) / v;
        // cot(2 theta) = (1 - tan^2) / (2 tan).
        const double bound = tan_t > 0.0 ? -(1.0 - tan_t * tan_t) / (2.0 * tan_t) * cot_o
                                         : -std::numeric_limits<double>::infinity();
        const double phi_c = bound <= -1.0  ? std::numbers::pi
                             : bound >= 1.0 ? 0.0
                                            : std::acos(bound);
        if (!(phi_c > 0.0)) continue;
        const double q = ring.mass * phi_c / std::numbers::pi / kPhi;
        const auto rho = static_cast<float>(std::sqrt(rho2));
        const auto z = static_cast<float>(v);
        for (int j = 0; j < kPhi; ++j) {
            const auto phi = static_cast<float>(phi_c * (j + 0.5) / kPhi);
            const float x = rho * std::cos(phi), y = rho * std::sin(phi);
            const V3 m = mf::normalize(V3{alpha * x, alpha * y, z});
            const float cos_om = mf::dot(wo, m);
            const V3 r = m * (2.0f * cos_om) - wo;
            if (cos_om <= 0.0f) continue;
            float f[3];
            fresnel.eval(cos_om, f);
            const double g =
                shadowing && r.z > 0.0f ? static_cast<double>(mf::ggx_g1(r, alpha, alpha)) : 1.0;
            Point p{q, static_cast<double>(cos_om / m.z), {}};
            for (int ch = 0; ch < 3; ++ch) p.a[ch] = static_cast<double>(f[ch]) * g;
            pts.push_back(p);
            w_lo = std::min(w_lo, p.w);
            w_hi = std::max(w_hi, p.w);
        }
    }
    const double lo = std::log(std::max(w_lo, 1e-9));
    const double span = std::max(1e-9, std::log(std::max(w_hi, 1e-9)) - lo);
    for (const Point& p : pts) {
        const int k = std::clamp(
            static_cast<int>((std::log(std::max(p.w, 1e-9)) - lo) / span * WeightBins::kBins), 0,
            WeightBins::kBins - 1);
        b.q[k] += p.q;
        b.qw[k] += p.q * p.w;
        for (int c = 0; c < 3; ++c) {
            b.qwa[k][c] += p.q * p.w * p.a[c];
            b.plain[c] += p.q * p.a[c];
        }
        b.mass += p.q;
    }
    if (b.mass > 0.0)
        for (double& v : b.plain) v /= b.mass;
}

}  // namespace

void SparseAlbedo::build_node(int i, const FresnelTable& fresnel) {
    const float cos_o = std::max(1e-3f, static_cast<float>(i) / (kNodes - 1));
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - cos_o * cos_o)), 0.0f, cos_o};
    WeightBins b;
    gather_bins(alpha, fresnel, shadowing, wo, b);
    // Normalised to the entering flakes; each bin at its mean w.
    double sum_w = 0.0, sum_wa[3] = {};
    int first = -1, last = -1;
    for (int k = 0; k < WeightBins::kBins; ++k) {
        if (!(b.q[k] > 0.0)) continue;
        if (first < 0) first = k;
        last = k;
        sum_w += b.qw[k];
        for (int c = 0; c < 3; ++c) sum_wa[c] += b.qwa[k][c];
    }
    double far[3] = {1.0, 1.0, 1.0};
    if (first >= 0 && sum_w > 0.0)
        for (int c = 0; c < 3; ++c) far[c] = sum_wa[c] / sum_w;
    // E[R | K] for K >= 2: the trapezoid rule in s = log t over the range where the
    // integrands live (t w from 1e-3 at the largest w to 40 at the smallest).
    double num[kMaxK][3] = {}, den[kMaxK] = {};
    if (first >= 0) {
        const double w_min = b.qw[first] / b.q[first], w_max = b.qw[last] / b.q[last];
        const double s0 = std::log(1e-3 / w_max), s1 = std::log(40.0 / w_min);
        constexpr double kStep = 0.25;
        const int steps = static_cast<int>(std::ceil((s1 - s0) / kStep));
        for (int n = 0; n <= steps; ++n) {
            const double t = std::exp(s0 + kStep * n);
            double l = 0.0, nw = 0.0, m[3] = {};
            for (int k = first; k <= last; ++k) {
                if (!(b.q[k] > 0.0)) continue;
                const double e = std::exp(-t * b.qw[k] / b.q[k]);
                l += b.q[k] * e;
                nw += b.qw[k] * e;
                for (int c = 0; c < 3; ++c) m[c] += b.qwa[k][c] * e;
            }
            l /= b.mass;
            const double end = (n == 0 || n == steps) ? 0.5 : 1.0;
            double lk = l;  // L^(K-1), from K = 2
            for (int K = 2; K <= kMaxK; ++K) {
                const double g = end * t * K * lk / b.mass;
                den[K - 1] += g * nw;
                for (int c = 0; c < 3; ++c) num[K - 1][c] += g * m[c];
                lk *= l;
            }
        }
    }
    for (int K = 1; K <= kMaxK; ++K)
        for (int c = 0; c < 3; ++c) {
            const double mean =
                K == 1 ? b.plain[c] : (den[K - 1] > 0.0 ? num[K - 1][c] / den[K - 1] : 0.0);
            const double s = mean > 0.0 && far[c] > 0.0 ? far[c] / mean : 1.0;
            scale[i][K - 1][c] = static_cast<float>(s);
            if (K == kMaxK)
                tail[i][c] = static_cast<float>(
                    mean > 0.0 && far[c] > 0.0 ? (mean / far[c] - 1.0) * kMaxK : 0.0);
        }
}

void SparseAlbedo::init(float roughness, float gamma_rad, const FresnelTable& fresnel,
                        bool with_shadowing, const TableCache* cache) {
    alpha = roughness;
    shadowing = with_shadowing;
    cos_gamma = std::cos(gamma_rad);
    sin_gamma = std::sin(gamma_rad);
    TableKey key("sparse albedo");
    key.add(roughness);
    key.add(with_shadowing);
    key.add(fresnel.rgb);
    std::vector<uint8_t> bytes;
    if (!(cache && cache->load(key, bytes) && bytes.size() == sizeof(scale) + sizeof(tail))) {
        // The nodes are independent: one thread each (the result does not depend on their
        // number).
        const int threads = table_threads();
        std::vector<std::thread> pool;
        for (int w = 0; w < threads; ++w)
            pool.emplace_back([&, w] {
                for (int i = w; i < kNodes; i += threads) build_node(i, fresnel);
            });
        for (auto& t : pool) t.join();
        if (cache) {
            bytes.resize(sizeof(scale) + sizeof(tail));
            std::memcpy(bytes.data(), scale, sizeof(scale));
            std::memcpy(bytes.data() + sizeof(scale), tail, sizeof(tail));
            cache->store(key, bytes);
        }
    } else {
        std::memcpy(scale, bytes.data(), sizeof(scale));
        std::memcpy(tail, bytes.data() + sizeof(scale), sizeof(tail));
    }
    flat = true;
    for (const auto& node : scale)
        for (const auto& k : node)
            for (float v : k)
                if (std::fabs(v - 1.0f) > 1e-4f) flat = false;
}

void SparseAlbedo::at(float cos_o, uint32_t k, float s[3]) const {
    k = std::max(k, 1u);
    const float x = (cos_o > 0.0f ? std::min(cos_o, 1.0f) : 0.0f) * static_cast<float>(kNodes - 1);
    const int i = std::min(static_cast<int>(x), kNodes - 2);
    const float f = x - static_cast<float>(i);
    for (int c = 0; c < 3; ++c) {
        float v0, v1;
        if (k <= static_cast<uint32_t>(kMaxK)) {
            v0 = scale[i][k - 1][c];
            v1 = scale[i + 1][k - 1][c];
        } else {
            const float kf = static_cast<float>(k);
            v0 = 1.0f / (1.0f + tail[i][c] / kf);
            v1 = 1.0f / (1.0f + tail[i + 1][c] / kf);
        }
        s[c] = v0 + f * (v1 - v0);
    }
}

void SparseAlbedo::apply(float cos_o, uint32_t k, CacheEntry* first, CacheEntry* end) const {
    if (flat || k == 0 || first == end) return;
    float s[3];
    at(cos_o, k, s);
    // Within 0.1% of 1 (unshadowed metal flakes, or many flakes of any kind): left as they are.
    if (std::max({std::fabs(s[0] - 1.0f), std::fabs(s[1] - 1.0f), std::fabs(s[2] - 1.0f)}) < 1e-3f)
        return;
    if (s[0] > 1.0f || s[1] > 1.0f || s[2] > 1.0f) {
        // Raised only as far as the footprint reflects at most what it receives: an entry
        // reflects rgb / W times G1 averaged over its cone (with shadowing), at most G1 at the
        // cone's direction nearest the normal (G1 grows towards the normal).
        float sum[3] = {}, w = 0.0f;
        for (const CacheEntry* e = first; e != end; ++e) {
            float g = 1.0f;
            if (shadowing) {
                const float cos_r = std::clamp(e->r.z, -1.0f, 1.0f);
                const float sin_r = std::sqrt(std::max(0.0f, 1.0f - cos_r * cos_r));
                // The cone's nearest direction to the normal: theta_r - gamma, or the normal.
                const bool holds_normal = cos_r >= cos_gamma;
                const float cos_n = holds_normal ? 1.0f : cos_r * cos_gamma + sin_r * sin_gamma;
                const float sin_n =
                    holds_normal ? 0.0f : std::sqrt(std::max(0.0f, 1.0f - cos_n * cos_n));
                g = mf::ggx_g1(V3{sin_n, 0.0f, cos_n}, alpha, alpha);
            }
            for (int c = 0; c < 3; ++c) sum[c] += e->rgb[c] * g;
            w += e->w;
        }
        for (int c = 0; c < 3; ++c)
            if (s[c] > 1.0f && sum[c] * s[c] > w) s[c] = std::max(1.0f, w / sum[c]);
    }
    for (CacheEntry* e = first; e != end; ++e) {
        for (int c = 0; c < 3; ++c) e->rgb[c] *= s[c];
        e->lum = std::max(0.0f, luminance(e->rgb));
    }
}

}  // namespace spangle::flake
