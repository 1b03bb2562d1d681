#include "scene/animation.h"

#include <algorithm>
#include <cmath>

namespace spangle {

std::vector<double> evaluate(const Track& track, double t) {
    const std::size_t n = track.times.size();
    if (n == 0) return {};
    if (n == 1 || t <= track.times.front()) return track.values.front();
    if (t >= track.times.back()) return track.values.back();
    // The segment [i, i + 1] that holds t.
    const std::size_t i = static_cast<std::size_t>(
        std::upper_bound(track.times.begin(), track.times.end(), t) - track.times.begin() - 1);
    const double t0 = track.times[i], t1 = track.times[i + 1], h = t1 - t0;
    const double s = (t - t0) / h;
    const std::vector<double>& p0 = track.values[i];
    const std::vector<double>& p1 = track.values[i + 1];
    std::vector<double> out(p0.size());
    if (!track.smooth) {
        for (std::size_t c = 0; c < out.size(); ++c) out[c] = p0[c] + (p1[c] - p0[c]) * s;
        return out;
    }
    // Tangents (per second) after Steffen (1990): from the secant slopes on either side, never
    // steeper than twice the smaller one and zero where the keys turn, so the curve does not
    // overshoot between keys (a camera that should stop does not swing past); one-sided at the
    // ends.
    const auto slope = [&](std::size_t k, std::size_t c) {
        return (track.values[k + 1][c] - track.values[k][c]) /
               (track.times[k + 1] - track.times[k]);
    };
    const auto tangent = [&](std::size_t k, std::size_t c) {
        if (k == 0) return slope(0, c);
        if (k + 1 == n) return slope(n - 2, c);
        const double d0 = slope(k - 1, c), d1 = slope(k, c);
        const double h0 = track.times[k] - track.times[k - 1],
                     h1 = track.times[k + 1] - track.times[k];
        const double p = (d0 * h1 + d1 * h0) / (h0 + h1);
        const double sign = (d0 > 0   ? 1.0
                             : d0 < 0 ? -1.0
                                      : 0.0) +
                            (d1 > 0   ? 1.0
                             : d1 < 0 ? -1.0
                                      : 0.0);
        return sign * std::min({std::fabs(d0), std::fabs(d1), 0.5 * std::fabs(p)});
    };
    const double s2 = s * s, s3 = s2 * s;
    const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2,
                 h11 = s3 - s2;
    for (std::size_t c = 0; c < out.size(); ++c)
        out[c] = h00 * p0[c] + h10 * h * tangent(i, c) + h01 * p1[c] + h11 * h * tangent(i + 1, c);
    return out;
}

int motion_segments(double t0, double t1, const std::function<bool(double, double)>& straight) {
    for (int k = 1; k < kMaxMotionSegments; k *= 2) {
        bool ok = true;
        for (int i = 0; i < k && ok; ++i)
            ok = straight(t0 + (t1 - t0) * i / k, t0 + (t1 - t0) * (i + 1) / k);
        if (ok) return k;
    }
    return kMaxMotionSegments;
}

}  // namespace spangle
