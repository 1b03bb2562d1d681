#include "smooth_lobe.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <tuple>

#include "slope_integral.h"
#include "table_cache.h"

namespace spangle::flake {

namespace {

/** View nodes: uniform in theta_o (4 degrees apart) down to cos = 0.5, then geometric in cos
 *  (ratio 1.2) down to 0.005: near grazing the blur stretches the lobe by 1 / cos(theta_o), so
 *  its shape changes with the cosine's ratio, not its difference. */
constexpr int kThetaNodes = 16;    ///< theta_o = 0, 4, ..., 60 degrees
constexpr int kGrazingNodes = 26;  ///< cos = 0.5 / 1.2^j, j = 1..26 (down to 0.0046)
constexpr int kViewNodes = kThetaNodes + kGrazingNodes;
constexpr float kThetaStep = 4.0f * 3.14159265f / 180.0f;
const float kLogRatio = std::log(1.2f);
/** Below the last view node the last node's table is used; its mass is corrected at
 *  cos = cos_last / 2^m, m = 0 .. kTailCorrections - 1 (down to 1e-7). */
constexpr int kTailCorrections = 17;

/** wo's azimuth as (cos, sin); (1, 0) at normal incidence. */
void azimuth(V3 wo, float& c, float& s) {
    const float r = std::sqrt(wo.x * wo.x + wo.y * wo.y);
    if (r > 1e-12f) {
        c = wo.x / r;
        s = wo.y / r;
    } else {
        c = 1.0f;
        s = 0.0f;
    }
}

/** v turned into wo's azimuthal frame (wo in the xz-plane, x >= 0). */
V3 to_frame(V3 v, float c, float s) {
    return {c * v.x + s * v.y, -s * v.x + c * v.y, v.z};
}
V3 from_frame(V3 v, float c, float s) {
    return {c * v.x - s * v.y, s * v.x + c * v.y, v.z};
}

/** Slope scales of the table at a view angle: the cone reaches kappa in half-vector slope along
 *  wo's plane and kappa / cos(theta_d) across it (reflection halves angles in the plane and
 *  divides by 2 cos(theta_d) across it). */
float scale_x(float kappa) {
    return 1.0f + kappa;
}
/** 1 / cos(theta_o), smoothly limited to 20 at grazing views: the cone's reach across wo's plane
 *  grows as 1 / cos, and a kink (a hard clamp) would be a kink in every table entry between two
 *  view nodes, which interpolation cannot follow. */
float grazing_stretch(float cos_o) {
    return 1.0f / std::hypot(cos_o, 0.05f);
}
float scale_y(float kappa, float cos_o) {
    return 1.0f + kappa * grazing_stretch(cos_o);
}

/** The widened roughness of the proposal (along and across wo's plane). */
void proposal_alpha_of(float alpha, float kappa, float cos_o, float& ax, float& ay) {
    ax = alpha * (1.0f + 0.5f * kappa);
    ay = alpha * (1.0f + 0.5f * kappa * grazing_stretch(cos_o));
}

/** Compactified coordinate of a slope: x / (s + |x|) in (-1, 1). */
float squash(float x, float s) {
    return x / (s + std::fabs(x));
}
/** Its inverse. */
double unsquash(double w, double s) {
    return s * w / (1.0 - std::fabs(w));
}

/** Catmull-Rom weights of the four taps around a fraction t in [0, 1]. */
void catmull_rom(float t, float w[4]) {
    const float t2 = t * t, t3 = t2 * t;
    w[0] = 0.5f * (-t3 + 2.0f * t2 - t);
    w[1] = 0.5f * (3.0f * t3 - 5.0f * t2 + 2.0f);
    w[2] = 0.5f * (-3.0f * t3 + 4.0f * t2 + t);
    w[3] = 0.5f * (t3 - t2);
}

/** Lookup in one view node's slice at compactified slopes (wx in [-1, 1], wy in [0, 1]): R
 *  bicubically (Catmull-Rom; rows mirrored at wy = 0, where the table is symmetric; clamped to
 *  be non-negative), the Fresnel ratios bilinearly. */
void lookup_node(const BlurTable& t, const float* slice, float wx, float wy, float out[4]) {
    const float fx = (wx + 1.0f) * 0.5f * static_cast<float>(t.n_x - 1);
    const float fy = wy * static_cast<float>(t.n_y - 1);
    const int ix = std::clamp(static_cast<int>(fx), 0, t.n_x - 2);
    const int iy = std::clamp(static_cast<int>(fy), 0, t.n_y - 2);
    const float ax = std::clamp(fx - static_cast<float>(ix), 0.0f, 1.0f),
                ay = std::clamp(fy - static_cast<float>(iy), 0.0f, 1.0f);
    const std::size_t row = static_cast<std::size_t>(t.n_x) * 4;
    const float* p = slice + static_cast<std::size_t>(iy) * row + 4 * ix;
    for (int c = 1; c < 4; ++c) {
        const float top = p[c] + ax * (p[4 + c] - p[c]);
        const float bottom = p[row + c] + ax * (p[row + 4 + c] - p[row + c]);
        out[c] = top + ay * (bottom - top);
    }
    float wxs[4], wys[4];
    catmull_rom(ax, wxs);
    catmull_rom(ay, wys);
    float r = 0.0f;
    for (int b = 0; b < 4; ++b) {
        int j = iy - 1 + b;
        j = j < 0 ? -j : std::min(j, t.n_y - 1);
        const float* line = slice + static_cast<std::size_t>(j) * row;
        float sum = 0.0f;
        for (int a = 0; a < 4; ++a) {
            const int i = std::clamp(ix - 1 + a, 0, t.n_x - 1);
            sum += wxs[a] * line[4 * i];
        }
        r += wys[b] * sum;
    }
    out[0] = std::max(0.0f, r);
}

/** The compactified slopes of h at view node k. */
void node_coords(const BlurTable& t, float cos_k, V3 h, float& wx, float& wy) {
    const float inv = 1.0f / (t.alpha * std::max(h.z, 1e-20f));
    wx = squash(h.x * inv, scale_x(t.kappa));
    wy = squash(std::fabs(h.y) * inv, scale_y(t.kappa, cos_k));
}

float node_cos(int k) {
    if (k < kThetaNodes) return std::cos(kThetaStep * static_cast<float>(k));
    return 0.5f * std::exp(-kLogRatio * static_cast<float>(k - kThetaNodes + 1));
}

/** Fractional node index of a view cosine (inverse of node_cos, clamped to the nodes). */
float node_index(float cos_o) {
    if (cos_o >= 0.5f) return std::acos(std::min(cos_o, 1.0f)) / kThetaStep;
    const float j = std::log(0.5f / std::max(cos_o, 1e-30f)) / kLogRatio;
    return std::min(static_cast<float>(kThetaNodes - 1) + j, static_cast<float>(kViewNodes - 1));
}

/** The view cosine at a fractional node index (inverse of node_index). */
float fractional_node_cos(float fk) {
    if (fk <= static_cast<float>(kThetaNodes - 1)) return std::cos(kThetaStep * fk);
    return 0.5f * std::exp(-kLogRatio * (fk - static_cast<float>(kThetaNodes - 1)));
}

/** R (and the Fresnel ratios) at fractional view node fk: the two nodes around it, linearly. */
void interpolate_nodes(const BlurTable& bt, float fk, V3 h, float out[4]) {
    const int k = std::min(static_cast<int>(fk), bt.n_o - 2);
    const float t = std::min(fk - static_cast<float>(k), 1.0f);
    float a[4], b[4], wx, wy;
    node_coords(bt, node_cos(k), h, wx, wy);
    lookup_node(bt, bt.node(k), wx, wy, a);
    node_coords(bt, node_cos(k + 1), h, wx, wy);
    lookup_node(bt, bt.node(k + 1), wx, wy, b);
    for (int c = 0; c < 4; ++c) out[c] = a[c] + t * (b[c] - a[c]);
}

/** Table columns and rows, (32 r + 1) x (16 r + 1): the rim of a wide cone over near-mirror
 *  flakes is about one slope unit wide at a distance kappa; it is resolved with a few nodes.
 *  r = 1 up to kappa 1.2, where the tabulated lobe is within 0.3% of the exact one for views
 *  above cos 0.3 (tests/stat/test_flake_smooth.cpp). */
int refinement(float kappa) {
    return std::clamp(static_cast<int>(std::ceil(kappa / 1.2f)), 1, 4);
}

/** Fills node k of the blur table from the exact integral (R and the Fresnel ratios). */
void build_node(BlurTable& t, const FresnelTable& fresnel, int k) {
    const float cos_k = node_cos(k);
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - cos_k * cos_k)), 0.0f, cos_k};
    const double sx = scale_x(t.kappa), sy = scale_y(t.kappa, cos_k);
    float ax, ay;
    proposal_alpha_of(t.alpha, t.kappa, cos_k, ax, ay);
    const float g1 = mf::ggx_g1(wo, ax, ay);
    float* slice = &t.data[static_cast<std::size_t>(k) * t.n_x * t.n_y * 4];
    for (int j = 0; j < t.n_y; ++j)
        for (int i = 0; i < t.n_x; ++i) {
            float* out = slice + (static_cast<std::size_t>(j) * t.n_x + i) * 4;
            out[0] = -1.0f;  // not yet known
            const double wx = -1.0 + 2.0 * i / (t.n_x - 1),
                         wy = static_cast<double>(j) / (t.n_y - 1);
            // The last nodes stand for infinite slopes: take them just short of it.
            const double x = unsquash(std::clamp(wx, -0.999, 0.999), sx),
                         y = unsquash(std::min(wy, 0.999), sy);
            const V3 h = mf::normalize(
                {t.alpha * static_cast<float>(x), t.alpha * static_cast<float>(y), 1.0f});
            const V3 wi = mf::reflect(wo, h);
            if (!(wi.z > 1e-5f)) continue;
            float i_f[3], i_1;
            slope_integral(t.alpha, t.sin2_half, &fresnel, wo, wi, i_f, i_1);
            // The share of wi's cone above the horizon is geometry, applied exactly at eval time.
            const auto above = static_cast<float>(cone_fraction_above(wi.z, t.sin2_half));
            const float p = g1 * mf::ggx_d(h, ax, ay) / (4.0f * wo.z) * above;
            if (!(p > 0.0f)) continue;
            out[0] = (i_1 / t.sigma) / p;
            float f[3];
            fresnel.eval(mf::dot(wo, h), f);
            for (int c = 0; c < 3; ++c)
                out[1 + c] = i_1 > 0.0f && f[c] > 0.0f ? i_f[c] / (i_1 * f[c]) : 1.0f;
        }
    // Directions under the horizon were skipped: continue each row from its nearest known node.
    for (int j = 0; j < t.n_y; ++j) {
        float* row = slice + static_cast<std::size_t>(j) * t.n_x * 4;
        int known = -1;
        for (int i = 0; i < t.n_x; ++i)
            if (row[4 * i] >= 0.0f) known = i;
        for (int i = t.n_x - 1; i >= 0; --i) {
            if (row[4 * i] >= 0.0f) {
                known = i;
            } else if (known >= 0) {
                std::copy(row + 4 * known, row + 4 * known + 4, row + 4 * i);
            } else {
                row[4 * i] = row[4 * i + 1] = row[4 * i + 2] = row[4 * i + 3] = 1.0f;
            }
        }
    }
}

