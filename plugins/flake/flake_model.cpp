#include "flake_model.h"

#include <algorithm>
#include <cmath>

namespace spangle::flake {

Footprint make_footprint(double u, double v, double dudx, double dvdx, double dudy, double dvdy,
                         double scale, double max_ratio) {
    Footprint p;
    p.cu = u;
    p.cv = v;
    // M = [a b] with a = (dudx, dvdx), b = (dudy, dvdy). Its closed-form 2x2 SVD (Blinn 1996):
    // M = R(phi) diag(s1, s2) R(theta); the minor singular value is raised to s1 / max_ratio.
    const double m00 = dudx * scale, m10 = dvdx * scale, m01 = dudy * scale, m11 = dvdy * scale;
    const double e = 0.5 * (m00 + m11), f = 0.5 * (m00 - m11);
    const double g = 0.5 * (m10 + m01), h = 0.5 * (m10 - m01);
    const double q = std::hypot(e, h), r = std::hypot(f, g);
    const double s1 = q + r;
    double s2 = q - r;  // signed: a negative value is a reflection
    const double a1 = std::atan2(g, f), a2 = std::atan2(h, e);
    const double theta = 0.5 * (a2 - a1), phi = 0.5 * (a2 + a1);
    const double min_s = s1 / max_ratio;
    if (std::fabs(s2) < min_s) s2 = s2 < 0 ? -min_s : min_s;
    const double cp = std::cos(phi), sp = std::sin(phi), ct = std::cos(theta), st = std::sin(theta);
    // R(phi) diag(s1, s2) R(theta), R(x) = [[cos, -sin], [sin, cos]].
    p.ax = cp * s1 * ct - sp * s2 * st;
    p.bx = -cp * s1 * st - sp * s2 * ct;
    p.ay = sp * s1 * ct + cp * s2 * st;
    p.by = -sp * s1 * st + cp * s2 * ct;
    if (!std::isfinite(p.ax + p.ay + p.bx + p.by)) p.ax = p.ay = p.bx = p.by = 0.0;
    // The inverse once here, so that testing each candidate flake is four multiplications.
    const double det = p.ax * p.by - p.ay * p.bx;
    if (std::fabs(det) > 0.0 && std::isfinite(1.0 / det)) {
        p.i00 = p.by / det;
        p.i01 = -p.bx / det;
        p.i10 = -p.ay / det;
        p.i11 = p.ax / det;
    }
    return p;
}

namespace {

constexpr int kMaxExact = 1000;  ///< the largest exact_below the schema allows
constexpr int kNormalTable = 4096;

/** Tables that make binomial sampling cheap: q^n for the three split probabilities, and the
 *  standard normal quantile at (i + 0.5) / 4096. Built once, read-only afterwards. */
struct BinomialTables {
    double q_pow[3][kMaxExact + 1];  ///< (1 - p)^n for p = 1/4, 1/3, 1/2
    double inv[kMaxExact + 2];       ///< 1 / k, so that the inversion loop does not divide
    double quantile[kNormalTable];
    BinomialTables() {
        inv[0] = 0.0;
        for (int k = 1; k <= kMaxExact + 1; ++k) inv[k] = 1.0 / k;
        const double ps[3] = {0.25, 1.0 / 3.0, 0.5};
        for (int k = 0; k < 3; ++k)
            for (int n = 0; n <= kMaxExact; ++n) q_pow[k][n] = std::pow(1.0 - ps[k], n);
        // Quantiles by bisection on the normal CDF 0.5 erfc(-z / sqrt 2): exact to 1e-12.
        for (int i = 0; i < kNormalTable; ++i) {
            const double u = (i + 0.5) / kNormalTable;
            double lo = -10.0, hi = 10.0;
            for (int it = 0; it < 80; ++it) {
                const double mid = 0.5 * (lo + hi);
                (0.5 * std::erfc(-mid / std::sqrt(2.0)) < u ? lo : hi) = mid;
            }
            quantile[i] = 0.5 * (lo + hi);
        }
    }
};

const BinomialTables& tables() {
    static const BinomialTables t;
    return t;
}

int split_index(double p) {
    return p < 0.3 ? 0 : p < 0.4 ? 1 : 2;
}

}  // namespace

uint32_t binomial(uint32_t n, double p, double u0, double u1, int exact_below) {
    if (n == 0 || p <= 0.0) return 0;
    if (p >= 1.0) return n;
    const BinomialTables& t = tables();
    if (static_cast<int64_t>(n) < std::min(exact_below, kMaxExact)) {
        // Inversion of the CDF with the pmf recurrence, bounded by n steps. The split
        // probabilities' q^n come from the table (q^n stays a normal double for n < 1000).
        const double q = 1.0 - p, ratio = p / q;
        const bool tabulated = p == 0.25 || p == 1.0 / 3.0 || p == 0.5;
        double pmf = tabulated ? t.q_pow[split_index(p)][n] : std::pow(q, static_cast<double>(n));
        double cdf = pmf;
        uint32_t k = 0;
        while (u0 > cdf && k < n) {
            pmf *= ratio * static_cast<double>(n - k) * t.inv[k + 1];
            cdf += pmf;
            ++k;
        }
        return k;
    }
    // Normal approximation: the standard normal quantile at u0 (tabulated, linearly
    // interpolated), rounded and clamped. u1 is unused here; the exact branch does not need it
    // either, and it is kept in the signature so either sampler may use two numbers.
    (void)u1;
    const double x = std::clamp(u0 * kNormalTable - 0.5, 0.0, kNormalTable - 1.000001);
    const auto i = static_cast<int>(x);
    const double z =
        t.quantile[i] + (x - i) * (t.quantile[std::min(i + 1, kNormalTable - 1)] - t.quantile[i]);
    const double mean = n * p, sd = std::sqrt(n * p * (1.0 - p));
    const double k = std::round(mean + sd * z);
    return static_cast<uint32_t>(std::clamp(k, 0.0, static_cast<double>(n)));
}

void split_counts(uint64_t key, uint32_t n, int exact_below, uint32_t out[4]) {
    const auto u = [&](uint64_t i) { return mf_unit(mf_hash(key, 100 + i)); };
    out[0] = binomial(n, 0.25, u(0), u(1), exact_below);
    out[1] = binomial(n - out[0], 1.0 / 3.0, u(2), u(3), exact_below);
    out[2] = binomial(n - out[0] - out[1], 0.5, u(4), u(5), exact_below);
    out[3] = n - out[0] - out[1] - out[2];
}

void split_counts_cached(uint64_t key, uint32_t n, int exact_below, uint32_t out[4]) {
    // A pure function memoised per thread in a direct-mapped table: neighbouring shading points
    // walk the same upper levels of the tree, and a hit returns exactly what the split would.
    struct Entry {
        uint64_t key;
        uint32_t n;
        int32_t exact;
        uint32_t c[4];
    };
    constexpr std::size_t kEntries = 1u << 15;
    thread_local std::vector<Entry> cache(kEntries, Entry{0, 0, -1, {0, 0, 0, 0}});
    Entry& e = cache[(key ^ (key >> 31)) & (kEntries - 1)];
    if (e.key == key && e.n == n && e.exact == exact_below) {
        std::copy(e.c, e.c + 4, out);
        return;
    }
    split_counts(key, n, exact_below, out);
    e = Entry{key, n, exact_below, {out[0], out[1], out[2], out[3]}};
}

uint64_t node_key(uint64_t tile, int depth, uint32_t ix, uint32_t iy) {
    return mf_hash(mf_hash(tile, static_cast<uint64_t>(depth)),
                   (static_cast<uint64_t>(ix) << 32) | iy);
}

uint64_t tile_key(uint64_t seed, int64_t tx, int64_t ty) {
    return mf_hash(mf_hash(seed, static_cast<uint64_t>(tx)), static_cast<uint64_t>(ty));
}

bool inside(const Footprint& p, double u, double v) {
    // (s, t) = [a b]^-1 ((u, v) - c); a singular footprint (zero area) holds no flake.
    if (p.i00 == 0.0 && p.i01 == 0.0 && p.i10 == 0.0 && p.i11 == 0.0) return false;
    const double du = u - p.cu, dv = v - p.cv;
    const double s = p.i00 * du + p.i01 * dv;
    const double t = p.i10 * du + p.i11 * dv;
    return s >= -0.5 && s <= 0.5 && t >= -0.5 && t <= 0.5;
}

bool overlaps(const Footprint& p, double x0, double y0, double x1, double y1) {
    // Bounding box of P against the cell first (cheap), then P's two edge normals.
    const double hx = 0.5 * (std::fabs(p.ax) + std::fabs(p.bx));
    const double hy = 0.5 * (std::fabs(p.ay) + std::fabs(p.by));
    if (p.cu + hx < x0 || p.cu - hx > x1 || p.cv + hy < y0 || p.cv - hy > y1) return false;
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1), ex = 0.5 * (x1 - x0),
                 ey = 0.5 * (y1 - y0);
    for (int k = 0; k < 2; ++k) {
        // Axis perpendicular to edge a (k = 0) or b (k = 1).
        const double nx = k == 0 ? -p.ay : -p.by, ny = k == 0 ? p.ax : p.bx;
        const double other =
            k == 0 ? std::fabs(nx * p.bx + ny * p.by) : std::fabs(nx * p.ax + ny * p.ay);
        const double rp = 0.5 * other;                              // P's half extent on the axis
        const double rc = ex * std::fabs(nx) + ey * std::fabs(ny);  // the cell's
        const double d = std::fabs(nx * (cx - p.cu) + ny * (cy - p.cv));
        if (d > rp + rc) return false;
    }
    return true;
}

