#include "field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

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

bool overlaps(const Footprint& p, double x0, double y0, double x1, double y1) {
    // Bounding box of P against the cell first (cheap), then P's two edge normals.
    const double hx = p.half_width(), hy = p.half_height();
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
        // (The reach's term only where there is one: hypot is a libm call.)
        if (d > rp + rc + (p.reach > 0.0 ? p.reach * std::hypot(nx, ny) : 0.0)) return false;
    }
    return true;
}

StripSpan::StripSpan(const Footprint& p) {
    // P is the intersection of the slabs |s| <= 1/2 and |t| <= 1/2, s = i00 du + i01 dv and
    // t = i10 du + i11 dv: in a row of y, each is an interval of x about a centre linear in y.
    const double di[2] = {p.i00, p.i10}, dj[2] = {p.i01, p.i11};
    for (int k = 0; k < 2; ++k) {
        Slab& s = slab[k];
        if (di[k] != 0.0) {
            s.slope = -dj[k] / di[k];
            s.half = 0.5 / std::fabs(di[k]);
        } else {
            // Parallel to x: it bounds y alone (every y when P is singular, where both are 0).
            s.bounds_x = false;
            s.half =
                dj[k] != 0.0 ? 0.5 / std::fabs(dj[k]) : std::numeric_limits<double>::infinity();
        }
    }
    cu = p.cu;
    cv = p.cv;
    half_width = 0.5 * (std::fabs(p.ax) + std::fabs(p.bx));
    margin = 1e-6 * (std::fabs(p.ax) + std::fabs(p.bx));
}

bool contains(const Footprint& p, double x0, double y0, double x1, double y1) {
    return inside(p, x0, y0) && inside(p, x1, y0) && inside(p, x0, y1) && inside(p, x1, y1);
}

double clipped_area(const double* xs, const double* ys, int n, double x0, double y0, double x1,
                    double y1) {
    // Sutherland-Hodgman: the polygon clipped by the box's four half-planes (x >= x0, y >= y0,
    // x <= x1, y <= y1, in that order), then the shoelace formula.
    constexpr int kMax = kMaxClipVertices + 4;
    double poly[2][kMax][2];
    n = std::min(n, kMaxClipVertices);
    for (int i = 0; i < n; ++i) {
        poly[0][i][0] = xs[i];
        poly[0][i][1] = ys[i];
    }
    int cur = 0;
    // A polygon inside the box is its own clip (each pass copies it unchanged): skip the passes.
    bool inside_box = true;
    for (int i = 0; i < n; ++i)
        inside_box = inside_box && xs[i] >= x0 && xs[i] <= x1 && ys[i] >= y0 && ys[i] <= y1;
    for (int edge = 0; edge < 4 && n > 0 && !inside_box; ++edge) {
        const int axis = edge & 1;  // 0: x, 1: y
        const double bound = edge < 2 ? (axis ? y0 : x0) : (axis ? y1 : x1);
        const double sign = edge < 2 ? 1.0 : -1.0;  // keep coord >= bound, or coord <= bound
        int m = 0;
        for (int i = 0; i < n; ++i) {
            const double* a = poly[cur][i];
            const double* b = poly[cur][i + 1 < n ? i + 1 : 0];
            const double da = sign * (a[axis] - bound), db = sign * (b[axis] - bound);
            if (da >= 0.0 && m < kMax) {
                poly[1 - cur][m][0] = a[0];
                poly[1 - cur][m][1] = a[1];
                ++m;
            }
            if ((da >= 0.0) != (db >= 0.0) && m < kMax) {
                const double t = da / (da - db);
                poly[1 - cur][m][0] = a[0] + t * (b[0] - a[0]);
                poly[1 - cur][m][1] = a[1] + t * (b[1] - a[1]);
                ++m;
            }
        }
        n = m;
        cur = 1 - cur;
    }
    double twice = 0.0;
    for (int i = 0; i < n; ++i) {
        const double* a = poly[cur][i];
        const double* b = poly[cur][i + 1 < n ? i + 1 : 0];
        twice += a[0] * b[1] - a[1] * b[0];
    }
    return 0.5 * std::fabs(twice);
}

