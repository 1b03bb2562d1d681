#pragma once
// Numbered file sequences: a mesh or cage named with a run of '#' in its file name
// ("body.####.ply") is one file per frame, the run replaced by the frame number zero-padded to
// the run's width ("body.0007.ply" for frame 7). The frame a scene is evaluated at is its
// frame_start plus its time in frames, the same in every mode (one-shot, --frames, watch, MPI).

#include <cstdint>
#include <string>

#include "core/error.h"
#include "scene/scene_description.h"

namespace spangle {

/** Where the run of '#' lies in `pattern`'s file name (after its last '/'): its first character
 *  and its length; count 0 when the file name has no '#'. */
struct FrameRun {
    std::size_t first = 0;  ///< index into the pattern
    std::size_t count = 0;  ///< number of '#' (the zero-padded width)
    /** Whether the file name has more than one run of '#' (an error: which one is the frame?). */
    bool several = false;
};

/** The run of '#' in the file name of `pattern`. */
FrameRun find_frame_run(const std::string& pattern);

/** Whether `pattern`'s file name names a sequence (holds a '#'). */
inline bool is_frame_pattern(const std::string& pattern) {
    return find_frame_run(pattern).count > 0;
}

/** `pattern` with its run of '#' replaced by `frame`, zero-padded to the run's width (a frame
 *  with more digits keeps them all; a negative one has its '-' inside the width, as printf's
 *  %0*d). `pattern` itself when it has no run. */
std::string expand_frame_pattern(const std::string& pattern, int64_t frame);

/** The frame a scene is evaluated at: frame_start plus `time` (seconds after it) in frames,
 *  rounded to the nearest frame. */
int64_t frame_at(int64_t frame_start, double fps, double time);

/** The file of a sequence `pattern` (named at `at`) for `frame`, checked to exist; `what`
 *  words it for the message ("mesh", "cage"). Throws SpangleError at `at` when it is missing. */
std::string sequence_file(const std::string& pattern, int64_t frame, const FileLoc& at,
                          const char* what);

/** Checks that every mesh and cage sequence of `scene` has its file for each frame of
 *  [first, last], before any frame renders (a missing frame 5 failed after frames 1 to 4).
 *  Throws SpangleError at the sequence's file:line:col, naming the first missing frame. */
void check_sequence_files(const SceneDescription& scene, int64_t first, int64_t last);

}  // namespace spangle