/** The table lobe's mass over wi at view cosine cos_e (wo in the xz-plane), for lookup(h, v)
 *  giving R and the Fresnel ratios at half vector h: the integral of p A R over the directions
 *  above the horizon. In half-vector slopes (x, y) (units of alpha) those directions are the disc
 *  (x - T)^2 + y^2 < 1 / (alpha cos)^2, T = tan(theta) / alpha, so the integral is taken row by
 *  row up to its edge (no direction under the horizon inside the quadrature), in compactified
 *  coordinates: 6 x 12 pieces of 3-point Gauss-Legendre, dw_i = 4 (wo.h) alpha^2 h_z^3 dx dy. */
template <class Lookup>
double table_mass(const BlurTable& t, float cos_e, Lookup&& lookup) {
    constexpr int kRows = 6, kCols = 12;
    // A refined table (a cone much wider than the flake lobe: its rim is sharp in the
    // compactified coordinates) is integrated cell by cell, 3 x 3 Gauss points in each piece of
    // a cell inside the disc: the interpolant is a cubic per cell, which a fixed grid of pieces
    // sampled out of step with the nodes (the mass, and the albedo, came out 4% high or low as
    // gamma moved the rim across the nodes: 1.047 at alpha 0.001, gamma 20).
    const bool by_cell = t.n_x > 33;
    const double c = std::clamp(static_cast<double>(cos_e), 1e-7, 1.0);
    const double s = std::sqrt(std::max(0.0, 1.0 - c * c));
    const V3 wo{static_cast<float>(s), 0.0f, static_cast<float>(c)};
    const double a = t.alpha, centre = s / (c * a), radius = 1.0 / (a * c);
    const double sx = scale_x(t.kappa), sy = scale_y(t.kappa, static_cast<float>(c));
    float ax, ay;
    proposal_alpha_of(t.alpha, t.kappa, static_cast<float>(c), ax, ay);
    const float g1 = mf::ggx_g1(wo, ax, ay);
    const double wy_end = radius / (sy + radius);
    // The pieces of [lo, hi]: kPieces equal ones, or split at the table's node lines (spacing
    // `cell`, from `origin`).
    const auto pieces = [&](double lo, double hi, int equal, double origin, double cell) {
        std::vector<double> cuts{lo};
        if (!by_cell) {
            for (int i = 1; i < equal; ++i) cuts.push_back(lo + (hi - lo) * i / equal);
        } else {
            for (double at = origin + cell * std::ceil((lo - origin) / cell + 1e-9); at < hi;
                 at += cell)
                if (at > lo) cuts.push_back(at);
        }
        cuts.push_back(hi);
        return cuts;
    };
    const std::vector<double> ycuts = pieces(0.0, wy_end, kRows, 0.0, 1.0 / (t.n_y - 1));
    double sum = 0.0;
    for (std::size_t pj = 0; pj + 1 < ycuts.size(); ++pj) {
        const double ya = ycuts[pj], yb = ycuts[pj + 1];
        for (int gj = 0; gj < 3; ++gj) {
            const double wy = ya + (yb - ya) * kGauss3Nodes[gj];
            const double y = unsquash(wy, sy), dy = sy / ((1.0 - wy) * (1.0 - wy));
            const double chord = std::sqrt(std::max(0.0, radius * radius - y * y));
            const double x0 = centre - chord, x1 = centre + chord;
            const double w0 = x0 / (sx + std::fabs(x0)), w1 = x1 / (sx + std::fabs(x1));
            const std::vector<double> xcuts = pieces(w0, w1, kCols, -1.0, 2.0 / (t.n_x - 1));
            double row = 0.0;
            for (std::size_t pi = 0; pi + 1 < xcuts.size(); ++pi)
                for (int gi = 0; gi < 3; ++gi) {
                    const double xa = xcuts[pi], xb = xcuts[pi + 1];
                    const double wx = xa + (xb - xa) * kGauss3Nodes[gi];
                    const double x = unsquash(wx, sx);
                    const double dx = sx / ((1.0 - std::fabs(wx)) * (1.0 - std::fabs(wx)));
                    const V3 h = mf::normalize(
                        {t.alpha * static_cast<float>(x), t.alpha * static_cast<float>(y), 1.0f});
                    const V3 wi = mf::reflect(wo, h);
                    if (!(wi.z > 0.0f)) continue;
                    float v[4];
                    lookup(h, v);
                    const double p = static_cast<double>(g1 * mf::ggx_d(h, ax, ay)) / (4.0 * c);
                    const double hz = h.z;
                    const double jac =
                        4.0 * static_cast<double>(mf::dot(wo, h)) * a * a * hz * hz * hz * dx * dy;
                    row += kGauss3Weights[gi] * (xb - xa) * p *
                           cone_fraction_above(wi.z, t.sin2_half) * static_cast<double>(v[0]) * jac;
                }
            sum += kGauss3Weights[gj] * (yb - ya) * row;
        }
    }
    return 2.0 * sum;  // both halves of the symmetric disc
}