V3 sample_flake_normal(float alpha, float u0, float u1) {
    // GGX: tan^2(theta) = alpha^2 u0 / (1 - u0) samples D(m) cos(theta_m).
    const float t2 = alpha * alpha * u0 / std::max(1e-7f, 1.0f - u0);
    const float cos_t = 1.0f / std::sqrt(1.0f + t2);
    const float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
    const float phi = 2.0f * mf::kPi * u1;
    return {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t};
}

Cone::Cone(float gamma_rad) {
    const float s = std::sin(0.5f * gamma_rad);
    sin2_half = s * s;
    threshold = 4.0f * sin2_half;
    solid_angle = 4.0f * mf::kPi * sin2_half;
}

void eval_discrete(const DiscreteLobe& lobe, const Cone& cone, V3 wi, float f[3], float& pdf) {
    f[0] = f[1] = f[2] = 0.0f;
    pdf = 0.0f;
    if (lobe.count == 0 || !(lobe.w_sum > 0.0f) || wi.z <= 0.0f) return;
    float lum = 0.0f;
    for (uint32_t j = 0; j < lobe.count; ++j) {
        const CacheEntry& e = lobe.entries[j];
        const float dx = wi.x - e.r.x, dy = wi.y - e.r.y, dz = wi.z - e.r.z;
        if (dx * dx + dy * dy + dz * dz > cone.threshold) continue;
        f[0] += e.rgb[0];
        f[1] += e.rgb[1];
        f[2] += e.rgb[2];
        lum += e.lum;
    }
    const float k = 1.0f / (lobe.w_sum * cone.solid_angle * wi.z);
    f[0] *= k;
    f[1] *= k;
    f[2] *= k;
    pdf = lobe.lum_sum > 0.0f ? lum / (lobe.lum_sum * cone.solid_angle) : 0.0f;
}

