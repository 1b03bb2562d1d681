#pragma once
// The files a scene names (meshes, cages, images), found the same way by every reader: relative
// to the scene file's folder, and checked to exist when the scene is read, so that a missing file
// is an error at the place that names it.

#include <filesystem>
#include <string>
#include <string_view>

#include "core/error.h"

namespace spangle {

/** `given`, the value of `key` written at `at`, resolved against `dir` when relative and
 *  normalised. Throws SpangleError at `at` when it is empty ("'key' must not be empty") or not a
 *  regular file ("key file 'given' not found (looked for PATH)"), or cannot be read ("... cannot
 *  be read: Permission denied"). */
std::string find_scene_file(const std::string& given, const std::filesystem::path& dir,
                            std::string_view key, const FileLoc& at);

/** Throws SpangleError (no location) unless `path` is a regular file that can be read: "scene
 *  file 'path' not found", that it is a folder, a device or a pipe, or that it cannot be read. */
void check_scene_file(const std::string& path);

}  // namespace spangle