/** Scales node k's R so that the table's mass over wi equals the exact one. */
void normalise_node(BlurTable& t, int k) {
    const float cos_k = node_cos(k);
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - cos_k * cos_k)), 0.0f, cos_k};
    const double mass = table_mass(t, cos_k, [&](V3 h, float v[4]) {
        float wx, wy;
        node_coords(t, cos_k, h, wx, wy);
        lookup_node(t, t.node(k), wx, wy, v);
    });
    const double exact = lobe_mass(t.alpha, t.sin2_half, wo);
    const auto scale = static_cast<float>(mass > 0.0 ? exact / mass : 1.0);
    float* slice = &t.data[static_cast<std::size_t>(k) * t.n_x * t.n_y * 4];
    for (std::size_t n = 0; n < static_cast<std::size_t>(t.n_x * t.n_y); ++n) slice[n * 4] *= scale;
}

/** The mass correction at fractional node fk (the interpolated table against the exact mass);
 *  fk beyond the last node stands for cos = cos_last / 2^(fk - last) on the last node's table. */
float correction_at(const BlurTable& t, float fk) {
    const float last = static_cast<float>(t.n_o - 1);
    const float cos_e =
        fk <= last ? fractional_node_cos(fk) : node_cos(t.n_o - 1) * std::exp2(-(fk - last));
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - cos_e * cos_e)), 0.0f, cos_e};
    const double mass = table_mass(
        t, cos_e, [&](V3 h, float v[4]) { interpolate_nodes(t, std::min(fk, last), h, v); });
    return static_cast<float>(mass > 0.0 ? lobe_mass(t.alpha, t.sin2_half, wo) / mass : 1.0);
}

