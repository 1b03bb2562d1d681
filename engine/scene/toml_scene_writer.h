#pragma once
// Writing a scene description as a TOML scene file (`spangle convert`): a scene read from any
// format becomes one a user can edit. Every setting is written out, numbers with as many digits
// as they need to be read back exactly, colours with their colour spaces, placements as matrices
// where they are not scale/rotate/translate, and the meshes a scene file held itself as binary
// PLY files beside the TOML. Reading the file back gives a scene that renders the same image,
// bit for bit.

#include <string>
#include <vector>

#include "scene/scene_description.h"

namespace spangle {

/** `s` as a TOML basic string: quoted, with quotes, backslashes and control characters
 *  escaped. */
std::string toml_basic_string(const std::string& s);

/** What writing a scene made. */
struct SceneWriteReport {
    std::vector<std::string> meshes;  ///< PLY files written for inline meshes
};

/** Writes `scene` (imports resolved) to `path`, a .toml file, whole or not at all; its inline
 *  meshes go into the folder `mesh_dir` (created when needed) as mesh_NNN.ply. Files in path's
 *  folder or below are written relative to it, others as absolute paths. Throws SpangleError when a
 * file cannot be written or the scene holds what TOML cannot say. */
SceneWriteReport write_toml_scene(const SceneDescription& scene, const std::string& path,
                                  const std::string& mesh_dir);

}  // namespace spangle
