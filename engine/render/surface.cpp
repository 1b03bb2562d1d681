#include "render/surface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace spangle {

void shading_frame(Vec3 n, Vec3 along, Vec3& s, Vec3& t) {
    s = along - n * dot(n, along);
    const float s_len = length(s);
    if (s_len > 1e-12f && std::isfinite(s_len)) {
        s = s / s_len;
        t = cross(n, s);
    } else {
        make_basis(n, s, t);
    }
}

bool keep_reflection_above(SurfacePoint& sp, Vec3 wo) {
    const float cos_g = dot(wo, sp.ng);
    if (!(cos_g > 0.0f)) return false;  // wo on the geometric back (rounding): nothing to keep
    const float limit = std::min(0.9f * cos_g, 0.01f);
    const Vec3 r = sp.n * (2.0f * dot(wo, sp.n)) - wo;
    const float rz = dot(r, sp.ng);
    if (rz >= limit || !std::isfinite(rz)) return false;
    // The valid reflection nearest to r: its part along the plane, lifted to height `limit`.
    // Where r points straight into the surface, the mirror image of wo about ng stands in. In
    // double: wo and that reflection can nearly cancel in their sum.
    const auto d3 = [](Vec3 v, double out[3]) {
        out[0] = v.x;
        out[1] = v.y;
        out[2] = v.z;
    };
    double w[3], g[3], a[3], sn[3];
    d3(wo, w);
    d3(sp.ng, g);
    d3(sp.n, sn);
    // Unit to the last bit: where wo and the reflection nearly oppose, their half vector turns
    // with any difference of their lengths, and a short horizontal part of r keeps what ng's
    // length error leaves of its height.
    for (double* v : {w, g, sn}) {
        const double v_len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int k = 0; k < 3; ++k) v[k] /= v_len;
    }
    const double cw = w[0] * g[0] + w[1] * g[1] + w[2] * g[2];
    const double wn = w[0] * sn[0] + w[1] * sn[1] + w[2] * sn[2];
    for (int k = 0; k < 3; ++k) a[k] = 2.0 * wn * sn[k] - w[k];  // r
    const double az = a[0] * g[0] + a[1] * g[1] + a[2] * g[2];
    for (int k = 0; k < 3; ++k) a[k] -= g[k] * az;
    double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(len > 1e-9)) {
        for (int k = 0; k < 3; ++k) a[k] = g[k] * cw - w[k];
        len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    }
    if (!(len > 1e-9)) {
        d3(sp.s, a);
        len = 1.0;
    }
    const double lim = limit, along = std::sqrt(1.0 - lim * lim) / len;
    double h[3];
    for (int k = 0; k < 3; ++k) h[k] = w[k] + a[k] * along + g[k] * lim;
    const double h_len = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (!(h_len > 0.0) || !std::isfinite(h_len)) return false;
    sp.n = Vec3(static_cast<float>(h[0] / h_len), static_cast<float>(h[1] / h_len),
                static_cast<float>(h[2] / h_len));
    shading_frame(sp.n, sp.s, sp.s, sp.t);
    return true;
}

namespace {

/** Embree's float rounding of a hit's distance to its triangle's plane, in float epsilons of
 *  the corners' coordinates along the normal: on a plane tilted 30 degrees with corners at 1e7
 *  in its file, 0.125 and 0.5 left streaks of self-hits, 1 none; twice that. */
constexpr float kPlaneRounding = 2.0f;

float max_abs(Vec3 v) {
    return std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
}

/** The ray's point on the plane of p0, p1, p2, in double; false when the ray runs along it. */
bool on_plane(Vec3 o, Vec3 d, Vec3 p0, Vec3 p1, Vec3 p2, Vec3& out) {
    const double a[3] = {p0.x, p0.y, p0.z};
    const double e1[3] = {double(p1.x) - a[0], double(p1.y) - a[1], double(p1.z) - a[2]};
    const double e2[3] = {double(p2.x) - a[0], double(p2.y) - a[1], double(p2.z) - a[2]};
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                         e1[0] * e2[1] - e1[1] * e2[0]};
    const double od[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
    double num = 0.0, den = 0.0;
    for (int i = 0; i < 3; ++i) {
        num += (a[i] - od[i]) * n[i];
        den += dd[i] * n[i];
    }
    const double t = num / den;
    if (!std::isfinite(t)) return false;
    out = Vec3(static_cast<float>(od[0] + t * dd[0]), static_cast<float>(od[1] + t * dd[1]),
               static_cast<float>(od[2] + t * dd[2]));
    return is_finite(out);
}

}  // namespace

