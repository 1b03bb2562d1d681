#include "scene/keyed_motion.h"

#include <algorithm>
#include <cmath>

namespace spangle {

Shutter frame_shutter(double time, double fps, double open, double close) {
    Shutter s;
    s.open = time + open / fps;
    s.close = time + close / fps;
    s.middle = time + 0.5 * (open + close) / fps;
    s.blurs = open < close;
    return s;
}

double key_seconds(const KeyTime& time, int64_t frame_start, double fps) {
    return time.frame ? static_cast<double>(*time.frame - frame_start) / fps : time.seconds;
}

bool MotionTest<Camera>::close(const Camera& a, const Camera& b, const Camera& m, float q) {
    const auto off = [q](Vec3 x0, Vec3 x1, Vec3 xm) { return length(xm - (x0 + (x1 - x0) * q)); };
    const float moved = length(b.position - a.position) + length(b.look_at - a.look_at);
    return off(a.position, b.position, m.position) <= 0.01f * moved + 1e-6f &&
           off(a.look_at, b.look_at, m.look_at) <= 0.01f * moved + 1e-6f &&
           off(a.up, b.up, m.up) <= 1e-3f * length(m.up) &&
           std::fabs(m.fov_deg - (a.fov_deg + (b.fov_deg - a.fov_deg) * q)) <= 1e-3f * m.fov_deg;
}

bool MotionTest<Affine>::close(const Affine& a, const Affine& b, const Affine& m, float q) {
    float size = 0.0f;
    for (int row = 0; row < 3; ++row)
        for (int j = 0; j < 3; ++j)
            size = std::max({size, std::fabs(a.m[row][j]), std::fabs(b.m[row][j])});
    for (int row = 0; row < 3; ++row)
        for (int j = 0; j < 3; ++j)
            if (std::fabs(m.m[row][j] - (a.m[row][j] + (b.m[row][j] - a.m[row][j]) * q)) >
                2.5e-4f * size)
                return false;
    return length(m.t - (a.t + (b.t - a.t) * q)) <= 0.01f * length(b.t - a.t) + 1e-6f * length(m.t);
}

}  // namespace spangle

namespace spangle {
namespace {

using Mat3 = double[3][3];

void multiply(const Mat3& a, const Mat3& b, Mat3& out) {
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            out[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
}

double determinant(const Mat3& m) {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/** The inverse of the transpose of m (det(m) != 0). */
void inverse_transpose(const Mat3& m, Mat3& out) {
    const double inv = 1.0 / determinant(m);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            // Cofactor (i, j) of m: the (i, j) entry of the inverse transpose.
            const int r0 = (i + 1) % 3, r1 = (i + 2) % 3, c0 = (j + 1) % 3, c1 = (j + 2) % 3;
            out[i][j] = (m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]) * inv;
        }
}

/** The unit quaternion of rotation matrix r (Shepperd's method: the largest of the four
 *  candidates, for accuracy). */
void quaternion_of(const Mat3& r, double q[4]) {
    const double tr = r[0][0] + r[1][1] + r[2][2];
    if (tr > 0.0) {
        const double s = 2.0 * std::sqrt(tr + 1.0);
        q[3] = 0.25 * s;
        q[0] = (r[2][1] - r[1][2]) / s;
        q[1] = (r[0][2] - r[2][0]) / s;
        q[2] = (r[1][0] - r[0][1]) / s;
        return;
    }
    int i = 0;
    if (r[1][1] > r[0][0]) i = 1;
    if (r[2][2] > r[i][i]) i = 2;
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    const double s = 2.0 * std::sqrt(1.0 + r[i][i] - r[j][j] - r[k][k]);
    q[i] = 0.25 * s;
    q[j] = (r[j][i] + r[i][j]) / s;
    q[k] = (r[k][i] + r[i][k]) / s;
    q[3] = (r[k][j] - r[j][k]) / s;
}

/** The rotation matrix of unit quaternion q. */
void rotation_of(const double q[4], Mat3& r) {
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    r[0][0] = 1 - 2 * (y * y + z * z);
    r[0][1] = 2 * (x * y - z * w);
    r[0][2] = 2 * (x * z + y * w);
    r[1][0] = 2 * (x * y + z * w);
    r[1][1] = 1 - 2 * (x * x + z * z);
    r[1][2] = 2 * (y * z - x * w);
    r[2][0] = 2 * (x * z - y * w);
    r[2][1] = 2 * (y * z + x * w);
    r[2][2] = 1 - 2 * (x * x + y * y);
}

}  // namespace

DecomposedAffine decompose(const Affine& m) {
    DecomposedAffine d;
    d.t[0] = m.t.x;
    d.t[1] = m.t.y;
    d.t[2] = m.t.z;
    Mat3 linear, r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) linear[i][j] = r[i][j] = m.m[i][j];
    // The polar decomposition by Newton's iteration R <- (R + R^-T) / 2 (Higham 1986), which
    // converges quadratically to the orthogonal factor.
    for (int it = 0; it < 100; ++it) {
        Mat3 inv_t, next;
        inverse_transpose(r, inv_t);
        double change = 0.0;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                next[i][j] = 0.5 * (r[i][j] + inv_t[i][j]);
                change = std::max(change, std::fabs(next[i][j] - r[i][j]));
            }
        std::copy(&next[0][0], &next[0][0] + 9, &r[0][0]);
        if (change < 1e-12) break;
    }
    // A mirroring placement: the rotation of -M, with the mirror in the stretch (M = (-R)(-S)).
    const bool mirrors = determinant(r) < 0.0;
    if (mirrors)
        for (auto& row : r)
            for (double& x : row) x = -x;
    quaternion_of(r, d.q);
    Mat3 rt;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) rt[i][j] = r[j][i];
    multiply(rt, linear, d.s);  // S = R^T M (R^-1 = R^T)
    return d;
}

