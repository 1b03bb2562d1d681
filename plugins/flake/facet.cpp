#include "facet.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "field.h"

namespace spangle::flake {

FacetShape::FacetShape(FacetKind kind) {
    // Regular polygons: the hexagon is 1 wide flat to flat (circumradius 1 / sqrt 3), the square
    // 1 wide side to side, the disc a 32-gon of diameter 1 through its corners.
    const int sides = kind == FacetKind::Hexagon ? 6 : kind == FacetKind::Square ? 4 : 32;
    radius = kind == FacetKind::Hexagon  ? 1.0 / std::sqrt(3.0)
             : kind == FacetKind::Square ? std::sqrt(0.5)
                                         : 0.5;
    const double start = kind == FacetKind::Square ? 0.25 * std::numbers::pi : 0.0;
    n = sides;
    for (int i = 0; i < n; ++i) {
        const double a = start + 2.0 * std::numbers::pi * i / n;
        x[i] = radius * std::cos(a);
        y[i] = radius * std::sin(a);
    }
    area = 0.5 * n * radius * radius * std::sin(2.0 * std::numbers::pi / n);
}

namespace {

/** Twice the signed area of polygon (xs, ys) of m vertices (shoelace). */
double twice_area(const double* xs, const double* ys, int m) {
    double a = 0.0;
    for (int i = 0; i < m; ++i) {
        const int j = i + 1 == m ? 0 : i + 1;
        a += xs[i] * ys[j] - xs[j] * ys[i];
    }
    return a;
}

}  // namespace

float facet_coverage(const Footprint& p, const FacetShape& shape, double size, double u, double v,
                     uint64_t id) {
    if (p.i00 == 0.0 && p.i01 == 0.0 && p.i10 == 0.0 && p.i11 == 0.0) return 0.0f;
    // The facet's corners in P's own coordinates (s, t), where P is the square [-1/2, 1/2]^2;
    // the ratio of areas is the same in both coordinates (the map is affine).
    const double angle = static_cast<double>(mix(id, 0xface7) >> 11) * 0x1p-53 * 6.283185307179586;
    const double ca = std::cos(angle) * size, sa = std::sin(angle) * size;
    static_assert(FacetShape::kMaxVertices <= kMaxClipVertices);
    double xs[FacetShape::kMaxVertices], ys[FacetShape::kMaxVertices];
    bool all_in = true;
    double lo_s = 1e300, hi_s = -1e300, lo_t = 1e300, hi_t = -1e300;
    for (int i = 0; i < shape.n; ++i) {
        const double du = u - p.cu + ca * shape.x[i] - sa * shape.y[i];
        const double dv = v - p.cv + sa * shape.x[i] + ca * shape.y[i];
        const double s = p.i00 * du + p.i01 * dv, t = p.i10 * du + p.i11 * dv;
        xs[i] = s;
        ys[i] = t;
        all_in = all_in && std::fabs(s) <= 0.5 && std::fabs(t) <= 0.5;
        lo_s = std::min(lo_s, s);
        hi_s = std::max(hi_s, s);
        lo_t = std::min(lo_t, t);
        hi_t = std::max(hi_t, t);
    }
    if (all_in) return 1.0f;
    if (hi_s <= -0.5 || lo_s >= 0.5 || hi_t <= -0.5 || lo_t >= 0.5) return 0.0f;
    const double whole = 0.5 * std::fabs(twice_area(xs, ys, shape.n));
    if (!(whole > 0.0)) return 0.0f;
    const double part = clipped_area(xs, ys, shape.n, -0.5, -0.5, 0.5, 0.5);
    return static_cast<float>(std::clamp(part / whole, 0.0, 1.0));
}

}  // namespace spangle::flake
