#include "cap_integral.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace spangle::flake {

namespace {

struct D3 {
    double x = 0, y = 0, z = 0;
};
D3 operator+(D3 a, D3 b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
D3 operator*(D3 a, double s) {
    return {a.x * s, a.y * s, a.z * s};
}
double dot(D3 a, D3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
[[maybe_unused]] D3 cross(D3 a, D3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
D3 normalized(D3 a) {
    const double l = std::sqrt(dot(a, a));
    return l > 0.0 ? a * (1.0 / l) : D3{0, 0, 1};
}
D3 to_d(V3 v) {
    return {v.x, v.y, v.z};
}

/** atan for x >= 0: a series for small x (the common case: caps much smaller than a radian). */
double fast_atan(double x) {
    if (x < 0.25) {
        const double x2 = x * x;
        return x *
               (1.0 - x2 * (1.0 / 3.0 -
                            x2 * (1.0 / 5.0 - x2 * (1.0 / 7.0 - x2 * (1.0 / 9.0 - x2 / 11.0)))));
    }
    return std::atan(x);
}

/** sin and cos of t >= 0: Taylor series below 0.5 (error under 1e-10), the library above. */
void fast_sincos(double t, double& s, double& c) {
    if (t < 0.5) {
        const double t2 = t * t;
        s = t * (1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))));
        c = 1.0 - t2 / 2.0 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0)));
        return;
    }
    s = std::sin(t);
    c = std::cos(t);
}

/** A symmetric 3x3 matrix, the quadric n^T Q n. */
struct Sym {
    double xx = 0, yy = 0, zz = 0, xy = 0, xz = 0, yz = 0;
    double form(D3 a, D3 b) const {
        return a.x * (xx * b.x + xy * b.y + xz * b.z) + a.y * (xy * b.x + yy * b.y + yz * b.z) +
               a.z * (xz * b.x + yz * b.y + zz * b.z);
    }
};

/** S (a b^T + b a^T + k I) S with S = diag(alpha, alpha, 1): a quadric of normals m expressed in
 *  the unstretched frame (m = S n). */
