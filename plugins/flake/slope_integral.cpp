#include "slope_integral.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "smooth_lobe.h"

namespace spangle::flake {

namespace {

/** The 15-point Gauss-Kronrod rule on [-1, 1] (Kronrod 1965; the constants of QUADPACK's qk15):
 *  nodes +-kXk[i], Kronrod weights kWk[i]; the 7-point Gauss rule uses the odd nodes with
 *  weights kWg, and the difference of the two estimates the error. */
constexpr double kXk[8] = {
    0.991455371120812639, 0.949107912342758525, 0.864864423359769073, 0.741531185599394440,
    0.586087235467691130, 0.405845151377397167, 0.207784955007898468, 0.0};
constexpr double kWk[8] = {0.022935322010529225, 0.063092092629978553, 0.104790010322250184,
                           0.140653259715525919, 0.169004726639267903, 0.190350578064785410,
                           0.204432940075298892, 0.209482141084727828};
constexpr double kWg[4] = {0.129484966168869693, 0.279705391489276668, 0.381830050505118945,
                           0.417959183673469388};
/** 8-point Gauss-Legendre on [-1, 1] (positive half; the rule is symmetric). */
constexpr double kX8[4] = {0.183434642495649805, 0.525532409916328986, 0.796666477413626740,
                           0.960289856497536232};
constexpr double kW8[4] = {0.362683783378361983, 0.313706645877887287, 0.222381034453374471,
                           0.101228536290376259};

/** The radial integral of (a0 + a1 rho) rho / (pi (1 + rho^2)^2) over [ra, rb] (rb may be
 *  infinite), written so that short intervals far from the origin do not cancel. */
double radial(double a0, double a1, double ra, double rb) {
    const double pa = 1.0 + ra * ra;
    double d1, d2;
    // Both angles below are atan(y / x) with x > 0 (ra, rb >= 0), which atan gives at half the
    // cost of atan2.
    if (std::isinf(rb)) {
        d1 = 0.5 / pa;
        d2 = 0.5 * ((ra > 0.0 ? std::atan(1.0 / ra) : 0.5 * std::numbers::pi) + ra / pa);
    } else {
        const double pb = 1.0 + rb * rb, d = rb - ra;
        d1 = d * (rb + ra) / (2.0 * pa * pb);
        d2 = 0.5 * (std::atan(d / (1.0 + ra * rb)) - d * (1.0 - ra * rb) / (pa * pb));
    }
    return (a0 * d1 + a1 * d2) / std::numbers::pi;
}

/** cos(x) and sin(x) (one sincos call). */
void sincos_of(double x, double& c, double& s) {
    c = std::cos(x);
    s = std::sin(x);
}

/** Roots r0 <= r1 of a rho^2 + b rho + c, a != 0 (numerically stable); false without any. */
bool roots(double a, double b, double c, double& r0, double& r1) {
    const double disc = b * b - 4.0 * a * c;
    if (disc < 0.0) return false;
    const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
    r0 = q / a;
    r1 = q != 0.0 ? c / q : r0;
    if (r0 > r1) std::swap(r0, r1);
    return true;
}

/** The region along one direction: up to two intervals of rho. */
struct Span {
    double lo[2], hi[2];
    int n = 0;
};

/** One (wo, wi) pair in slope coordinates: the cone conic Q1 = A(e) rho^2 + B(e) rho + C and the
 *  horizon conic, per ray direction e. */
struct Problem {
    double alpha = 0.15, a2 = 0.0225;
    double wox = 0, woy = 0, woz = 1;
    double C = 0;                      ///< Q1 at the origin (the normal's own mirror direction)
    double axx = 0, axy = 0, ayy = 0;  ///< A(e) = e^T [axx axy; axy ayy] e
    double bx = 0, by = 0;             ///< B(e) = (bx, by).e
    const FresnelTable* fresnel = nullptr;