SurfacePoint surface_at(const TriangleMesh& mesh, const Instance& inst, const Hit& h, Vec3 o,
                        Vec3 d) {
    const uint32_t i0 = mesh.indices[3 * h.prim], i1 = mesh.indices[3 * h.prim + 1],
                   i2 = mesh.indices[3 * h.prim + 2];
    const float b0 = 1.0f - h.b1 - h.b2;
    const Vec3 o0 = mesh.position(i0), o1 = mesh.position(i1), o2 = mesh.position(i2);
    const Vec3 p0 = inst.to_world.apply_point(o0);
    const Vec3 p1 = inst.to_world.apply_point(o1);
    const Vec3 p2 = inst.to_world.apply_point(o2);
    SurfacePoint sp;
    sp.p = p0 * b0 + p1 * h.b1 + p2 * h.b2;
    if (!mesh.colors.empty())
        sp.color = mesh.color(i0) * b0 + mesh.color(i1) * h.b1 + mesh.color(i2) * h.b2;
    // A triangle whose corners lie far beyond the hit (a ground plane scaled to 1e7): the
    // barycentric sum is as precise as the corners, a unit or more at 1e7, so the floor's
    // points jumped on a grid of that size (shadows became rectangles, then bands). The ray's
    // own point on the triangle's plane, in double, is as precise as the ray: taken where the
    // corners are a thousand times farther out than the ray reaches (a 20 m floor seen from
    // 5 m keeps its sum, within 1e-5 m).
    const float corners = std::max({max_abs(p0), max_abs(p1), max_abs(p2)});
    if (h.t > 0.0f && corners > 1024.0f * (max_abs(o) + h.t)) {
        Vec3 q;
        if (on_plane(o, d, p0, p1, p2, q)) sp.p = q;
    }
    // The same point in object space, for patterns fixed to the object: on a deforming mesh,
    // the point of its rest pose with the same barycentrics.
    // The object-space triangle's normal serves the plane's rounding bound below as well, and
    // is the object-space normal unless a rest pose stands in for the corners here.
    const Vec3 n_obj = cross(o1 - o0, o2 - o0);
    const float n_obj_len = length(n_obj);
    if (mesh.rest_positions.empty()) {
        sp.p_obj = o0 * b0 + o1 * h.b1 + o2 * h.b2;
        sp.ng_obj =
            n_obj_len > 0.0f && std::isfinite(n_obj_len) ? n_obj / n_obj_len : Vec3(0, 0, 1);
    } else {
        const Vec3 q0 = mesh.rest_position(i0), q1 = mesh.rest_position(i1),
                   q2 = mesh.rest_position(i2);
        sp.p_obj = q0 * b0 + q1 * h.b1 + q2 * h.b2;
        const Vec3 nq = cross(q1 - q0, q2 - q0);
        const float len = length(nq);
        sp.ng_obj = len > 0.0f && std::isfinite(len) ? nq / len : Vec3(0, 0, 1);
    }
    const Vec3 e1 = p1 - p0, e2 = p2 - p0;
    Vec3 ng = cross(e1, e2);
    const float ng_len = length(ng);
    ng = ng_len > 0.0f ? ng / ng_len : Vec3(0, 0, 1);
    // Embree finds the triangle in object space (an instance's ray is carried there), and its
    // distance to the plane is a dot product of the corners' coordinates (relative to the ray's
    // origin) with the normal: its rounding is that of each coordinate times the normal's
    // component along it. None for a floor at y = 0, or for a unit plane scaled to 1e7 by its
    // placement; a plane tilted 30 degrees with corners at 1e7 in its file found itself again
    // from 256 ulps of a small hit's coordinates, in streaks over the whole floor. Carried to
    // world space along the normal (the plane's covector goes through normal_to_world).
    if (n_obj_len > 0.0f && std::isfinite(n_obj_len)) {
        const Vec3 u = n_obj / n_obj_len;
        const auto axis = [&](float Vec3::*c) {
            return std::max({std::fabs(o0.*c), std::fabs(o1.*c), std::fabs(o2.*c)}) *
                   std::fabs(u.*c);
        };
        const float stretch = length(inst.normal_to_world.apply_vector(u));
        const float error = kPlaneRounding * std::numeric_limits<float>::epsilon() *
                            (axis(&Vec3::x) + axis(&Vec3::y) + axis(&Vec3::z)) / stretch;
        // Only where offset_origin's ulps of the hit's own coordinates fall short (about
        // 1.5e-5 of them; 1/65536 near the origin): elsewhere nothing changes.
        if (std::isfinite(error) && error > 1.5e-5f * std::max(max_abs(sp.p), 1.0f / 32.0f))
            sp.p_error = error;
    }
    Vec3 n = ng;
    Vec3 n0, n1, n2;
    const bool smooth = !mesh.normals.empty();
    if (smooth) {
        const auto nrm = [&](uint32_t i) {
            return inst.normal_to_world.apply_vector(
                Vec3(mesh.normals[3 * i], mesh.normals[3 * i + 1], mesh.normals[3 * i + 2]));
        };
        n0 = nrm(i0);
        n1 = nrm(i1);
        n2 = nrm(i2);
        const Vec3 ni = n0 * b0 + n1 * h.b1 + n2 * h.b2;
        const float len = length(ni);
        if (len > 0.0f && std::isfinite(len)) n = ni / len;
        if (dot(n, ng) < 0.0f) ng = -ng;  // the geometric normal follows the authored normals
        // The lift onto the smooth surface: p raised to each corner's tangent plane where it
        // lies below it, the three raised points blended by the barycentrics.
        // With n not of unit length: (p - c).n n / |n|^2, one division and no root.
        const Vec3 corner[3] = {p0, p1, p2}, cn[3] = {n0, n1, n2};
        const float bary[3] = {b0, h.b1, h.b2};
        Vec3 lift(0.0f);
        for (int k = 0; k < 3; ++k) {
            const float below = dot(sp.p - corner[k], cn[k]);
            const float len2 = dot(cn[k], cn[k]);
            if (below < 0.0f && len2 > 0.0f) lift = lift - cn[k] * (below * bary[k] / len2);
        }
        if (is_finite(lift)) sp.lift = lift;
    }
    float uv0[2] = {0, 0}, uv1[2] = {1, 0}, uv2[2] = {0, 1};
    if (!mesh.uvs.empty()) {
        for (uint32_t k = 0; k < 2; ++k) {
            uv0[k] = mesh.uvs[2 * i0 + k];
            uv1[k] = mesh.uvs[2 * i1 + k];
            uv2[k] = mesh.uvs[2 * i2 + k];
        }
    }
    sp.u = uv0[0] * b0 + uv1[0] * h.b1 + uv2[0] * h.b2;
    sp.v = uv0[1] * b0 + uv1[1] * h.b1 + uv2[1] * h.b2;
    // dp/du, dp/dv (and dn/du, dn/dv) from the triangle's uv mapping (pbrt, section 3.6.2).
    const float du1 = uv1[0] - uv0[0], dv1 = uv1[1] - uv0[1];
    const float du2 = uv2[0] - uv0[0], dv2 = uv2[1] - uv0[1];
    const float det = du1 * dv2 - dv1 * du2;
    // Where the determinant overflows a float (uvs beyond about 1e19: inf, or inf - inf) it and
    // dp/du come from double: no dp/du left the point without a uv footprint for the flakes.
    const bool overflow = !std::isfinite(det);
    const double det_d = static_cast<double>(du1) * static_cast<double>(dv2) -
                         static_cast<double>(dv1) * static_cast<double>(du2);
    if (overflow ? std::fabs(det_d) > 1e-20 : std::fabs(det) > 1e-20f) {
        sp.has_uv = !mesh.uvs.empty();
        const float inv = overflow ? 0.0f : 1.0f / det;
        if (!overflow) {
            sp.dpdu = (e1 * dv2 - e2 * dv1) * inv;
            sp.dpdv = (e2 * du1 - e1 * du2) * inv;
            sp.uv_area = length(cross(sp.dpdu, sp.dpdv));
        } else {
            const double i = 1.0 / det_d;
            const auto comb = [](Vec3 a, double ka, Vec3 b, double kb) {
                return std::array<double, 3>{double(a.x) * ka - double(b.x) * kb,
                                             double(a.y) * ka - double(b.y) * kb,
                                             double(a.z) * ka - double(b.z) * kb};
            };
            const auto u = comb(e1, double(dv2) * i, e2, double(dv1) * i);
            const auto v = comb(e2, double(du1) * i, e1, double(du2) * i);
            sp.dpdu = Vec3(float(u[0]), float(u[1]), float(u[2]));
            sp.dpdv = Vec3(float(v[0]), float(v[1]), float(v[2]));
            const double cx = u[1] * v[2] - u[2] * v[1], cy = u[2] * v[0] - u[0] * v[2],
                         cz = u[0] * v[1] - u[1] * v[0];
            sp.uv_area = static_cast<float>(std::sqrt(cx * cx + cy * cy + cz * cz));
        }
        if (smooth) {
            const Vec3 dn1 = n1 - n0, dn2 = n2 - n0;
            sp.dndu = (dn1 * dv2 - dn2 * dv1) * inv;
            sp.dndv = (dn2 * du1 - dn1 * du2) * inv;
        }
    }
    const bool back = dot(ng, d) > 0.0f;
    if (back) {
        ng = -ng;
        n = -n;
        sp.dndu = -sp.dndu;
        sp.dndv = -sp.dndv;
    }
    shading_frame(n, sp.dpdu, sp.s, sp.t);
    sp.ng = ng;
    sp.n = n;
    sp.n_smooth = n;
    sp.backface = back;
    return sp;
}