double overlap_area(const Footprint& p, double x0, double y0, double x1, double y1) {
    // P's four corners clipped by the cell.
    double xs[4], ys[4];
    const double sa[4] = {-0.5, 0.5, 0.5, -0.5}, tb[4] = {-0.5, -0.5, 0.5, 0.5};
    for (int i = 0; i < 4; ++i) {
        xs[i] = p.cu + sa[i] * p.ax + tb[i] * p.bx;
        ys[i] = p.cv + sa[i] * p.ay + tb[i] * p.by;
    }
    return clipped_area(xs, ys, 4, x0, y0, x1, y1);
}

namespace {

constexpr int kMaxExact = 1000;  ///< the largest exact_below the schema allows
constexpr int kNormalTable = 4096;

/** Tables that make binomial sampling cheap: the standard normal quantile at (i + 0.5) / 4096,
 *  and reciprocals for the inversion loop. Built once, read-only afterwards. */
struct BinomialTables {
    double inv[kMaxExact + 2];
    double quantile[kNormalTable];
    BinomialTables() {
        inv[0] = 0.0;
        for (int k = 1; k <= kMaxExact + 1; ++k) inv[k] = 1.0 / k;
        // Quantiles of the normal CDF 0.5 erfc(-z / sqrt 2): Abramowitz and Stegun's rational
        // approximation 26.2.23 (error under 4.5e-4), then three Newton steps (each squares the
        // error: 1e-14). The library loads faster than with bisection (80 erfc per entry).
        for (int i = 0; i < kNormalTable; ++i) {
            const double u = (i + 0.5) / kNormalTable;
            const double p = std::min(u, 1.0 - u), t = std::sqrt(-2.0 * std::log(p));
            double z = t - (2.515517 + t * (0.802853 + t * 0.010328)) /
                               (1.0 + t * (1.432788 + t * (0.189269 + t * 0.001308)));
            if (u < 0.5) z = -z;
            for (int it = 0; it < 3; ++it) {
                const double cdf = 0.5 * std::erfc(-z / std::sqrt(2.0));
                const double pdf = std::exp(-0.5 * z * z) / std::sqrt(2.0 * 3.14159265358979323846);
                z -= (cdf - u) / pdf;
            }
            quantile[i] = z;
        }
    }
};

/** Built when the library loads, so that reading it needs no initialisation guard. */
const BinomialTables kTables;
const BinomialTables& tables() {
    return kTables;
}

/** Standard normal quantile at u (tabulated, linearly interpolated). */
double normal_quantile(double u) {
    const BinomialTables& t = tables();
    const double x = std::clamp(u * kNormalTable - 0.5, 0.0, kNormalTable - 1.000001);
    const auto i = static_cast<int>(x);
    return t.quantile[i] +
           (x - i) * (t.quantile[std::min(i + 1, kNormalTable - 1)] - t.quantile[i]);
}

uint32_t normal_binomial(uint32_t n, double p, double u) {
    const double mean = n * p, sd = std::sqrt(n * p * (1.0 - p));
    const double k = std::clamp(mean + sd * normal_quantile(u) + 0.5, 0.0, n + 0.5);
    return std::min(n, static_cast<uint32_t>(k));  // floor of k, rounding the normal variate
}

/** Population count without relying on the CPU's instruction (no -mpopcnt in a portable build). */
inline uint32_t popcount64(uint64_t x) {
    x = x - ((x >> 1) & 0x5555555555555555ull);
    x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
    x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0full;
    return static_cast<uint32_t>((x * 0x0101010101010101ull) >> 56);
}

/** Counts of the labels 0, 1, 2 among the first `lanes` 2-bit lanes of w. */
void count_lanes(uint64_t w, uint32_t lanes, uint32_t c[3]) {
    constexpr uint64_t kLow = 0x5555555555555555ull;
    const uint64_t mask = lanes >= 32 ? kLow : (kLow & ((1ull << (2 * lanes)) - 1));
    const uint64_t pattern[3] = {0, kLow, kLow << 1};
    for (int v = 0; v < 3; ++v) {
        const uint64_t x = w ^ pattern[v];  // lanes equal to v become 00
        c[v] += popcount64(~(x | (x >> 1)) & mask);
    }
}

}  // namespace