Sym stretched(D3 a, D3 b, double k, double alpha) {
    const double s[3] = {alpha, alpha, 1.0};
    const double av[3] = {a.x, a.y, a.z}, bv[3] = {b.x, b.y, b.z};
    double m[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            m[i][j] = s[i] * s[j] * (av[i] * bv[j] + bv[i] * av[j] + (i == j ? k : 0.0));
    return {m[0][0], m[1][1], m[2][2], m[0][1], m[0][2], m[1][2]};
}

/** A quadric restricted to the great circles through c0: Q(cos t c0 + sin t d) for
 *  d = cos(phi) e1 + sin(phi) e2 is a cos^2 t + 2 b sin t cos t + c sin^2 t. */
struct RayQuadric {
    double a = 0, b1 = 0, b2 = 0, c11 = 0, c12 = 0, c22 = 0;
    RayQuadric(const Sym& q, D3 c0, D3 e1, D3 e2, double a_exact)
        : a(a_exact),
          b1(q.form(c0, e1)),
          b2(q.form(c0, e2)),
          c11(q.form(e1, e1)),
          c12(q.form(e1, e2)),
          c22(q.form(e2, e2)) {}
    /** Smallest angle t in (0, pi] where the quadric reaches zero along direction (cs, sn); pi
     *  when it stays positive. a > 0 (c0 is inside). */
    double first_zero(double cs, double sn) const {
        const double b = cs * b1 + sn * b2;
        const double c = cs * cs * c11 + 2.0 * cs * sn * c12 + sn * sn * c22;
        // a + 2 b x + c x^2 = 0 for x = tan t: x > 0 gives t in (0, pi/2), x < 0 t in (pi/2, pi).
        if (c == 0.0) {
            // cos t (a cos t + 2 b sin t): zero at pi/2, or earlier when b < 0.
            return b < 0.0 ? fast_atan(-a / (2.0 * b)) : 0.5 * std::numbers::pi;
        }
        const double disc = b * b - a * c;
        if (disc < 0.0) return std::numbers::pi;
        const double q = -(b + std::copysign(std::sqrt(disc), b));
        if (q == 0.0) return std::numbers::pi;
        double best = std::numbers::pi;
        for (const double x : {q / c, a / q}) {
            if (!std::isfinite(x) || x == 0.0) continue;
            best = std::min(best, x > 0.0 ? fast_atan(x) : std::numbers::pi - fast_atan(-x));
        }
        return best;
    }
    /** A lower bound of the angle of the first zero over every direction. */
    double first_zero_bound() const {
        const double bmax = std::sqrt(b1 * b1 + b2 * b2);
        const double tr = 0.5 * (c11 + c22),
                     dev = std::sqrt(0.25 * (c11 - c22) * (c11 - c22) + c12 * c12);
        const double cmin = tr - dev;  // the most negative c over directions
        // a cos^2 - 2 bmax sin cos + cmin sin^2 >= 0 up to its first root.
        RayQuadric worst = *this;
        worst.b1 = -bmax;
        worst.b2 = 0.0;
        worst.c11 = cmin;
        worst.c12 = 0.0;
        worst.c22 = cmin;
        return worst.first_zero(1.0, 0.0);
    }
};

/** A half-space n.e >= 0 along the great circles through c0 (c0.e > 0). */
struct RayPlane {
    double l0 = 0, l1 = 0, l2 = 0;
    RayPlane(D3 e, D3 c0, D3 e1, D3 e2) : l0(dot(c0, e)), l1(dot(e1, e)), l2(dot(e2, e)) {}
    double first_zero(double cs, double sn) const {
        const double l = cs * l1 + sn * l2;
        // l0 cos t + l sin t = 0.
        if (l >= 0.0)
            return l == 0.0 ? 0.5 * std::numbers::pi : std::numbers::pi - fast_atan(l0 / l);
        return fast_atan(l0 / -l);
    }
    double distance() const { return std::asin(std::clamp(l0, -1.0, 1.0)); }
};

void basis(D3 n, D3& e1, D3& e2) {
    const double sign = std::copysign(1.0, n.z);
    const double a = -1.0 / (sign + n.z), b = n.x * n.y * a;
    e1 = {1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x};
    e2 = {b, sign + n.y * n.y * a, -n.y};
}

/** Projected-area mass of the arc from c0 along d up to angle t: the integral of
 *  (v.n) sin(s) ds, with vc = v.c0 and vd = v.d. */
double arc_mass(double vc, double vd, double t) {
    double s, c;
    fast_sincos(t, s, c);
    return 0.5 * (vc * s * s + vd * (t - s * c));
}

/** Everything the angular sum needs for one (wo, region) pair. Directions around c0 are
 *  d(psi) = normalize(cos(psi) e1 / sqrt(k1) + sin(psi) e2 / sqrt(k2)) (e1, e2 turned onto the
 *  ellipse's axes): for a region bounded by the ellipse k1 x^2 + k2 y^2 = 1 in the tangent plane
 *  the mass per unit psi is then constant, so the trapezoid rule converges in a few steps even for
 *  very elongated regions (grazing views). k1 = k2 = 1 is the plain polar angle. */
struct Region {
    D3 c0, e1, e2, v;
    double rk1 = 1.0, rk2 = 1.0;        ///< 1 / sqrt(k1), 1 / sqrt(k2)
    double axis_c = 1.0, axis_s = 0.0;  ///< the ellipse's first axis, in the (e1, e2) basis
    double alpha = 1.0;
    D3 wo;
    const FresnelTable* fresnel = nullptr;  ///< set: integrate F along each arc
    const RayQuadric* quadrics[2] = {nullptr, nullptr};
    const RayPlane* planes[2] = {nullptr, nullptr};
    int nq = 0, np = 0;
};

/** An empty region centred on c0 (with its own tangent basis) for view wo. */
Region region_at(D3 c0, D3 v, double alpha, D3 wo) {
    Region r;
    r.c0 = c0;
    basis(c0, r.e1, r.e2);
    r.v = v;
    r.alpha = alpha;
    r.wo = wo;
    return r;
}

/** cos and sin of 2 pi k / 4096. */
struct AngleTable {
    static constexpr int kSize = 4096;
    double c[kSize], s[kSize];
    AngleTable() {
        for (int k = 0; k < kSize; ++k) {
            c[k] = std::cos(2.0 * std::numbers::pi * k / kSize);
            s[k] = std::sin(2.0 * std::numbers::pi * k / kSize);
        }
    }
};
const AngleTable& angles() {
    static const AngleTable t;
    return t;
}

/** Mass (and, with r.fresnel, Fresnel-weighted mass) of the region along direction
 *  psi = 2 pi k / 4096, times d(phi)/d(psi). */
void arc_at(const Region& r, int k, double& mass, double mass_f[3]) {
    const AngleTable& at = angles();
    const double x = at.c[k] * r.rk1, y = at.s[k] * r.rk2;
    const double len2 = x * x + y * y, inv = 1.0 / std::sqrt(len2);
    // From the ellipse's axes back to the (e1, e2) basis the constraints were expressed in.
    const double cs = (r.axis_c * x - r.axis_s * y) * inv, sn = (r.axis_s * x + r.axis_c * y) * inv;
    // phi = atan2(y, x): d(phi)/d(psi) = 1 / (sqrt(k1 k2) (x^2 + y^2)) = rk1 rk2 / len2.
    const double jac = r.rk1 * r.rk2 / len2;
    double t = r.quadrics[0]->first_zero(cs, sn);
    for (int i = 1; i < r.nq; ++i) t = std::min(t, r.quadrics[i]->first_zero(cs, sn));
    for (int i = 0; i < r.np; ++i) t = std::min(t, r.planes[i]->first_zero(cs, sn));
    const D3 d = r.e1 * cs + r.e2 * sn;
    const double vc = dot(r.v, r.c0), vd = dot(r.v, d);
    mass = arc_mass(vc, vd, t) * jac;
    if (!r.fresnel) return;
    // F along the arc, over sub-arcs that each turn the (stretched) normal by at most 0.05 rad
    // (the unstretched frame magnifies angles near the normal by 1 / alpha): per sub-arc, F at two
    // Gauss points weighted by the mass density there, so that the sub-arc from c0, whose mass
    // grows as t, is not weighted as if uniform.
    double s_end, c_end;
    fast_sincos(t, s_end, c_end);
    const D3 n_end = r.c0 * c_end + d * s_end;
    const D3 m0 = normalized({r.alpha * r.c0.x, r.alpha * r.c0.y, r.c0.z});
    const D3 m1 = normalized({r.alpha * n_end.x, r.alpha * n_end.y, n_end.z});
    const double turn = std::acos(std::clamp(dot(m0, m1), -1.0, 1.0));
    const int pieces = std::min(32, 1 + static_cast<int>(turn / 0.05));
    double prev = 0.0, t0 = 0.0;
    mass_f[0] = mass_f[1] = mass_f[2] = 0.0;
    constexpr double kHalfGauss = 0.5 / 1.7320508075688772;  // Gauss points mid +- half / sqrt 3
    for (int p = 1; p <= pieces; ++p) {
        const double t1 = t * p / pieces;
        const double cum = arc_mass(vc, vd, t1);
        double sum[3] = {0, 0, 0}, wsum = 0.0;
        for (const double g : {0.5 - kHalfGauss, 0.5 + kHalfGauss}) {
            double s, c;
            fast_sincos(t0 + (t1 - t0) * g, s, c);
            const double w = std::max(0.0, vc * s * c + vd * s * s);  // d(arc_mass)/dt
            const D3 n = r.c0 * c + d * s;
            const D3 m = normalized({r.alpha * n.x, r.alpha * n.y, n.z});
            float f[3];
            r.fresnel->eval(static_cast<float>(dot(r.wo, m)), f);
            for (int ch = 0; ch < 3; ++ch) sum[ch] += w * static_cast<double>(f[ch]);
            wsum += w;
        }
        for (int ch = 0; ch < 3; ++ch)
            mass_f[ch] += (cum - prev) * jac * (wsum > 0.0 ? sum[ch] / wsum : 0.0);
        prev = cum;
        t0 = t1;
    }
}

/** The region's mass (and Fresnel-weighted mass with r.fresnel) by the trapezoid rule in psi,
 *  doubling the number of directions from 4 until two successive sums agree to `tolerance`
 *  (relative), with at least 8 and at most 4096 directions. */
double angular_sum(const Region& r, double tolerance, double sum_f[3]) {
    sum_f[0] = sum_f[1] = sum_f[2] = 0.0;
    double total = 0.0, f[3] = {0, 0, 0};
    int n = 4;
    for (int k = 0; k < n; ++k) {
        double m;
        arc_at(r, k * (AngleTable::kSize / n), m, f);
        total += m;
        for (int c = 0; c < 3; ++c) sum_f[c] += f[c];
    }
    while (n < AngleTable::kSize) {
        // The midpoints of the current grid refine it to 2n directions.
        const int step = AngleTable::kSize / n;
        double add = 0.0, add_f[3] = {0, 0, 0};
        for (int k = 0; k < n; ++k) {
            double m;
            arc_at(r, k * step + step / 2, m, f);
            add += m;
            for (int c = 0; c < 3; ++c) add_f[c] += f[c];
        }
        const double previous = total / n;
        total += add;
        for (int c = 0; c < 3; ++c) sum_f[c] += add_f[c];
        n *= 2;
        const double current = total / n;
        if (std::fabs(current - previous) <= tolerance * std::fabs(current)) break;
    }
    const double w = 2.0 * std::numbers::pi / n;
    for (int c = 0; c < 3; ++c) sum_f[c] *= w;
    return total * w;
}

/** Principal axes of the cap quadric's tangent part: when it is negative definite, the region is
 *  (to first order) the ellipse it defines; sets the axes and k1, k2 (their product 1). */
void fit_ellipse(Region& r, const RayQuadric& cap) {
    const double tr = 0.5 * (cap.c11 + cap.c22);
    const double dev =
        std::sqrt(0.25 * (cap.c11 - cap.c22) * (cap.c11 - cap.c22) + cap.c12 * cap.c12);
    const double l1 = tr - dev, l2 = tr + dev;  // l1 <= l2
    if (!(l2 < 0.0)) return;                    // not an ellipse: plain polar angle
    // The eigenvector of the larger eigenvalue l2 (the ellipse's long axis) is at `angle`.
    const double angle = 0.5 * std::atan2(2.0 * cap.c12, cap.c11 - cap.c22);
    r.axis_c = std::cos(angle);
    r.axis_s = std::sin(angle);
    // Only the ratio matters: k1 = sqrt(l2 / l1), k2 = 1 / k1.
    const double ratio = std::sqrt(l2 / l1);
    r.rk1 = 1.0 / std::sqrt(ratio);
    r.rk2 = std::sqrt(ratio);
}

/** The unstretched view direction and its hemisphere's projected area pi (1 + v.z) / 2. */
D3 unstretched_view(float alpha, V3 wo, double& area) {
    const double a = alpha;
    const D3 v = normalized(
        {a * static_cast<double>(wo.x), a * static_cast<double>(wo.y), static_cast<double>(wo.z)});
    area = 0.5 * std::numbers::pi * (1.0 + v.z);
    return v;
}

/** The validity quadric r(m).z >= 0: 2 (wo.m) m_z - wo.z |m|^2 >= 0. */
Sym validity_quadric(D3 wo, double alpha) {
    return stretched(wo, {0, 0, 1}, -wo.z, alpha);
}

}  // namespace

