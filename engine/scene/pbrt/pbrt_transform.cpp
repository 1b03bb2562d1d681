// pbrt's 4x4 transforms and the Reader's small shared helpers.

#include <cmath>

#include "scene/pbrt/pbrt_state.h"
#include "scene/scene_paths.h"

namespace spangle::pbrt {

Mat4 Mat4::scale(double x, double y, double z) {
    Mat4 m;
    m.m[0][0] = x;
    m.m[1][1] = y;
    m.m[2][2] = z;
    return m;
}

Mat4 Mat4::operator*(const Mat4& o) const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = 0.0;
            for (int k = 0; k < 4; ++k) s += m[i][k] * o.m[k][j];
            r.m[i][j] = s;
        }
    return r;
}

std::optional<Mat4> Mat4::inverse() const {
    // Gauss-Jordan elimination with partial pivoting.
    double a[4][8];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            a[i][j] = m[i][j];
            a[i][j + 4] = i == j ? 1.0 : 0.0;
        }
    for (int c = 0; c < 4; ++c) {
        int p = c;
        for (int i = c + 1; i < 4; ++i)
            if (std::fabs(a[i][c]) > std::fabs(a[p][c])) p = i;
        if (!(std::fabs(a[p][c]) > 1e-300)) return std::nullopt;
        if (p != c)
            for (int j = 0; j < 8; ++j) std::swap(a[p][j], a[c][j]);
        const double inv = 1.0 / a[c][c];
        for (int j = 0; j < 8; ++j) a[c][j] *= inv;
        for (int i = 0; i < 4; ++i) {
            if (i == c) continue;
            const double f = a[i][c];
            if (f != 0.0)
                for (int j = 0; j < 8; ++j) a[i][j] -= f * a[c][j];
        }
    }
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) r.m[i][j] = a[i][j + 4];
    for (const auto& row : r.m)
        for (double v : row)
            if (!std::isfinite(v)) return std::nullopt;
    return r;
}

double Mat4::determinant3() const {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

Vec3 Mat4::point(Vec3 p) const {
    return vector(p) + Vec3(static_cast<float>(m[0][3]), static_cast<float>(m[1][3]),
                            static_cast<float>(m[2][3]));
}

Vec3 Mat4::vector(Vec3 v) const {
    const double x = v.x, y = v.y, z = v.z;
    return {static_cast<float>(m[0][0] * x + m[0][1] * y + m[0][2] * z),
            static_cast<float>(m[1][0] * x + m[1][1] * y + m[1][2] * z),
            static_cast<float>(m[2][0] * x + m[2][1] * y + m[2][2] * z)};
}

Affine Mat4::affine() const {
    Affine a;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a.m[i][j] = static_cast<float>(m[i][j]);
    a.t = {static_cast<float>(m[0][3]), static_cast<float>(m[1][3]), static_cast<float>(m[2][3])};
    return a;
}

void Reader::sign(bool v4, const FileLoc& at, const char* what) {
    std::string& first = v4 ? info.v4_sign : info.v3_sign;
    if (!first.empty()) return;
    first = fmt::format("{}:{}: {}", at.file, at.line, what);
    if (v4)
        info.version = PbrtVersion::V4;
    else if (info.version == PbrtVersion::Unknown)
        info.version = PbrtVersion::V3;
}

ColorDesc Reader::color(Vec3 rgb, const FileLoc& at) const {
    ColorDesc c;
    c.rgb = rgb;
    c.space = gs.space;
    c.loc = at;
    c.space_loc = at;
    return c;
}

std::string Reader::find_file(const std::string& given, const char* what, const FileLoc& at) const {
    if (!given.empty() && std::filesystem::path(given).is_relative() && current_dir != dir) {
        std::error_code ec;
        if (!std::filesystem::exists(dir / given, ec) &&
            std::filesystem::exists(current_dir / given, ec))
            return find_scene_file(given, current_dir, what, at);
    }
    return find_scene_file(given, dir, what, at);
}

}  // namespace spangle::pbrt