uint32_t binomial(uint32_t n, double p, double u, int exact_below) {
    if (n == 0 || p <= 0.0) return 0;
    if (p >= 1.0) return n;
    if (static_cast<int64_t>(n) >= std::min(exact_below, kMaxExact))
        return normal_binomial(n, p, u);
    // Inversion of the CDF with the pmf recurrence, bounded by n steps; q^n is a normal double
    // for the n < 1000 handled here unless p is within 1e-300 of 1.
    const BinomialTables& t = tables();
    const double q = 1.0 - p, ratio = p / q;
    double pmf = std::pow(q, static_cast<double>(n));
    double cdf = pmf;
    uint32_t k = 0;
    while (u > cdf && k < n) {
        pmf *= ratio * static_cast<double>(n - k) * t.inv[k + 1];
        cdf += pmf;
        ++k;
    }
    return k;
}

uint32_t poisson(double mean, double u) {
    if (!(mean > 0.0)) return 0;
    if (mean >= kPoissonNormalFrom) {
        const double k = mean + std::sqrt(mean) * normal_quantile(u) + 0.5;
        return static_cast<uint32_t>(std::clamp(k, 0.0, 4.0e9));
    }
    // (Drawn per cell the counting algorithm visits: reciprocals from the table, no division.)
    const BinomialTables& t = tables();
    double pmf = std::exp(-mean), cdf = pmf;
    uint32_t k = 0;
    while (u >= cdf && k < 200) {
        ++k;
        pmf *= mean * t.inv[k];
        cdf += pmf;
    }
    return k;
}

void split_counts(uint64_t key, uint32_t n, int exact_below, uint32_t out[4]) {
    if (static_cast<int64_t>(n) < std::min(exact_below, kMaxExact)) {
        // Flake i draws its child from bits 2i, 2i + 1 of word i / 32: an exact multinomial.
        uint32_t c[3] = {0, 0, 0};
        for (uint32_t first = 0, word = 0; first < n; first += 32, ++word)
            count_lanes(mix(key, 1000 + word), std::min(32u, n - first), c);
        out[0] = c[0];
        out[1] = c[1];
        out[2] = c[2];
        out[3] = n - c[0] - c[1] - c[2];
        return;
    }
    // Three 21-bit uniforms from one hash: the normal quantiles need no more.
    const uint64_t h = mix(key, 100);
    const auto u = [&](int i) {
        return (static_cast<double>((h >> (21 * i)) & 0x1fffffu) + 0.5) * 0x1p-21;
    };
    out[0] = normal_binomial(n, 0.25, u(0));
    out[1] = normal_binomial(n - out[0], 1.0 / 3.0, u(1));
    out[2] = normal_binomial(n - out[0] - out[1], 0.5, u(2));
    out[3] = n - out[0] - out[1] - out[2];
}

void split_counts_cached(uint64_t key, uint32_t n, int exact_below, uint32_t out[4]) {
    // Small splits are a handful of popcounts: cheaper than a cache probe.
    if (n < 256) {
        split_counts(key, n, exact_below, out);
        return;
    }
    // A pure function memoised per thread in a direct-mapped table: neighbouring shading points
    // walk the same upper levels of the tree, and a hit returns exactly what the split would.
    struct Entry {
        uint64_t key;
        uint32_t n;
        int32_t exact;
        uint32_t c[4];
    };
    constexpr std::size_t kEntries = 1u << 14;
    thread_local std::vector<Entry> cache(kEntries, Entry{0, 0, -1, {0, 0, 0, 0}});
    Entry& e = cache[(key ^ (key >> 31)) & (kEntries - 1)];
    if (e.key == key && e.n == n && e.exact == exact_below) {
        std::copy(e.c, e.c + 4, out);
        return;
    }
    split_counts(key, n, exact_below, out);
    e = Entry{key, n, exact_below, {out[0], out[1], out[2], out[3]}};
}

PoissonCdf::PoissonCdf(double mean) {
    double pmf = std::exp(-mean), sum = pmf;
    for (uint32_t j = 0; j < kClassMaxPerBlock; ++j) {
        cdf[j] = sum;
        pmf *= mean / static_cast<double>(j + 1);
        sum += pmf;
    }
}

const PoissonCdf kWholeClass(kClassMean);

