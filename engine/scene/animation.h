#pragma once
// Keyframed values: a track of keys (time in seconds, a few numbers each) evaluated at any time,
// linearly or smoothly (a cubic Hermite spline through every key, C1, with Steffen's tangents:
// monotone between keys, so no overshoot). Before the first key and after the last, a track
// holds its end values.

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

}  // namespace spangle
