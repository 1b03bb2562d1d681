#pragma once
// Keyframed values: a track of keys (time in seconds, a few numbers each) evaluated at any time,
// linearly or smoothly (a cubic Hermite spline through every key, C1, with Steffen's tangents:
// monotone between keys, so no overshoot). Before the first key and after the last, a track
// holds its end values.

#include <cstddef>
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

}  // namespace spangle
