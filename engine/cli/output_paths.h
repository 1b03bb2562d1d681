#pragma once
// Output paths before and after a render: whether an image can be written there (checked before
// any work), whether two paths are one file, and the path of a numbered frame. `spangle merge`
// checks its output with these too.

#include <cstdint>
#include <string>

namespace spangle {

/** Checks, before any work, that an image can be written at `path`: its folder exists and is
 *  writable, the path is not a folder, its names are not too long. `what` names the image in
 *  the message ("EXR"). Throws SpangleError. */
void check_writable(const std::string& path, const char* what);

/** Whether two output paths name the same file (existing or not). */
bool same_file(const std::string& a, const std::string& b);

/** Whether `path` ends in `ext` (given in lower case), in any case: out.EXR is an EXR. */
bool has_extension(const std::string& path, const std::string& ext);

/** The output path of frame f: a run of '#' in `pattern` becomes f zero-padded to the run's
 *  length; without one, ".####" goes before the extension. */
std::string frame_path(const std::string& pattern, int64_t f);

/** Before a command that writes one EXR and nothing else (merge, denoise) does its work: `path`
 *  ends in .exr (else a usage error) and can be written, and the temporary images a killed
 *  process left beside it are removed (said on stderr, as a render does). */
void prepare_exr_output(const std::string& path);

}  // namespace spangle
