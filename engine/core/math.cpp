#include "core/math.h"

namespace spangle {

Affine Affine::compose(const Affine& o) const {
    Affine r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            r.m[i][j] = m[i][0] * o.m[0][j] + m[i][1] * o.m[1][j] + m[i][2] * o.m[2][j];
    r.t = apply_point(o.t);
    return r;
}

double Affine::determinant_in_double() const {
    // Double: the cofactor sums cancel for thin transforms.
    const double a = m[0][0], b = m[0][1], c = m[0][2], d = m[1][0], e = m[1][1], f = m[1][2],
                 g = m[2][0], h = m[2][1], k = m[2][2];
    return a * (e * k - f * h) - b * (d * k - f * g) + c * (d * h - e * g);
}

float Affine::determinant() const {
    return static_cast<float>(determinant_in_double());
}

double Affine::determinant_share() const {
    constexpr int kPerm[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {1, 0, 2}, {2, 1, 0}};
    double det = 0.0, products = 0.0;
    for (int k = 0; k < 6; ++k) {
        const double term = static_cast<double>(m[0][kPerm[k][0]]) *
                            static_cast<double>(m[1][kPerm[k][1]]) *
                            static_cast<double>(m[2][kPerm[k][2]]);
        det += k < 3 ? term : -term;
        products += std::fabs(term);
    }
    return products > 0.0 ? std::fabs(det) / products : 1.0;
}

Affine Affine::inverse() const {
    double a[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a[i][j] = m[i][j];
    const double inv = 1.0 / determinant_in_double();
    Affine r;
    r.m[0][0] = static_cast<float>((a[1][1] * a[2][2] - a[1][2] * a[2][1]) * inv);
    r.m[0][1] = static_cast<float>((a[0][2] * a[2][1] - a[0][1] * a[2][2]) * inv);
    r.m[0][2] = static_cast<float>((a[0][1] * a[1][2] - a[0][2] * a[1][1]) * inv);
    r.m[1][0] = static_cast<float>((a[1][2] * a[2][0] - a[1][0] * a[2][2]) * inv);
    r.m[1][1] = static_cast<float>((a[0][0] * a[2][2] - a[0][2] * a[2][0]) * inv);
    r.m[1][2] = static_cast<float>((a[0][2] * a[1][0] - a[0][0] * a[1][2]) * inv);
    r.m[2][0] = static_cast<float>((a[1][0] * a[2][1] - a[1][1] * a[2][0]) * inv);
    r.m[2][1] = static_cast<float>((a[0][1] * a[2][0] - a[0][0] * a[2][1]) * inv);
    r.m[2][2] = static_cast<float>((a[0][0] * a[1][1] - a[0][1] * a[1][0]) * inv);
    r.t = -r.apply_vector(t);
    return r;
}

Affine Affine::normal_matrix() const {
    const Affine inv = inverse();
    Affine r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r.m[i][j] = inv.m[j][i];
    return r;
}

Affine Affine::translate(Vec3 d) {
    Affine r;
    r.t = d;
    return r;
}

Affine Affine::scale(Vec3 s) {
    Affine r;
    r.m[0][0] = s.x;
    r.m[1][1] = s.y;
    r.m[2][2] = s.z;
    return r;
}

Affine Affine::rotate(float degrees, Vec3 axis) {
    const Vec3 a = normalize(axis);
    const float th = degrees * kPi / 180.0f;
    const float c = std::cos(th), s = std::sin(th), ic = 1.0f - c;
    Affine r;
    r.m[0][0] = c + a.x * a.x * ic;
    r.m[0][1] = a.x * a.y * ic - a.z * s;
    r.m[0][2] = a.x * a.z * ic + a.y * s;
    r.m[1][0] = a.y * a.x * ic + a.z * s;
    r.m[1][1] = c + a.y * a.y * ic;
    r.m[1][2] = a.y * a.z * ic - a.x * s;
    r.m[2][0] = a.z * a.x * ic - a.y * s;
    r.m[2][1] = a.z * a.y * ic + a.x * s;
    r.m[2][2] = c + a.z * a.z * ic;
    return r;
}

}  // namespace spangle