bool sample_discrete(const DiscreteLobe& lobe, const Cone& cone, float u0, float u1, float u2,
                     V3& wi) {
    if (lobe.count == 0 || !(lobe.lum_sum > 0.0f)) return false;
    // Binary search, bounded by the table; u0 = 0 and u0 -> 1 both land on valid entries.
    const float target = u0 * lobe.lum_sum;
    const float* it = std::upper_bound(lobe.cdf, lobe.cdf + lobe.count, target);
    const auto j = static_cast<uint32_t>(std::min<std::ptrdiff_t>(it - lobe.cdf, lobe.count - 1));
    const V3 r = lobe.entries[j].r;
    // Uniform in the cone: cos(theta) = 1 - u1 (1 - cos gamma), with 1 - cos gamma = 2
    // sin^2(gamma/2).
    const float one_minus_cos = u1 * 2.0f * cone.sin2_half;
    const float cos_t = 1.0f - one_minus_cos;
    const float sin_t = std::sqrt(std::max(0.0f, one_minus_cos * (2.0f - one_minus_cos)));
    const float phi = 2.0f * mf::kPi * u2;
    // Orthonormal basis around r (Duff et al. 2017).
    const float sign = std::copysign(1.0f, r.z);
    const float a = -1.0f / (sign + r.z), b = r.x * r.y * a;
    const V3 s{1.0f + sign * r.x * r.x * a, sign * b, -sign * r.x};
    const V3 t{b, sign + r.y * r.y * a, -r.y};
    wi = mf::normalize(s * (sin_t * std::cos(phi)) + t * (sin_t * std::sin(phi)) + r * cos_t);
    return wi.z > 0.0f;
}

}  // namespace spangle::flake