/** Runs job(i) for i in [0, n) on up to `threads` threads. */
template <class Job>
void parallel_for(int n, int threads, Job&& job) {
    threads = std::clamp(threads, 1, n);
    if (threads == 1) {
        for (int i = 0; i < n; ++i) job(i);
        return;
    }
    std::vector<std::thread> pool;
    for (int w = 0; w < threads; ++w)
        pool.emplace_back([&, w] {
            for (int i = w; i < n; i += threads) job(i);
        });
    for (auto& th : pool) th.join();
}

}  // namespace

std::shared_ptr<BlurTable> build_blur_table(float alpha, double sin2_half,
                                            const FresnelTable& fresnel, int threads) {
    auto t = std::make_shared<BlurTable>();
    t->alpha = alpha;
    t->sin2_half = sin2_half;
    t->sigma = static_cast<float>(4.0 * 3.14159265358979 * sin2_half);
    const double half = std::asin(std::sqrt(sin2_half));
    t->kappa = std::tan(static_cast<float>(half)) / alpha;
    const int r = refinement(t->kappa);
    t->n_o = kViewNodes;
    t->n_x = 32 * r + 1;
    t->n_y = 16 * r + 1;
    t->data.assign(static_cast<std::size_t>(t->n_o) * t->n_x * t->n_y * 4, 1.0f);
    parallel_for(t->n_o, threads, [&](int k) {
        build_node(*t, fresnel, k);
        normalise_node(*t, k);
    });
    // Halfway between view nodes (and below the last one) the interpolated table's mass.
    const int mids = t->n_o - 1;
    t->correction.assign(static_cast<std::size_t>(2 * mids + 1 + kTailCorrections), 1.0f);
    parallel_for(mids + kTailCorrections, threads, [&](int i) {
        const float fk =
            i < mids ? static_cast<float>(i) + 0.5f : static_cast<float>(mids + 1 + (i - mids));
        t->correction[static_cast<std::size_t>(i < mids ? 2 * i + 1 : 2 * mids + 1 + (i - mids))] =
            correction_at(*t, fk);
    });
    return t;
}

