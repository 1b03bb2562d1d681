#pragma once
// Spangle's own PLY reader (ASCII and binary, either byte order). Every count the header claims
// is checked against the bytes the file has before anything is allocated, and every read is
// bounded, so a malformed or truncated file is an error with a reason, never a crash, a hang or a
// huge allocation (the general-purpose importer used before had all three).

#include <cstdint>
#include <string>

#include "core/error.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** Reads the vertex positions (x, y, z), normals (nx, ny, nz), uvs (u, v or s, t), colours
 *  (red, green, blue: integer ones sRGB-encoded, floating-point ones linear) and the faces
 *  (vertex_indices, triangulated) of a PLY file. Other elements and properties are
 *  skipped. Throws SpangleError at `ref` naming the file and what is wrong. */
TriangleMesh read_ply(const std::string& path, const FileLoc& ref);

/** The counts of the `vertex` and `face` elements a PLY file's header declares, read from the
 *  header alone (a few kilobytes, for checking a sequence of meshes up front); false when the
 *  file is not a plain PLY file with a readable header (a gzip'd one included). */
bool ply_header_counts(const std::string& path, uint64_t& vertices, uint64_t& faces);

}  // namespace spangle
