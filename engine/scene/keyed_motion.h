#pragma once
// Keyframes into motion, written once for everything that moves (the camera, objects): the keys
// become a Track, the track gives the value at the shutter's middle (where whatever does not blur
// stands) and, while the shutter is open, the steps motion blur follows (motion_steps). Each kind
// of value says once how close to straight is straight enough between steps (MotionTest).

#include <cstdint>
#include <vector>

#include "core/error.h"
#include "core/math.h"
#include "scene/animation.h"
#include "scene/components.h"
#include "scene/scene_description.h"

namespace spangle {

/** One frame's exposure, in seconds. */
struct Shutter {
    double open = 0.0;    ///< when it opens
    double middle = 0.0;  ///< where what does not blur is placed
    double close = 0.0;   ///< when it closes
    bool blurs = false;   ///< it opens before it closes: what moves is blurred
};

/** The shutter of the frame at `time` (seconds) of a scene at `fps` whose shutter is
 *  [open, close] in frames from the frame's time. */
Shutter frame_shutter(double time, double fps, double open, double close);

/** A key's time in seconds: its seconds, or (frame - frame_start) / fps. */
double key_seconds(const KeyTime& time, int64_t frame_start, double fps);

/** The keys as a track, `values(key)` giving each key's numbers. Throws SpangleError at a key
 *  that does not come after the one before it. */
template <class Key, class Values>
Track key_track(const Keys<Key>& keys, int64_t frame_start, double fps, const Values& values) {
    Track track;
    track.smooth = keys.smooth;
    for (const Key& key : keys.keys) {
        const double time = key_seconds(key.time, frame_start, fps);
        if (!track.times.empty() && !(time > track.times.back()))
            throw_error(key.loc, "{}: keys must be in increasing time ({} s follows {} s)",
                        key.what, time, track.times.back());
        track.times.push_back(time);
        track.values.push_back(values(key));
    }
    return track;
}

/** For each kind of value that moves: whether the motion through vm at fraction q between va and
 *  vb is straight enough (close), and whether two values are the same (same). */
template <class Value>
struct MotionTest;

/** The camera: the eye and the point looked at stray from the straight line by under 1% of the
 *  distance they move; up and the field of view by under 1e-3. */
template <>
struct MotionTest<Camera> {
    static bool close(const Camera& a, const Camera& b, const Camera& m, float q);
    static bool same(const Camera& a, const Camera& b) { return Camera::same(a, b); }
};

/** A placement: the linear part strays from the straight line by under 2.5e-4 of its size (a
 *  rotation cut into steps of about 2.5 degrees), the translation by under 1% of how far it
 *  moves. */
template <>
struct MotionTest<Affine> {
    static bool close(const Affine& a, const Affine& b, const Affine& m, float q);
    static bool same(const Affine& a, const Affine& b) { return a == b; }
};

/** A placement split as M = T R S (Shoemake and Duff's polar decomposition, as pbrt's animated
 *  transforms do): translation t, rotation q (a unit quaternion x, y, z, w) and stretch s (a
 *  symmetric matrix, negative where M mirrors). */
struct DecomposedAffine {
    double t[3] = {0, 0, 0};
    double q[4] = {0, 0, 0, 1};
    double s[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
};

/** The decomposition of m (invertible). */
DecomposedAffine decompose(const Affine& m);

/** The placement a fraction f of the way from a to b: t and s along straight lines, the
 *  rotation along the shorter arc (slerp). */
Affine interpolate(const DecomposedAffine& a, const DecomposedAffine& b, double f);

/** A keyframed value through one shutter. */
template <class Value>
struct KeyedMotion {
    Value middle;              ///< at the shutter's middle
    std::vector<Value> steps;  ///< motion steps over the shutter; empty when it does not blur
};

/** The value `at(t)` gives through `shutter` (see keyed_motion). */
template <class Value, class At>
KeyedMotion<Value> motion_through(const Shutter& shutter, const At& at) {
    KeyedMotion<Value> out{at(shutter.middle), {}};
    if (shutter.blurs)
        out.steps = motion_steps(shutter.open, shutter.close, at, MotionTest<Value>::close,
                                 MotionTest<Value>::same);
    return out;
}

/** `track` through `shutter`: `make(values, t)` turns the track's numbers at time t into a
 *  Value (and throws for numbers that make no valid one). The steps follow the motion as
 *  motion_steps cuts it, tested by MotionTest<Value>; none when the shutter does not blur or
 *  nothing moves while it is open. */
template <class Value, class Make>
KeyedMotion<Value> keyed_motion(const Track& track, const Shutter& shutter, const Make& make) {
    return motion_through<Value>(shutter,
                                 [&](double t) -> Value { return make(evaluate(track, t), t); });
}

/** Matrix keys through `shutter` (held before the first key and after the last). Throws
 *  SpangleError at a key out of time order or a key whose matrix is not invertible. */
KeyedMotion<Affine> matrix_motion(const Keys<MatrixKey>& keys, int64_t frame_start, double fps,
                                  const Shutter& shutter);

}  // namespace spangle