double cone_fraction_above(double r_z, double sin2_half) {
    // The cone (a spherical cap of radius gamma around r) against the lower hemisphere (a cap of
    // radius pi/2 around -z, at angular distance pi - theta_r): the area of two intersecting caps
    // of radii r1, r2 at distance d is 2 pi - 2 cos(r1) acos((cos r2 - cos d cos r1) / (sin d sin
    // r1)) - 2 cos(r2) acos(...) - 2 acos((cos d - cos r1 cos r2) / (sin r1 sin r2)); with
    // r2 = pi/2 the middle term vanishes.
    const double sin_g = 2.0 * std::sqrt(sin2_half * (1.0 - sin2_half));  // sin(gamma)
    const double cos_g = 1.0 - 2.0 * sin2_half;
    if (r_z >= sin_g) return 1.0;  // the whole cone is above the horizon
    if (r_z <= -sin_g) return 0.0;
    const double sin_r = std::sqrt(std::max(0.0, 1.0 - r_z * r_z));  // sin(theta_r)
    const double a1 = std::acos(std::clamp(r_z * cos_g / (sin_r * sin_g), -1.0, 1.0));
    const double a2 = std::acos(std::clamp(-r_z / sin_g, -1.0, 1.0));
    const double below = 2.0 * 3.14159265358979 - 2.0 * cos_g * a1 - 2.0 * a2;
    const double cap = 4.0 * 3.14159265358979 * sin2_half;  // 2 pi (1 - cos gamma)
    return std::clamp(1.0 - below / cap, 0.0, 1.0);
}

