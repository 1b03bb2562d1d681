#pragma once
// Loading OBJ and PLY (ASCII and binary) meshes with Spangle's own readers (obj_reader.h,
// ply_reader.h), then validating them: every position finite, every index in range, at least one
// triangle.

#include <string>

#include "core/error.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** Loads and validates `path`. Errors name the file and, via `ref`, the scene line naming it. */
TriangleMesh load_mesh(const std::string& path, const FileLoc& ref);

/** Checks a mesh's numbers; throws SpangleError naming the first bad vertex or index. */
void validate_mesh(const TriangleMesh& mesh, const FileLoc& ref);

}  // namespace spangle