    /** The horizon's bound along e: r.z >= 0 for rho <= rho_v. Also where a1 = alpha wo.e. */
    double horizon(double a1) const {
        const double s = std::sqrt(a1 * a1 + woz * woz * a2);
        return a1 > 0.0 ? (s + a1) / (woz * a2) : woz / (s - a1);
    }
    /** The cone's bound along e as it meets the horizon's: the part of [0, rho_v] where Q1 >= 0.
     */
    Span span(double ex, double ey, double& a1) const {
        a1 = alpha * (wox * ex + woy * ey);
        const double rv = horizon(a1);
        const double a = axx * ex * ex + 2.0 * axy * ex * ey + ayy * ey * ey;
        const double b = bx * ex + by * ey;
        Span s;
        const auto add = [&](double lo, double hi) {
            lo = std::max(lo, 0.0);
            hi = std::min(hi, rv);
            if (hi > lo) {
                s.lo[s.n] = lo;
                s.hi[s.n] = hi;
                ++s.n;
            }
        };
        double r0, r1;
        if (a > 0.0) {
            // Q1 >= 0 outside its roots, or everywhere without them.
            if (!roots(a, b, C, r0, r1)) {
                add(0.0, rv);
            } else {
                add(0.0, r0);
                add(r1, INFINITY);
            }
        } else if (a < 0.0) {
            if (roots(a, b, C, r0, r1)) add(r0, r1);  // between its roots
        } else if (b != 0.0) {
            b > 0.0 ? add(-C / b, INFINITY) : add(0.0, -C / b);
        } else if (C >= 0.0) {
            add(0.0, rv);
        }
        return s;
    }
    /** Whether the ray along e meets the cone's conic at all (ignoring the horizon). */
    bool meets(double ex, double ey) const {
        const double a = axx * ex * ex + 2.0 * axy * ex * ey + ayy * ey * ey;
        const double b = bx * ex + by * ey;
        double r0, r1;
        if (a == 0.0) return b != 0.0 && -C / b > 0.0;
        return roots(a, b, C, r0, r1) && r1 > 0.0;
    }
    /** Mass along direction e (and the Fresnel-weighted mass with `fresnel`). */
    double ray(double ex, double ey, double mf[3]) const {
        double a1;
        const Span s = span(ex, ey, a1);
        double m = 0.0;
        for (int k = 0; k < s.n; ++k) {
            const double part = radial(woz, a1, s.lo[k], s.hi[k]);
            m += part;
            if (fresnel && mf) fresnel_along(a1, s.lo[k], s.hi[k], part, mf);
        }
        return m;
    }
    /** Adds `part` times the mean Fresnel over [lo, hi] to mf. In the angle theta = atan(rho)
     *  the radial weight (wo.M) rho / (1 + rho^2)^2 drho is (a0 cos + a1 sin) sin dtheta and
     *  wo.m = (a0 cos + a1 sin) / sqrt(cos^2 + alpha^2 sin^2), both smooth and bounded; the
     *  interval is cut into pieces over which wo.m changes by at most 0.05 (at most 8), three
     *  Gauss points each. Where wo.m changes by less than 0.04 along the whole ray, two Gauss
     *  points of the mass variable u = 1 / (1 + rho^2) are enough (no trigonometry). */
    void fresnel_along(double a1, double lo, double hi, double part, double mf[3]) const {
        const auto cos_rho = [&](double rho) {
            return std::isinf(rho) ? a1 / alpha
                                   : (woz + a1 * rho) / std::sqrt(1.0 + a2 * rho * rho);
        };
        const double span = std::fabs(cos_rho(hi) - cos_rho(lo));
        if (span < 0.01) {
            // Hardly any change: F at the middle of the mass in u.
            const double ulo = 1.0 / (1.0 + lo * lo);
            const double uhi = std::isinf(hi) ? 0.0 : 1.0 / (1.0 + hi * hi);
            const double rho = std::sqrt(std::max(0.0, 2.0 / (ulo + uhi) - 1.0));
            float f[3];
            fresnel->eval(static_cast<float>(std::max(0.0, cos_rho(rho))), f);
            for (int c = 0; c < 3; ++c) mf[c] += part * static_cast<double>(f[c]);
            return;
        }
        if (span < 0.04) {
            // F barely changes along the ray: two Gauss points of the mass variable
            // u = 1 / (1 + rho^2), in which the radial weight is (wo.M) / 2 du.
            const double ulo = 1.0 / (1.0 + lo * lo),
                         uhi = std::isinf(hi) ? 0.0 : 1.0 / (1.0 + hi * hi);
            constexpr double kG = 0.2113248654051871;  // (1 - 1 / sqrt(3)) / 2
            double sum[3] = {0, 0, 0}, wsum = 0.0;
            for (const double g : {kG, 1.0 - kG}) {
                const double u = ulo + (uhi - ulo) * g;
                const double rho = std::sqrt(std::max(0.0, 1.0 / u - 1.0));
                const double w = std::max(0.0, woz + a1 * rho);
                float f[3];
                fresnel->eval(static_cast<float>(w / std::sqrt(1.0 + a2 * rho * rho)), f);
                for (int c = 0; c < 3; ++c) sum[c] += w * static_cast<double>(f[c]);
                wsum += w;
            }
            if (wsum > 0.0)
                for (int c = 0; c < 3; ++c) mf[c] += part * sum[c] / wsum;
            return;
        }
        // theta runs from atan(lo) over dt = atan(hi) - atan(lo), written as one atan; the
        // points' cosines and sines come from (cos, sin) of atan(lo) (algebraic) turned by the
        // pieces' step and the Gauss offsets, with four sincos calls instead of one per point.
        const double dt = std::isinf(hi) ? (lo > 0.0 ? std::atan(1.0 / lo) : 0.5 * std::numbers::pi)
                                         : std::atan((hi - lo) / (1.0 + lo * hi));
        const auto cos_at = [&](double c, double s, double& weight) {
            const double lin = std::max(0.0, woz * c + a1 * s);
            weight = lin * s;
            return lin / std::sqrt(c * c + a2 * s * s);
        };
        const int n = std::min(8, 1 + static_cast<int>(span / 0.05));
        double step_c, step_s, off_c[3], off_s[3];
        sincos_of(dt / n, step_c, step_s);
        for (int g = 0; g < 3; ++g) sincos_of(dt * kGauss3Nodes[g] / n, off_c[g], off_s[g]);
        double base_c = 1.0 / std::sqrt(1.0 + lo * lo), base_s = lo * base_c;
        double sum[3] = {0, 0, 0}, wsum = 0.0;
        for (int p = 0; p < n; ++p) {
            if (p > 0) {
                const double c = base_c * step_c - base_s * step_s;
                base_s = base_s * step_c + base_c * step_s;
                base_c = c;
            }
            for (int g = 0; g < 3; ++g) {
                double weight;
                const double cos_om = cos_at(base_c * off_c[g] - base_s * off_s[g],
                                             base_s * off_c[g] + base_c * off_s[g], weight);
                float f[3];
                fresnel->eval(static_cast<float>(cos_om), f);
                const double w = kGauss3Weights[g] * weight;
                for (int c = 0; c < 3; ++c) sum[c] += w * static_cast<double>(f[c]);
                wsum += w;
            }
        }
        if (!(wsum > 0.0)) return;
        for (int c = 0; c < 3; ++c) mf[c] += part * sum[c] / wsum;
    }
    /** The upper bound of the region along e minus the horizon's, for finding where the horizon
     *  takes over (a kink of the angular integrand). */
    double bound_gap(double phi) const {
        const double ex = std::cos(phi), ey = std::sin(phi);
        const double a1 = alpha * (wox * ex + woy * ey);
        const double rv = horizon(a1);
        // Q1 at the horizon's bound: negative where the cone ends first.
        const double a = axx * ex * ex + 2.0 * axy * ex * ey + ayy * ey * ey;
        const double b = bx * ex + by * ey;
        const double q = (a * rv + b) * rv + C;
        return q / (1.0 + rv * rv);
    }
};

/** The integral of g over [a, b] by the 15-point Gauss-Kronrod rule, and its error estimate
 *  (the difference from the embedded 7-point Gauss rule). g(x, f) returns the mass at x and, when f
 *  is not null, adds the Fresnel-weighted one to f; `mf` receives the Fresnel-weighted integral by
 *  the 7-point rule (the mean Fresnel is smooth: it needs no more). */
template <class G>
double kronrod(const G& g, double a, double b, double& err, double mf[3]) {
    const double mid = 0.5 * (a + b), half = 0.5 * (b - a);
    double k = 0.0, gs = 0.0;
    for (int i = 0; i < 8; ++i) {
        for (int side = 0; side < (i < 7 ? 2 : 1); ++side) {
            const double x = mid + (side ? -half : half) * kXk[i];
            // Fresnel (a smooth average) at the 7 Gauss nodes only, with their weights.
            const bool gauss = i % 2 == 1;
            double f[3] = {0, 0, 0};
            const double v = g(x, gauss ? f : nullptr);
            k += kWk[i] * v;
            if (!gauss) continue;
            gs += kWg[i / 2] * v;
            for (int c = 0; c < 3; ++c) mf[c] += half * kWg[i / 2] * f[c];
        }
    }
    err = std::fabs(k - gs) * half;
    return k * half;
}

/** Adaptive Gauss-Kronrod over [a, b]: halved until the error estimate is below `abs_tol`, at
 *  most `depth` times. */
template <class G>
double adaptive(const G& g, double a, double b, double abs_tol, int depth, double mf[3]) {
    double err, f[3] = {0, 0, 0};
    const double v = kronrod(g, a, b, err, f);
    if (err <= abs_tol || depth == 0) {
        for (int c = 0; c < 3; ++c) mf[c] += f[c];
        return v;
    }
    const double m = 0.5 * (a + b);
    return adaptive(g, a, m, 0.5 * abs_tol, depth - 1, mf) +
           adaptive(g, m, b, 0.5 * abs_tol, depth - 1, mf);
}

/** The integral of g over [a, b] split at `cuts` (sorted, inside): a first Kronrod pass over the
 *  pieces sets the scale, then each piece is refined until its Kronrod-Gauss difference is below
 *  `rel_tol` of it. That difference is the 7-point rule's error; the 15-point result kept is
 *  accurate to about its 1.5th power (Piessens et al. 1983, QUADPACK's error heuristic). */
template <class G>
double pieces(const G& g, double a, double b, const double* cuts, int n_cuts, double mf[3],
              double rel_tol = 1e-4) {
    double edges[12];
    int n = 0;
    edges[n++] = a;
    for (int i = 0; i < n_cuts; ++i) edges[n++] = cuts[i];
    edges[n++] = b;
    double value[12], err[12], f[12][3] = {}, scale = 0.0, total_err = 0.0;
    for (int i = 0; i + 1 < n; ++i) {
        value[i] = kronrod(g, edges[i], edges[i + 1], err[i], f[i]);
        scale += std::fabs(value[i]);
        total_err += err[i];
    }
    const double tol = rel_tol * scale;
    double sum = 0.0;
    for (int i = 0; i + 1 < n; ++i) {
        if (err[i] <= tol / (n - 1) || total_err <= tol) {
            sum += value[i];
            for (int c = 0; c < 3; ++c) mf[c] += f[i][c];
            continue;
        }
        const double m = 0.5 * (edges[i] + edges[i + 1]);
        sum += adaptive(g, edges[i], m, 0.5 * tol / (n - 1), 8, mf) +
               adaptive(g, m, edges[i + 1], 0.5 * tol / (n - 1), 8, mf);
    }
    return sum;
}

/** Kinks of the angular integrand for phi = c + h sin(theta), theta in [t0, t1], where the
 *  horizon and the cone swap as the region's bound: sign changes of bound_gap on 32 samples,
 *  refined by bisection. */
int kinks(const Problem& pr, double c, double h, double t0, double t1, double out[8]) {
    constexpr int kSamples = 32;
    int n = 0;
    double prev_t = t0, prev = pr.bound_gap(c + h * std::sin(t0));
    for (int i = 1; i <= kSamples && n < 8; ++i) {
        const double t = t0 + (t1 - t0) * i / kSamples;
        const double g = pr.bound_gap(c + h * std::sin(t));
        if ((g < 0.0) != (prev < 0.0)) {
            double lo = prev_t, hi = t, glo = prev;
            for (int it = 0; it < 16; ++it) {
                const double m = 0.5 * (lo + hi);
                const double gm = pr.bound_gap(c + h * std::sin(m));
                if ((gm < 0.0) == (glo < 0.0)) {
                    lo = m;
                    glo = gm;
                } else {
                    hi = m;
                }
            }
            out[n++] = 0.5 * (lo + hi);
        }
        prev_t = t;
        prev = g;
    }
    return n;
}

/** The mass over the arc c +- h of directions, in theta (phi = c + h sin(theta)), split at the
 *  horizon's kinks when it can bound the region, refined where the Kronrod estimate asks. */
double arc(const Problem& pr, double c, double h, bool horizon, double mf[3]) {
    const auto g = [&](double th, double f[3]) {
        const double phi = c + h * std::sin(th), jac = h * std::cos(th);
        double raw[3] = {0, 0, 0};
        const double m = pr.ray(std::cos(phi), std::sin(phi), f ? raw : nullptr);
        if (f)
            for (int k = 0; k < 3; ++k) f[k] += jac * raw[k];
        return jac * m;
    };
    double cuts[8];
    const int n =
        horizon ? kinks(pr, c, h, -0.5 * std::numbers::pi, 0.5 * std::numbers::pi, cuts) : 0;
    return pieces(g, -0.5 * std::numbers::pi, 0.5 * std::numbers::pi, cuts, n, mf);
}

/** The periodic trapezoid rule over the whole circle, doubling from 16 directions until two
 *  successive sums differ by 1e-4 (at most 1024 directions). It converges geometrically on this
 *  smooth periodic integrand, so the last sum is accurate to about the square of that. */
double circle(const Problem& pr, double mf[3]) {
    // The mean Fresnel (a smooth average) from at most the first 64 directions.
    int n = 16;
    double sum = 0.0, first_f[3] = {0, 0, 0};
    for (int k = 0; k < n; ++k) {
        const double phi = 2.0 * std::numbers::pi * k / n;
        sum += pr.ray(std::cos(phi), std::sin(phi), first_f);
    }
    double first = sum;
    while (n < 1024) {
        const bool with_f = n < 64;
        double add = 0.0;
        for (int k = 0; k < n; ++k) {
            const double phi = 2.0 * std::numbers::pi * (k + 0.5) / n;
            add += pr.ray(std::cos(phi), std::sin(phi), with_f ? first_f : nullptr);
        }
        const double before = sum / n;
        sum += add;
        if (with_f) first = sum;
        n *= 2;
        if (std::fabs(sum / n - before) <= 1e-4 * std::fabs(sum / n)) break;
    }
    const double mass = sum * 2.0 * std::numbers::pi / n;
    if (first > 0.0)
        for (int c = 0; c < 3; ++c) mf[c] += mass * first_f[c] / first;
    return mass;
}

/** The mass over the whole circle when the horizon may kink it: adaptive Gauss between the
 *  kinks (phi in [-pi, pi]). */
double circle_with_kinks(const Problem& pr, bool horizon, double mf[3]) {
    double cuts[8];
    // phi = pi sin(theta) maps theta in [-pi/2, pi/2] onto [-pi, pi] one to one.
    const int n = horizon ? kinks(pr, 0.0, std::numbers::pi, -0.5 * std::numbers::pi,
                                  0.5 * std::numbers::pi, cuts)
                          : 0;
    for (int i = 0; i < n; ++i) cuts[i] = std::numbers::pi * std::sin(cuts[i]);
    const auto g = [&](double phi, double f[3]) { return pr.ray(std::cos(phi), std::sin(phi), f); };
    return pieces(g, -std::numbers::pi, std::numbers::pi, cuts, n, mf);
}

/** A region that contains the origin, by its boundary (Green's theorem in polar form): with the
 *  boundary parameterised by an angle theta about the conic's centre c,
 *  t(theta) = c + s(theta) L (cos theta, sin theta), the mass is the integral over theta of
 *  F(|t|) dphi/dtheta, F the closed-form radial integral from the origin and phi the polar angle of
 *  t about it. With L the conic's own axes s = 1 and the integrand is smooth and periodic however
 *  close to the boundary the origin lies, where the polar angle about the origin itself would
 *  need hundreds of directions (the ray towards the near boundary changes length fast). */
struct Boundary {
    const Problem& pr;
    double cx = 0, cy = 0;                      ///< interior point
    double l00 = 1, l01 = 0, l10 = 0, l11 = 1;  ///< L: the unit circle onto the region's shape
    double q1c = 0, q2c = 0;                    ///< Q1 and Q2 at c (both positive)

