#pragma once
// Small vector and affine-transform types for geometry in float. Sums that can cancel are done in
// double where they are used, not here.

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace spangle {

/** How far from the origin the ray tracer (Embree) keeps geometry: beyond (its FLT_LARGE), in
 *  object space as in the world, it leaves primitives out of its structures without a word. */
constexpr float kEmbreeReach = 1.8e18f;

/** Three floats: a point, a direction or an RGB colour, by context. */
struct Vec3 {
    float x = 0.0f, y = 0.0f, z = 0.0f;

    constexpr Vec3() = default;
    constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    constexpr explicit Vec3(float s) : x(s), y(s), z(s) {}

    constexpr float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    constexpr Vec3 operator+(Vec3 o) const { return {x + o.x, y + o.y, z + o.z}; }
    constexpr Vec3 operator-(Vec3 o) const { return {x - o.x, y - o.y, z - o.z}; }
    constexpr Vec3 operator*(Vec3 o) const { return {x * o.x, y * o.y, z * o.z}; }
    constexpr Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
    constexpr Vec3 operator/(float s) const { return {x / s, y / s, z / s}; }
    constexpr Vec3 operator-() const { return {-x, -y, -z}; }
    constexpr Vec3& operator+=(Vec3 o) {
        x += o.x;
        y += o.y;
        z += o.z;
        return *this;
    }
    constexpr Vec3& operator*=(Vec3 o) {
        x *= o.x;
        y *= o.y;
        z *= o.z;
        return *this;
    }
    constexpr Vec3& operator*=(float s) {
        x *= s;
        y *= s;
        z *= s;
        return *this;
    }
    constexpr bool operator==(const Vec3&) const = default;
};

constexpr Vec3 operator*(float s, Vec3 v) {
    return v * s;
}
constexpr float dot(Vec3 a, Vec3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
constexpr Vec3 cross(Vec3 a, Vec3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(Vec3 v) {
    return std::sqrt(dot(v, v));
}
inline Vec3 normalize(Vec3 v) {
    return v / length(v);
}
inline bool is_finite(Vec3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
constexpr float max_component(Vec3 v) {
    return std::max(v.x, std::max(v.y, v.z));
}
/** Luminance weights of linear Rec.709 RGB (the Y row of its RGB to XYZ matrix), in float and
 *  in double (each the nearest to the decimal weights). */
inline constexpr float kRec709Y[3] = {0.2126f, 0.7152f, 0.0722f};
inline constexpr double kRec709YDouble[3] = {0.2126, 0.7152, 0.0722};
/** Rec.709 luminance; used only for heuristics (roulette, light power). */
constexpr float luminance(Vec3 c) {
    return kRec709Y[0] * c.x + kRec709Y[1] * c.y + kRec709Y[2] * c.z;
}

/** sRGB's transfer function decoded (IEC 61966-2-1): an encoded value in [0, 1] (8-bit images,
 *  scanners' vertex colours) to its linear value. */
inline double srgb_to_linear(double x) {
    return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4);
}
/** sRGB's transfer function: a linear value in [0, 1] to its encoded value. */
inline double linear_to_srgb(double x) {
    return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
}

/** Orthonormal basis around unit n (Duff et al. 2017, "Building an Orthonormal Basis,
 *  Revisited"), used when a surface has no usable dpdu. */
inline void make_basis(Vec3 n, Vec3& s, Vec3& t) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    s = {1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x};
    t = {b, sign + n.y * n.y * a, -n.y};
}

/** An affine transform: 3x3 linear part m (row-major) and translation t. */
struct Affine {
    float m[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    Vec3 t;
    constexpr bool operator==(const Affine&) const = default;

    constexpr Vec3 apply_point(Vec3 p) const { return apply_vector(p) + t; }
    constexpr Vec3 apply_vector(Vec3 v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    /** this * o: apply o first. */
    Affine compose(const Affine& o) const;
    /** The inverse; the caller guarantees the linear part is invertible. */
    Affine inverse() const;
    /** Determinant of the linear part, computed in double (0 only for a part singular as
     *  written, or within double rounding of it). */
    double determinant_in_double() const;
    /** Determinant of the linear part (determinant_in_double, as a float). */
    float determinant() const;
    /** |determinant| of the linear part over the sum of the sizes of the six products it is the
     *  difference of (the permanent of its entries' sizes), in double: 1 for a scale, rotation
     *  or shear however strong; near 0 where the determinant cancels to nothing in float
     *  (axes nearly parallel). 1 for a linear part of zeros. */
    double determinant_share() const;
    /** The inverse transpose of the linear part, no translation: transforms normals with
     *  apply_vector. Compute it once per transform, not per normal. */
    Affine normal_matrix() const;
    /** Applies the inverse transpose of the linear part (for normals); one-off use. */
    Vec3 apply_normal(Vec3 n) const { return normal_matrix().apply_vector(n); }

    static Affine translate(Vec3 d);
    static Affine scale(Vec3 s);
    /** Rotation by `degrees` about unit `axis`, right-handed. */
    static Affine rotate(float degrees, Vec3 axis);
};

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;

}  // namespace spangle
