#pragma once
// `spangle render --frames A..B`: a keyframed sequence through one session.

#include "cli/render_args.h"

namespace spangle {

/** Renders frames A..B of --frames, each to its own output (frame_path); between frames only
 *  what the keyframes moved is rebuilt (transforms: the top-level BVH; the camera: nothing).
 *  Returns the exit status; throws UsageError or SpangleError. */
int run_frames(const RenderArgs& a);

}  // namespace spangle