    double q2(double x, double y) const {
        const double a1 = pr.alpha * (pr.wox * x + pr.woy * y);
        return -pr.woz * pr.a2 * (x * x + y * y) + 2.0 * a1 + pr.woz;
    }
    /** The exit along d from c of each constraint (s1: the cone, s2: the horizon). */
    void exits(double dx, double dy, double& s1, double& s2) const {
        const double qa = (pr.axx * dx + 2.0 * pr.axy * dy) * dx + pr.ayy * dy * dy;
        const double qb =
            2.0 * ((pr.axx * cx + pr.axy * cy) * dx + (pr.axy * cx + pr.ayy * cy) * dy) +
            pr.bx * dx + pr.by * dy;
        // q1c > 0: one positive root when qa < 0; when qa >= 0, one only if qb < 0.
        s1 = INFINITY;
        const double disc = qb * qb - 4.0 * qa * q1c;
        if (disc >= 0.0) {
            const double sq = std::sqrt(disc);
            // The smallest positive root of qa s^2 + qb s + q1c = 0.
            const double q = -0.5 * (qb + std::copysign(sq, qb));
            const double inf = std::numeric_limits<double>::infinity();
            const double r0 = q != 0.0 ? q1c / q : inf, r1 = qa != 0.0 ? q / qa : inf;
            for (const double r : {r0, r1})
                if (r > 0.0 && r < s1) s1 = r;
        }
        const double pa = -pr.woz * pr.a2 * (dx * dx + dy * dy);
        const double pb =
            2.0 * (-pr.woz * pr.a2 * (cx * dx + cy * dy) + pr.alpha * (pr.wox * dx + pr.woy * dy));
        const double pd = std::sqrt(pb * pb - 4.0 * pa * q2c);  // pa < 0 < q2c: real
        const double q = -0.5 * (pb + std::copysign(pd, pb));
        s2 = std::max(q2c / q, q / pa);
    }
    /** The integrand at theta: F(|t|) dphi/dtheta; with fw, also its Fresnel-weighted version
     *  (the mean Fresnel along the ray from the origin to the boundary). */
    double at(double th, double fw[3]) const {
        const double ux = std::cos(th), uy = std::sin(th);
        const double dx = l00 * ux + l01 * uy, dy = l10 * ux + l11 * uy;
        const double ex = -l00 * uy + l01 * ux, ey = -l10 * uy + l11 * ux;  // d' = L u'
        double s1, s2;
        exits(dx, dy, s1, s2);
        const bool cone = s1 <= s2;
        const double sv = cone ? s1 : s2;
        const double px = cx + sv * dx, py = cy + sv * dy;
        double gx, gy;  // the gradient of the bounding constraint at p
        if (cone) {
            gx = 2.0 * (pr.axx * px + pr.axy * py) + pr.bx;
            gy = 2.0 * (pr.axy * px + pr.ayy * py) + pr.by;
        } else {
            gx = -2.0 * pr.woz * pr.a2 * px + 2.0 * pr.alpha * pr.wox;
            gy = -2.0 * pr.woz * pr.a2 * py + 2.0 * pr.alpha * pr.woy;
        }
        const double gd = gx * dx + gy * dy;
        const double ds = gd != 0.0 ? -sv * (gx * ex + gy * ey) / gd : 0.0;
        const double ppx = ds * dx + sv * ex, ppy = ds * dy + sv * ey;  // dt/dtheta
        const double r2 = px * px + py * py;
        if (!(r2 > 1e-300)) return 0.0;
        const double rho = std::sqrt(r2);
        const double a1 = pr.alpha * (pr.wox * px + pr.woy * py) / rho;
        const double dphi = (px * ppy - py * ppx) / r2;
        const double v = radial(pr.woz, a1, 0.0, rho) * dphi;
        if (fw && pr.fresnel) pr.fresnel_along(a1, 0.0, rho, v, fw);
        return v;
    }
};

/** The mass (and Fresnel) of a region that contains the origin, by its boundary; false when the
 *  cone's conic is not an ellipse of moderate size (the caller then integrates about the origin).
 *  Where the horizon cuts the region (`horizon`), the boundary's corners (where the bound switches
 *  between the cone and the horizon) split it into pieces done by adaptive Gauss-Kronrod. */
bool boundary_integral(const Problem& pr, bool horizon, double& mass, double mf[3]) {
    Boundary b{pr};
    const auto set_centre = [&](double x, double y) {
        b.cx = x;
        b.cy = y;
        b.q1c = (pr.axx * x + 2.0 * pr.axy * y) * x + pr.ayy * y * y + pr.bx * x + pr.by * y + pr.C;
        b.q2c = b.q2(x, y);
        return b.q1c > 0.0 && b.q2c > 0.0;
    };
    const double det = pr.axx * pr.ayy - pr.axy * pr.axy;
    bool found = false;
    if (pr.axx < 0.0 && det > 0.0) {
        // An ellipse: its centre and axes, (t - c)^T (-A) (t - c) <= Q1(c), eigenvectors of -A.
        const double ex = -0.5 * (pr.ayy * pr.bx - pr.axy * pr.by) / det;
        const double ey = -0.5 * (pr.axx * pr.by - pr.axy * pr.bx) / det;
        const double q1e = 0.5 * (pr.bx * ex + pr.by * ey) + pr.C;
        if (!(q1e > 0.0)) return false;
        const double tr = -(pr.axx + pr.ayy), dev = std::hypot(pr.axx - pr.ayy, 2.0 * pr.axy);
        const double l1 = 0.5 * (tr + dev), l2 = 0.5 * (tr - dev);  // l1 >= l2 > 0
        const double ang = 0.5 * std::atan2(-2.0 * pr.axy, -(pr.axx - pr.ayy));
        const double ca = std::cos(ang), sa = std::sin(ang);
        const double r1 = std::sqrt(q1e / l1), r2 = std::sqrt(q1e / l2);
        // Regions much wider than the kernel (which peaks at the origin, width 1) put a sharp
        // feature into the boundary integrand: those are done about the origin.
        if (r2 > 20.0) return false;
        b.l00 = ca * r1;
        b.l10 = sa * r1;
        b.l01 = -sa * r2;
        b.l11 = ca * r2;
        // The centre, or where the horizon cuts it away a point towards the origin (which is
        // inside both the cone's region and the horizon's disc).
        for (const double tau : {0.0, 0.5, 0.8, 1.0})
            if ((found = set_centre((1.0 - tau) * ex, (1.0 - tau) * ey))) break;
    } else {
        // Not an ellipse (the cone's region is unbounded in the slope plane and the horizon's
        // disc bounds it): about the origin.
        return false;
    }
    if (!found) return false;
    double cuts[8];
    int n_cuts = 0;
    if (horizon) {
        const auto cone_bounds = [&](double th) {
            const double ux = std::cos(th), uy = std::sin(th);
            double s1, s2;
            b.exits(b.l00 * ux + b.l01 * uy, b.l10 * ux + b.l11 * uy, s1, s2);
            return s1 <= s2;
        };
        constexpr int kScan = 32;
        bool prev = cone_bounds(0.0);
        for (int i = 1; i <= kScan && n_cuts < 8; ++i) {
            const double th = 2.0 * std::numbers::pi * i / kScan;
            const bool now = cone_bounds(th);
            if (now == prev) continue;
            double lo = 2.0 * std::numbers::pi * (i - 1) / kScan, hi = th;
            for (int it = 0; it < 24; ++it) {
                const double m = 0.5 * (lo + hi);
                (cone_bounds(m) == prev ? lo : hi) = m;
            }
            cuts[n_cuts++] = 0.5 * (lo + hi);
            prev = now;
        }
    }
    if (n_cuts > 0) {
        // Between consecutive corners, around the circle.
        const auto g = [&](double th, double* f) { return b.at(th, f); };
        mass = 0.0;
        double f[3] = {0, 0, 0};
        for (int i = 0; i < n_cuts; ++i) {
            const double a0 = cuts[i],
                         a1 = i + 1 < n_cuts ? cuts[i + 1] : cuts[0] + 2.0 * std::numbers::pi;
            mass += pieces(g, a0, a1, nullptr, 0, f, 1e-5);
        }
        for (int c = 0; c < 3; ++c) mf[c] = f[c];
        return true;
    }
    // Periodic trapezoid, doubling from 16 angles until two sums agree to 1e-5 (the last one is
    // then accurate to far better: on a near-ellipse the error falls geometrically). The mean
    // Fresnel (a smooth average) from at most the first 64 angles.
    int n = 16;
    double sum = 0.0, fw[3] = {0, 0, 0};
    for (int k = 0; k < n; ++k)
        sum += b.at(2.0 * std::numbers::pi * k / n, pr.fresnel ? fw : nullptr);
    double first = sum;
    while (n < 1024) {
        const bool with_f = pr.fresnel && n < 64;
        double add = 0.0;
        for (int k = 0; k < n; ++k)
            add += b.at(2.0 * std::numbers::pi * (k + 0.5) / n, with_f ? fw : nullptr);
        const double before = sum / n;
        sum += add;
        if (with_f) first = sum;
        n *= 2;
        if (std::fabs(sum / n - before) <= 1e-5 * std::fabs(sum / n)) break;
    }
    mass = sum * 2.0 * std::numbers::pi / n;
    for (int c = 0; c < 3; ++c) mf[c] = first > 0.0 ? mass * fw[c] / first : 0.0;
    return true;
}

}  // namespace

void slope_integral(float alpha, double sin2_half, const FresnelTable* fresnel, V3 wo_f, V3 wi_f,
                    float i_f[3], float& i_1) {
    i_f[0] = i_f[1] = i_f[2] = i_1 = 0.0f;
    if (!(wo_f.z > 0.0f) || !(wi_f.z > 0.0f)) return;
    Problem pr;
    pr.alpha = alpha;
    pr.a2 = pr.alpha * pr.alpha;
    pr.fresnel = fresnel;
    pr.wox = wo_f.x;
    pr.woy = wo_f.y;
    pr.woz = wo_f.z;
    const double wix = wi_f.x, wiy = wi_f.y, wiz = wi_f.z;
    const double k = pr.wox * wix + pr.woy * wiy + pr.woz * wiz + (1.0 - 2.0 * sin2_half);
    // Q1 = 2 (a0 + a1 rho)(b0 + b1 rho) - k (1 + alpha^2 rho^2), a = alpha (wo.e), b = alpha
    // (wi.e).
    pr.axx = pr.a2 * (2.0 * pr.wox * wix - k);
    pr.ayy = pr.a2 * (2.0 * pr.woy * wiy - k);
    pr.axy = pr.a2 * (pr.wox * wiy + pr.woy * wix);
    pr.bx = 2.0 * pr.alpha * (pr.woz * wix + wiz * pr.wox);
    pr.by = 2.0 * pr.alpha * (pr.woz * wiy + wiz * pr.woy);
    // At the origin, 2 wo_z wi_z - wo.wi - cos(gamma) = r0.wi - cos(gamma) with r0 the mirror
    // direction: written through |r0 - wi|^2 it does not cancel near the cone's rim.
    const double dx = -pr.wox - wix, dy = -pr.woy - wiy, dz = pr.woz - wiz;
    pr.C = 2.0 * sin2_half - 0.5 * (dx * dx + dy * dy + dz * dz);
    // The horizon can bound the region only when wi's cone reaches under it.
    const double sin_g = 2.0 * std::sqrt(sin2_half * (1.0 - sin2_half));
    const bool horizon = wiz < sin_g * 1.0001 + 1e-12;
    double mf[3] = {0, 0, 0}, mass = 0.0;
    // The origin close to the cone's boundary (relative to the cone's own scale, C <= 2 sin^2):
    // the integrand has features of angular width about sqrt(|C| / (2 sin^2(gamma / 2))).
    const bool near = std::fabs(pr.C) < 0.05 * 2.0 * sin2_half;
    if (pr.C > 0.0 && boundary_integral(pr, horizon, mass, mf)) {
        // The origin inside: by the region's boundary (see Boundary).
    } else if (pr.C >= 0.0) {
        mass = horizon || near ? circle_with_kinks(pr, horizon, mf) : circle(pr, mf);
    } else {
        // Directions that meet the cone's conic: B(e)^2 - 4 A(e) C >= 0, a quadratic form in e,
        // m + p cos(2 phi) + q sin(2 phi). Of its two antipodal arcs, the one with positive roots.
        const double nxx = pr.bx * pr.bx - 4.0 * pr.C * pr.axx;
        const double nyy = pr.by * pr.by - 4.0 * pr.C * pr.ayy;
        const double nxy = pr.bx * pr.by - 4.0 * pr.C * pr.axy;
        const double m = 0.5 * (nxx + nyy), p = 0.5 * (nxx - nyy), q = nxy;
        const double amp = std::hypot(p, q);
        if (amp <= std::fabs(m)) {
            // No tangent: every ray meets the conic (an unbounded region) or none does.
            if (m > 0.0) mass = circle_with_kinks(pr, horizon, mf);
        } else {
            const double phi0 = 0.5 * std::atan2(q, p);
            const double h = 0.5 * std::acos(std::clamp(-m / amp, -1.0, 1.0));
            for (const double c : {phi0, phi0 + std::numbers::pi}) {
                if (!pr.meets(std::cos(c), std::sin(c))) continue;
                mass += arc(pr, c, h, horizon, mf);
            }
        }
    }
    const double g1 = static_cast<double>(mf::ggx_g1(wo_f, alpha, alpha)) / pr.woz;
    i_1 = static_cast<float>(std::max(0.0, mass * g1));
    if (fresnel)
        for (int c = 0; c < 3; ++c) i_f[c] = static_cast<float>(std::max(0.0, mf[c] * g1));
}

double lobe_mass(float alpha, double sin2_half, V3 wo_f) {
    if (!(wo_f.z > 0.0f)) return 0.0;
    // In wo's azimuthal frame the integrand is symmetric in phi -> -phi: [0, pi] suffices.
    const double a = alpha, a2 = a * a;
    const double woz = wo_f.z, wox = std::sqrt(std::max(0.0, 1.0 - woz * woz));
    const double sg = 2.0 * std::sqrt(sin2_half * (1.0 - sin2_half));
    const auto ray = [&](double phi) {
        const double a1 = a * wox * std::cos(phi);
        const double s = std::sqrt(a1 * a1 + woz * woz * a2);
        const double rv = a1 > 0.0 ? (s + a1) / (woz * a2) : woz / (s - a1);
        // r.z >= sin(gamma) (A = 1) where -(woz + sg) a2 rho^2 + 2 a1 rho + (woz - sg) >= 0.
        double full = 0.0, r0 = 0.0, r1 = 0.0;
        double lo = 0.0, hi = 0.0;  // the interval with A = 1
        if (roots(-(woz + sg) * a2, 2.0 * a1, woz - sg, r0, r1)) {
            lo = std::clamp(r0, 0.0, rv);
            hi = std::clamp(r1, 0.0, rv);
            if (hi > lo) full = radial(woz, a1, lo, hi);
        }
        // The band where the cone crosses the horizon: [0, lo) and (hi, rv], A by Gauss in
        // theta = atan(rho), where the radial weight (a0 cos + a1 sin) sin dtheta is smooth and
        // bounded (in rho it is concentrated at the band's near end): 8 points.
        double band = 0.0;
        for (const auto& [b0, b1] : {std::pair<double, double>{0.0, lo}, {hi, rv}}) {
            if (!(b1 > b0)) continue;
            const double t0 = std::atan(b0), t1 = std::atan(b1);
            for (int piece = 0; piece < 1; ++piece)
                for (int g = 0; g < 8; ++g) {
                    const double x = g < 4 ? -kX8[3 - g] : kX8[g - 4];
                    const double w = kW8[g < 4 ? 3 - g : g - 4] * 0.5 * (t1 - t0);
                    const double th = t0 + (t1 - t0) * (piece + 0.5 + 0.5 * x);
                    const double c = std::cos(th), sn = std::sin(th), rho = sn / c;
                    const double rz = (2.0 * (woz + a1 * rho) - woz * (1.0 + a2 * rho * rho)) /
                                      (1.0 + a2 * rho * rho);
                    band += w * (woz * c + a1 * sn) * sn / std::numbers::pi *
                            cone_fraction_above(rz, sin2_half);
                }
        }
        return full + band;
    };
    // Adaptive Gauss-Kronrod over the half circle, split where the integrand has a kink: when
    // the view is lower than the cone is wide (wo_z < sin(gamma)), the rays with
    // a1^2 < alpha^2 (sin^2(gamma) - wo_z^2) meet no direction whose whole cone is above the
    // horizon, and the interval with A = 1 appears where the quadratic's discriminant vanishes,
    // cos(phi) = sqrt(sin^2(gamma) - wo_z^2) / wo_x (its roots are negative on the other side).
    double cuts[1];
    int n_cuts = 0;
    if (woz < sg && wox > 0.0) {
        const double c = std::sqrt(sg * sg - woz * woz) / wox;
        if (c < 1.0) cuts[n_cuts++] = std::acos(c);
    }
    double unused[3] = {0, 0, 0};
    const double half = pieces([&](double phi, double*) { return ray(phi); }, 0.0, std::numbers::pi,
                               cuts, n_cuts, unused, 1e-6);
    // Twice the half circle, times G1(wo) / wo_z.
    const double g1 = static_cast<double>(mf::ggx_g1(wo_f, alpha, alpha)) / woz;
    return std::clamp(2.0 * half * g1, 0.0, 1.0);
}

}  // namespace spangle::flake