float SmoothLobe::valid_fraction(float cos_o) const {
    const float x = std::clamp(cos_o, 0.0f, 1.0f) * static_cast<float>(kValidNodes - 1);
    const int i = std::min(static_cast<int>(x), kValidNodes - 2);
    const float f = x - static_cast<float>(i);
    return valid[i] + f * (valid[i + 1] - valid[i]);
}

void SmoothLobe::blur(float cos_o, V3 h, float out[4]) const {
    if (!table) {
        out[0] = out[1] = out[2] = out[3] = 1.0f;
        return;
    }
    const BlurTable& t = *table;
    const float last = static_cast<float>(t.n_o - 1);
    const float fk = node_index(cos_o);
    interpolate_nodes(t, fk, h, out);
    // The correction, linear between its samples: at nodes and halfway (1 at nodes), then below
    // the last node at cos_last / 2^m.
    const float cos_last = node_cos(t.n_o - 1);
    float corr;
    if (cos_o >= cos_last || fk < last) {
        const float e = std::clamp(2.0f * fk, 0.0f, 2.0f * last);
        const int e0 = std::min(static_cast<int>(e), 2 * (t.n_o - 1) - 1);
        const float a = e - static_cast<float>(e0);
        corr = t.correction[static_cast<std::size_t>(e0)] +
               a * (t.correction[static_cast<std::size_t>(e0) + 1] -
                    t.correction[static_cast<std::size_t>(e0)]);
    } else {
        const float m = std::clamp(std::log2(cos_last / std::max(cos_o, 1e-30f)), 0.0f,
                                   static_cast<float>(kTailCorrections - 1) - 1e-3f);
        const auto m0 = static_cast<std::size_t>(m);
        const std::size_t base = static_cast<std::size_t>(2 * (t.n_o - 1));
        // Sample 0 of the tail is the last node itself (correction 1).
        const float c0 = m0 == 0 ? t.correction[base] : t.correction[base + m0];
        const float c1 = t.correction[base + m0 + 1];
        corr = c0 + (m - static_cast<float>(m0)) * (c1 - c0);
    }
    out[0] *= corr;
}

