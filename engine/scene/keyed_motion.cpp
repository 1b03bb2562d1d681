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