Affine interpolate(const DecomposedAffine& a, const DecomposedAffine& b, double f) {
    // The rotation: slerp the shorter way round.
    double qb[4] = {b.q[0], b.q[1], b.q[2], b.q[3]};
    double cos_theta = a.q[0] * qb[0] + a.q[1] * qb[1] + a.q[2] * qb[2] + a.q[3] * qb[3];
    if (cos_theta < 0.0) {
        for (double& x : qb) x = -x;
        cos_theta = -cos_theta;
    }
    double q[4];
    if (cos_theta > 0.9995) {  // nearly the same rotation: a straight line, normalised
        for (int i = 0; i < 4; ++i) q[i] = a.q[i] + (qb[i] - a.q[i]) * f;
    } else {
        const double theta = std::acos(std::min(1.0, cos_theta));
        const double wa = std::sin((1.0 - f) * theta) / std::sin(theta);
        const double wb = std::sin(f * theta) / std::sin(theta);
        for (int i = 0; i < 4; ++i) q[i] = a.q[i] * wa + qb[i] * wb;
    }
    const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (double& x : q) x /= len;
    Mat3 r, s, m;
    rotation_of(q, r);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) s[i][j] = a.s[i][j] + (b.s[i][j] - a.s[i][j]) * f;
    multiply(r, s, m);
    Affine out;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) out.m[i][j] = static_cast<float>(m[i][j]);
    out.t = {static_cast<float>(a.t[0] + (b.t[0] - a.t[0]) * f),
             static_cast<float>(a.t[1] + (b.t[1] - a.t[1]) * f),
             static_cast<float>(a.t[2] + (b.t[2] - a.t[2]) * f)};
    return out;
}

KeyedMotion<Affine> matrix_motion(const Keys<MatrixKey>& keys, int64_t frame_start, double fps,
                                  const Shutter& shutter) {
    std::vector<double> times;
    std::vector<DecomposedAffine> parts;
    std::vector<Affine> given;
    for (const MatrixKey& k : keys.keys) {
        const double time = key_seconds(k.time, frame_start, fps);
        if (!times.empty() && !(time > times.back()))
            throw_error(k.loc, "{}: keys must be in increasing time ({} s follows {} s)", k.what,
                        time, times.back());
        const float det = k.matrix.determinant();
        if (!(std::fabs(det) > 1e-30f) || !std::isfinite(det))
            throw_error(k.loc, "{}: its transform is not invertible (determinant {})", k.what, det);
        times.push_back(time);
        parts.push_back(decompose(k.matrix));
        given.push_back(k.matrix);
    }
    // At a key exactly, the key's own matrix (not its decomposition composed back).
    const auto at = [&](double t) -> Affine {
        if (t <= times.front()) return given.front();
        if (t >= times.back()) return given.back();
        const std::size_t i = static_cast<std::size_t>(
                                  std::upper_bound(times.begin(), times.end(), t) - times.begin()) -
                              1;
        if (t == times[i]) return given[i];
        return interpolate(parts[i], parts[i + 1], (t - times[i]) / (times[i + 1] - times[i]));
    };
    return motion_through<Affine>(shutter, at);
}

}  // namespace spangle