namespace {

/** Tables by (alpha, gamma, Fresnel), shared within the process: scenes and tests often create
 *  the same material many times. Entries live as long as some material holds them. */
std::mutex g_shared_mutex;
std::map<std::string, std::weak_ptr<const BlurTable>> g_shared;

}  // namespace

void SmoothLobe::init(float alpha_, float gamma_rad, const FresnelTable* fresnel_,
                      const TableCache* cache) {
    alpha = alpha_;
    const double s = std::sin(0.5 * static_cast<double>(gamma_rad));
    sin2_half = s * s;
    sigma = static_cast<float>(4.0 * 3.14159265358979 * sin2_half);
    kappa = std::tan(0.5f * gamma_rad) / alpha;
    // The blur changes the lobe by O(kappa^2): below kappa = 0.01 it is under 1e-4.
    blur_negligible = kappa < 0.01f;
    fresnel = fresnel_;
    const auto t0 = std::chrono::steady_clock::now();
    // Everything the tables depend on, as bytes: the key of the process-wide share and of the
    // disk cache (which adds the plugin's version).
    TableKey key("smooth lobe");
    key.add(alpha);
    key.add(sin2_half);
    key.add(blur_negligible);
    if (!blur_negligible) key.add_bytes(&fresnel->rgb[0][0], sizeof(fresnel->rgb));
    std::lock_guard<std::mutex> lock(g_shared_mutex);
    std::vector<uint8_t> blob;
    from_cache = cache && cache->load(key, blob) && unpack(blob);
    if (!from_cache) {
        for (int i = 0; i < kValidNodes; ++i) {
            const float mu = std::max(1e-7f, static_cast<float>(i) / (kValidNodes - 1));
            const V3 wo{std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu};
            valid[i] = static_cast<float>(valid_fraction_exact(alpha, wo, 1e-9));
        }
        table.reset();
        if (!blur_negligible) {
            const std::string name(key.bytes().begin(), key.bytes().end());
            if (auto hit = g_shared[name].lock()) {
                table = hit;
            } else {
                auto built = build_blur_table(alpha, sin2_half, *fresnel, table_threads());
                g_shared[name] = built;
                table = built;
            }
        }
        build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                       .count();
        if (cache) cache->store(key, pack());
    }
}

namespace {

template <class T>
void put(std::vector<uint8_t>& out, const T* p, std::size_t n) {
    const auto* b = reinterpret_cast<const uint8_t*>(p);
    out.insert(out.end(), b, b + n * sizeof(T));
}

template <class T>
bool get(const std::vector<uint8_t>& in, std::size_t& at, T* p, std::size_t n) {
    if (at + n * sizeof(T) > in.size()) return false;
    std::memcpy(p, in.data() + at, n * sizeof(T));
    at += n * sizeof(T);
    return true;
}

}  // namespace

std::vector<uint8_t> SmoothLobe::pack() const {
    std::vector<uint8_t> out;
    put(out, valid, kValidNodes);
    const int32_t has = table ? 1 : 0;
    put(out, &has, 1);
    if (!table) return out;
    const BlurTable& t = *table;
    const int32_t dims[3] = {t.n_o, t.n_x, t.n_y};
    const float scalars[3] = {t.alpha, t.kappa, t.sigma};
    const auto counts = static_cast<uint64_t>(t.data.size()),
               corrections = static_cast<uint64_t>(t.correction.size());
    put(out, dims, 3);
    put(out, scalars, 3);
    put(out, &t.sin2_half, 1);
    put(out, &counts, 1);
    put(out, &corrections, 1);
    put(out, t.data.data(), t.data.size());
    put(out, t.correction.data(), t.correction.size());
    return out;
}

