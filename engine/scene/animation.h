#pragma once
// Keyframed values: a track of keys (time in seconds, a few numbers each) evaluated at any time,
// linearly or smoothly (a cubic Hermite spline through every key, C1, with Steffen's tangents:
// monotone between keys, so no overshoot). Before the first key and after the last, a track
// holds its end values.

#include <algorithm>
#include <cstddef>
#include <functional>
#include <vector>

namespace spangle {

/** Keys of equal length, in strictly increasing time. */
struct Track {
    std::vector<double> times;
    std::vector<std::vector<double>> values;
    bool smooth = true;
    bool empty() const { return times.empty(); }
};

/** The track's values at time t. */
std::vector<double> evaluate(const Track& track, double t);

/** Most segments a motion within one shutter is cut into (Embree takes up to 129 time steps). */
constexpr int kMaxMotionSegments = 64;

/** Motion blur follows a keyframed motion through the shutter [t0, t1] as straight segments
 *  between evenly spaced steps (what Embree interpolates). This is the fewest segments, a power
 *  of two up to kMaxMotionSegments, for which `straight(a, b)` holds on every segment [a, b]:
 *  whether the motion stays close enough to the straight line from its value at a to its
 *  value at b. */
int motion_segments(double t0, double t1, const std::function<bool(double, double)>& straight);

/** The steps motion blur needs of a motion `at(t)` over the shutter [t0, t1]: its values at the
 *  evenly spaced times of motion_segments, where a segment [a, b] is straight enough when
 *  `close(va, vb, vm, q)` holds for q = 1/4, 1/2, 3/4, 2 - phi and 1 / sqrt(2) -- whether vm,
 *  the value at a + (b - a) q, lies near enough to the straight line from va = at(a) to
 *  vb = at(b). Empty when every step is `same` as the first (nothing moves). */
template <class At, class Close, class Same>
auto motion_steps(double t0, double t1, const At& at, const Close& close, const Same& same) {
    using Value = decltype(at(t0));
    const auto straight = [&](double a, double b) {
        const Value va = at(a), vb = at(b);
        // Quarters, and two irrational fractions: a spin of a whole number of turns per
        // quarter of the shutter looked the same at every quarter, hence still (a wheel at
        // 1440 degrees a frame rendered sharp).
        for (const double q : {0.25, 0.5, 0.75, 0.3819660112501051, 0.7071067811865476})
            if (!close(va, vb, at(a + (b - a) * q), static_cast<float>(q))) return false;
        return true;
    };
    const int segments = motion_segments(t0, t1, straight);
    std::vector<Value> steps;
    for (int k = 0; k <= segments; ++k) steps.push_back(at(t0 + (t1 - t0) * k / segments));
    if (std::all_of(steps.begin(), steps.end(),
                    [&](const Value& v) { return same(v, steps.front()); }))
        steps.clear();
    return steps;
}

}  // namespace spangle