double valid_fraction_exact(float alpha, V3 wo_f, double tolerance) {
    if (!(wo_f.z > 0.0f)) return 0.0;
    double area = 0.0;
    const D3 wo = to_d(wo_f), v = unstretched_view(alpha, wo_f, area);
    // Around the normal itself: m = z reflects wo to its mirror image, above the horizon.
    const D3 c0{0, 0, 1};
    Region r = region_at(c0, v, alpha, wo);
    const Sym q2 = validity_quadric(wo, alpha);
    const RayQuadric valid(q2, c0, r.e1, r.e2, q2.form(c0, c0));
    const RayPlane up({0, 0, 1}, c0, r.e1, r.e2), visible(v, c0, r.e1, r.e2);
    r.quadrics[r.nq++] = &valid;
    r.planes[r.np++] = &up;
    r.planes[r.np++] = &visible;
    double unused[3];
    return std::clamp(angular_sum(r, tolerance, unused) / area, 0.0, 1.0);
}

void cap_integral(const CapParams& p, V3 wo_f, V3 wi_f, float i_f[3], float& i_1,
                  double tolerance) {
    i_f[0] = i_f[1] = i_f[2] = i_1 = 0.0f;
    if (!(wo_f.z > 0.0f) || !(wi_f.z > 0.0f)) return;
    const D3 wo = to_d(wo_f), wi = to_d(wi_f);
    const double alpha = p.alpha;
    double area = 0.0;
    const D3 v = unstretched_view(p.alpha, wo_f, area);
    // Centre: the unstretched image of the half vector, whose mirror direction is wi itself.
    const D3 h = normalized(wo + wi);
    const D3 c0 = normalized({h.x / alpha, h.y / alpha, h.z});
    Region r = region_at(c0, v, alpha, wo);
    const D3 e1 = r.e1, e2 = r.e2;
    const D3 sc0{alpha * c0.x, alpha * c0.y, c0.z};
    // r.wi >= cos(gamma) <=> 2 (wo.m)(wi.m) - (1 + wo.wi)|m|^2 + 2 sin^2(gamma/2)|m|^2 >= 0. The
    // first part vanishes at c0, so its value there is the second part alone, without cancellation.
    Sym q1 = stretched(wo, wi, -(1.0 + dot(wo, wi)), alpha);
    const double k = 2.0 * p.sin2_half;
    q1.xx += k * alpha * alpha;
    q1.yy += k * alpha * alpha;
    q1.zz += k;
    const RayQuadric cap(q1, c0, e1, e2, k * dot(sc0, sc0));
    const Sym q2 = validity_quadric(wo, alpha);
    const RayQuadric valid(q2, c0, e1, e2, q2.form(c0, c0));
    const RayPlane up({0, 0, 1}, c0, e1, e2), visible(v, c0, e1, e2);
    r.quadrics[r.nq++] = &cap;
    // The cap's extent bounds where the other constraints can matter.
    double reach = 0.0;
    for (int j = 0; j < 8; ++j) {
        const double phi = 2.0 * std::numbers::pi * j / 8;
        reach = std::max(reach, cap.first_zero(std::cos(phi), std::sin(phi)));
    }
    const double margin = 1.5 * reach + 1e-3;
    if (valid.first_zero_bound() < margin) r.quadrics[r.nq++] = &valid;
    if (up.distance() < margin) r.planes[r.np++] = &up;
    if (visible.distance() < margin) r.planes[r.np++] = &visible;
    fit_ellipse(r, cap);
    r.fresnel = p.fresnel;
    double f[3];
    const double mass = angular_sum(r, tolerance, f);
    i_1 = static_cast<float>(mass / area);
    for (int c = 0; c < 3; ++c) i_f[c] = p.fresnel ? static_cast<float>(f[c] / area) : 0.0f;
}

}  // namespace spangle::flake
