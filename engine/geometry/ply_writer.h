#pragma once
// Writing a triangle mesh as a binary little-endian PLY file, the way the PLY reader reads it
// back exactly: float32 positions (and normals and uvs when the mesh has them), faces as uchar
// counts of uint32 indices.

#include <string>

#include "geometry/cage.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** Writes `mesh` to `path` (whole, or not at all: through a temporary file renamed into place).
 *  `comment` goes into the header. Throws SpangleError when the file cannot be written. */
void write_ply(const TriangleMesh& mesh, const std::string& path, const std::string& comment);

/** Writes `cage` as an OBJ file load_cage() reads back exactly: `v` lines with each float's
 *  exact decimal value (17 digits: OBJ readers parse in double, and a value that close to the
 *  float cannot round to its neighbour), `vt` lines, and `f v/vt` faces as they were (not
 *  triangulated). Whole or not at all. Throws SpangleError when it cannot be written. */
void write_obj_cage(const Cage& cage, const std::string& path, const std::string& comment);

}  // namespace spangle