namespace {

/** Least-squares solutions of dp = dpdu du + dpdv dv (pbrt-v4's approach: the normal equations
 *  of the 3x2 system, stable for any orientation), for the two footprint axes at once: they
 *  share the system's matrix. */
bool solve_uv(const SurfacePoint& sp, Vec3 dpx, Vec3 dpy, float& dux, float& dvx, float& duy,
              float& dvy) {
    double a = dot(sp.dpdu, sp.dpdu), b = dot(sp.dpdu, sp.dpdv), c = dot(sp.dpdv, sp.dpdv);
    double det = a * c - b * b;
    double rux = dot(sp.dpdu, dpx), rvx = dot(sp.dpdv, dpx);
    double ruy = dot(sp.dpdu, dpy), rvy = dot(sp.dpdv, dpy);
    if (!(a * c >= 1e-30)) {
        // Tiny dp/du (uvs spanning 1e8 over a metre make |dp/du|^2 1e-16): in double
        // throughout, and degenerate only against the edges' own size. The fixed floor of 1e-30
        // on the determinant (and products underflowing in float further out) gave those
        // triangles no uv footprint: uv-space flakes found none there, their glitter gone.
        const auto ddot = [](Vec3 x, Vec3 y) {
            return static_cast<double>(x.x) * static_cast<double>(y.x) +
                   static_cast<double>(x.y) * static_cast<double>(y.y) +
                   static_cast<double>(x.z) * static_cast<double>(y.z);
        };
        a = ddot(sp.dpdu, sp.dpdu);
        b = ddot(sp.dpdu, sp.dpdv);
        c = ddot(sp.dpdv, sp.dpdv);
        det = a * c - b * b;
        if (!(a * c > 0.0) || !(det > 1e-12 * a * c)) return false;
        rux = ddot(sp.dpdu, dpx);
        rvx = ddot(sp.dpdv, dpx);
        ruy = ddot(sp.dpdu, dpy);
        rvy = ddot(sp.dpdv, dpy);
    } else if (!(std::fabs(det) > 1e-30)) {
        return false;
    }
    dux = static_cast<float>((c * rux - b * rvx) / det);
    dvx = static_cast<float>((a * rvx - b * rux) / det);
    duy = static_cast<float>((c * ruy - b * rvy) / det);
    dvy = static_cast<float>((a * rvy - b * ruy) / det);
    return std::isfinite(dux) && std::isfinite(dvx) && std::isfinite(duy) && std::isfinite(dvy);
}

/** Carries sp's object-space footprint axes from the deformed triangle `prim` to its rest
 *  pose: the affine map of the triangle that takes the deformed edges e1, e2 to the rest edges
 *  r1, r2. An axis v = a e1 + b e2 (least squares: the axes lie in the triangle's plane up to
 *  rounding) becomes a r1 + b r2. A degenerate deformed triangle leaves the axes as they are. */
void rest_footprint(SurfacePoint& sp, const TriangleMesh& mesh, uint32_t prim) {
    const uint32_t* i = &mesh.indices[3 * static_cast<std::size_t>(prim)];
    const Vec3 q0 = mesh.position(i[0]);
    const Vec3 e1 = mesh.position(i[1]) - q0, e2 = mesh.position(i[2]) - q0;
    const Vec3 r0 = mesh.rest_position(i[0]);
    const Vec3 r1 = mesh.rest_position(i[1]) - r0, r2 = mesh.rest_position(i[2]) - r0;
    const double a = dot(e1, e1), b = dot(e1, e2), c = dot(e2, e2);
    const double det = a * c - b * b;
    if (!(det > 1e-30 * a * c)) return;
    const auto to_rest = [&](Vec3 v) {
        const double p = dot(e1, v), q = dot(e2, v);
        const auto x = static_cast<float>((c * p - b * q) / det);
        const auto y = static_cast<float>((a * q - b * p) / det);
        return r1 * x + r2 * y;
    };
    sp.dpdx_obj = to_rest(sp.dpdx_obj);
    sp.dpdy_obj = to_rest(sp.dpdy_obj);
}

}  // namespace