bool SmoothLobe::unpack(const std::vector<uint8_t>& in) {
    std::size_t at = 0;
    int32_t has = 0;
    if (!get(in, at, valid, kValidNodes) || !get(in, at, &has, 1)) return false;
    if (has != (blur_negligible ? 0 : 1)) return false;
    table.reset();
    if (!has) return at == in.size();
    auto t = std::make_shared<BlurTable>();
    int32_t dims[3];
    float scalars[3];
    uint64_t counts = 0, corrections = 0;
    if (!get(in, at, dims, 3) || !get(in, at, scalars, 3) || !get(in, at, &t->sin2_half, 1) ||
        !get(in, at, &counts, 1) || !get(in, at, &corrections, 1))
        return false;
    t->n_o = dims[0];
    t->n_x = dims[1];
    t->n_y = dims[2];
    t->alpha = scalars[0];
    t->kappa = scalars[1];
    t->sigma = scalars[2];
    if (counts != static_cast<uint64_t>(t->n_o) * t->n_x * t->n_y * 4 || corrections > (1u << 16) ||
        at + (counts + corrections) * sizeof(float) != in.size())
        return false;
    t->data.resize(counts);
    t->correction.resize(corrections);
    get(in, at, t->data.data(), counts);
    get(in, at, t->correction.data(), corrections);
    table = t;
    return true;
}

void SmoothLobe::proposal_alpha(float cos_o, float& ax, float& ay) const {
    if (blur_negligible) {
        ax = ay = alpha;  // the lobe is the unblurred one: sample it exactly
        return;
    }
    proposal_alpha_of(alpha, kappa, cos_o, ax, ay);
}

void eval_smooth(const SmoothLobe& lobe, V3 wo, float v_o, V3 wi, float f[3], float& pdf) {
    f[0] = f[1] = f[2] = pdf = 0.0f;
    if (!(wo.z > 0.0f) || !(wi.z > 0.0f) || !(v_o > 0.0f)) return;
    float c, s;
    azimuth(wo, c, s);
    const V3 wo_a = to_frame(wo, c, s), wi_a = to_frame(wi, c, s);
    V3 h = wo_a + wi_a;
    if (!(h.z > 0.0f)) return;
    h = mf::normalize(h);
    // The proposal's density of mirror directions, exact for sample_smooth().
    float ax, ay;
    lobe.proposal_alpha(wo.z, ax, ay);
    pdf = mf::ggx_g1(wo_a, ax, ay) * mf::ggx_d(h, ax, ay) / (4.0f * wo.z);
    float blur[4];
    lobe.blur(wo.z, h, blur);
    float fr[3];
    lobe.fresnel->eval(mf::dot(wo_a, h), fr);
    const auto above = static_cast<float>(cone_fraction_above(wi.z, lobe.sin2_half));
    const float k = pdf * blur[0] * above / (wi.z * v_o);
    for (int ch = 0; ch < 3; ++ch) f[ch] = fr[ch] * blur[1 + ch] * k;
    if (!std::isfinite(pdf + f[0] + f[1] + f[2])) f[0] = f[1] = f[2] = pdf = 0.0f;
}

bool sample_smooth(const SmoothLobe& lobe, V3 wo, float u0, float u1, V3& wi) {
    if (!(wo.z > 0.0f)) return false;
    float c, s, ax, ay;
    azimuth(wo, c, s);
    lobe.proposal_alpha(wo.z, ax, ay);
    const V3 wo_a = to_frame(wo, c, s);
    const V3 h = mf::ggx_sample_visible(wo_a, ax, ay, u0, u1);
    const V3 wi_a = mf::reflect(wo_a, h);
    if (!(wi_a.z > 0.0f)) return false;
    wi = from_frame(wi_a, c, s);
    return true;
}

}  // namespace spangle::flake