PoissonCdf poisson_law(double mean) {
    struct Kept {
        double mean = -1.0;
        PoissonCdf law;
    };
    thread_local Kept kept_law;
    Kept& k = kept_law;  // (one __tls_get_addr)
    // (A mean that is not a number is never equal to itself: made each time, as before.)
    if (!(k.mean == mean)) {
        k.law = PoissonCdf(mean);
        k.mean = mean;
    }
    return k.law;
}

ClassLayout class_layout(const FieldParams& fp) {
    ClassLayout cl;
    const uint32_t n = root_count(fp);
    const uint32_t t = n / 2;
    cl.residual = n - t;
    cl.per_tile = t;
    if (t == 0) return cl;
    // Whole classes while they fit (class c holds 192 x 4^c per tile), then a share of the next.
    double below = 0.0, rho = 64.0 * kClassMean;
    int c = 0;
    while (below + rho < static_cast<double>(t)) {
        below += rho;
        rho *= 4.0;
        ++c;
    }
    cl.last = c;
    cl.last_share = (static_cast<double>(t) - below) / rho;
    return cl;
}

uint64_t tile_key(uint64_t seed, int64_t tx, int64_t ty) {
    return mix(mix(seed, static_cast<uint64_t>(tx)), static_cast<uint64_t>(ty));
}

uint64_t node_key(uint64_t tile, int depth, uint32_t ix, uint32_t iy) {
    // One hash: the depth enters through a distinct odd multiple per level (a bijection of the
    // tile key for each depth), the cell through its packed coordinates.
    return mix(tile ^ (static_cast<uint64_t>(depth + 1) * 0x9e3779b97f4a7c15ull),
               (static_cast<uint64_t>(ix) << 32) | iy);
}

V3 flake_normal(float alpha, float s, float t) {
    V3 m;
    flake_normal_of(alpha, s, t, m.x, m.y, m.z);
    return m;
}

void flake_square(float alpha, V3 m, float& s, float& t) {
    // Unstretch to the hemisphere; its (x, y) is the disk point.
    const V3 h = mf::normalize({m.x / alpha, m.y / alpha, std::max(m.z, 1e-20f)});
    const float x = h.x, y = h.y;
    const float r = std::sqrt(x * x + y * y);
    float a = 0.0f, b = 0.0f;
    if (r > 0.0f) {
        constexpr float kQuarter = 0.25f * mf::kPi;
        float phi = std::atan2(y, x);  // (-pi, pi]
        // Sector |phi| <= pi/4 or >= 3pi/4: a = +-r; otherwise b = +-r.
        if (phi >= -kQuarter && phi <= kQuarter) {
            a = r;
            b = r * phi / kQuarter;
        } else if (phi > kQuarter && phi < 3.0f * kQuarter) {
            b = r;
            a = -r * (phi - 2.0f * kQuarter) / kQuarter;
        } else if (phi < -kQuarter && phi > -3.0f * kQuarter) {
            b = -r;
            a = r * (phi + 2.0f * kQuarter) / kQuarter;
        } else {
            a = -r;
            const float p = phi > 0.0f ? phi - 4.0f * kQuarter : phi + 4.0f * kQuarter;
            b = -r * p / kQuarter;
        }
    }
    s = std::clamp(0.5f * (a + 1.0f), 0.0f, 0x1.fffffep-1f);
    t = std::clamp(0.5f * (b + 1.0f), 0.0f, 0x1.fffffep-1f);
}

TileRange tiles_of(const Footprint& p) {
    TileRange r;
    const double hx = p.half_width(), hy = p.half_height();
    // Clamp far-away uv before converting: a tile index must fit an int64. A bound that is not
    // a number (NaN uv or extent) stands for every tile: callers see too many and give up.
    const auto fl = [](double x) {
        return static_cast<int64_t>(std::floor(std::clamp(x, -4.0e18, 4.0e18)));
    };
    if (std::isnan(p.cu - hx) || std::isnan(p.cu + hx) || std::isnan(p.cv - hy) ||
        std::isnan(p.cv + hy)) {
        r.tx0 = r.ty0 = -4'000'000'000'000'000'000;
        r.tx1 = r.ty1 = 4'000'000'000'000'000'000;
        return r;
    }
    r.tx0 = fl(p.cu - hx);
    r.tx1 = fl(p.cu + hx);
    r.ty0 = fl(p.cv - hy);
    r.ty1 = fl(p.cv + hy);
    return r;
}

}  // namespace spangle::flake