void footprint_at(SurfacePoint& sp, const RayDifferential& ray, bool& has_diff, float widened) {
    if (has_diff) {
        // Where do the neighbours' rays meet the tangent plane at p?
        const float plane = dot(sp.ng, sp.p);
        const float tx = (plane - dot(sp.ng, ray.dx_o)) / dot(sp.ng, ray.dx_d);
        const float ty = (plane - dot(sp.ng, ray.dy_o)) / dot(sp.ng, ray.dy_d);
        if (std::isfinite(tx) && std::isfinite(ty)) {
            sp.dpdx = ray.dx_o + ray.dx_d * tx - sp.p;
            sp.dpdy = ray.dy_o + ray.dy_d * ty - sp.p;
            // Where the uvs map the triangle to no area (all (0, 0), as some exporters write
            // them) there is no uv footprint, but the surface footprint stands: object-space
            // patterns (flakes) take it. Dropping it left a footprint of the widened width
            // alone: a few flakes a pixel, and the glitter of such a mesh was gone.
            if (!solve_uv(sp, sp.dpdx, sp.dpdy, sp.dudx, sp.dvdx, sp.dudy, sp.dvdy))
                sp.dudx = sp.dvdx = sp.dudy = sp.dvdy = 0.0f;
            sp.footprint = std::max(length(sp.dpdx), length(sp.dpdy));
            return;
        }
        has_diff = false;
    }
    // A square footprint of the widened width, along the surface's parameter directions.
    sp.footprint = widened;
    sp.dpdx = sp.s * widened;
    sp.dpdy = sp.t * widened;
    const float lu = length(sp.dpdu), lv = length(sp.dpdv);
    sp.dudx = lu > 0.0f ? widened / lu : 0.0f;
    sp.dvdy = lv > 0.0f ? widened / lv : 0.0f;
    sp.dudy = sp.dvdx = 0.0f;
}

void object_footprint(SurfacePoint& sp, const Instance& inst, const TriangleMesh& mesh,
                      uint32_t prim) {
    sp.dpdx_obj = inst.to_object.apply_vector(sp.dpdx);
    sp.dpdy_obj = inst.to_object.apply_vector(sp.dpdy);
    if (!mesh.rest_positions.empty()) rest_footprint(sp, mesh, prim);
}

}  // namespace spangle
