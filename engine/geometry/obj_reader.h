#pragma once
// Spangle's own reader for Wavefront OBJ meshes: v, vt, vn and f statements (positive or
// negative 1-based indices, v, v/vt, v//vn and v/vt/vn corners, polygons triangulated by
// geometry/polygon.h); every other statement (o, g, s, usemtl, mtllib, l, p, ...) is skipped.
// Errors name the line.
// It replaced a general-purpose importer that spent milliseconds on every file, leaked memory on
// some malformed ones and reported problems without a line.

#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** Reads an OBJ mesh. Corners sharing the same (v, vt, vn) share a vertex. Vertex colours
 *  (`v x y z r g b`, sRGB-encoded) are kept, linear. Normals are kept when
 *  every corner has one, uvs when any corner has one (corners without get (0, 0), which the
 *  renderer treats as unmapped). Throws SpangleError "path:line: ..." (with `ref`, the scene
 *  line naming the file) for a bad number, a non-finite value, an index out of range or a face
 *  of fewer than 3 corners. */
TriangleMesh read_obj(const std::string& path, const FileLoc& ref);

/** An OBJ file's faces as written (a subdivision cage): positions, uvs and each face's corners
 *  (0-based vertex and uv indices, uv -1 where a corner has none) with the line it is on. */
struct ObjPolygons {
    std::vector<float> positions, uvs;
    std::vector<float> colors;  ///< linear rgb per vertex (white where not given), or empty
    std::vector<int> face_sizes, face_lines;
    std::vector<int64_t> face_vertices, face_uvs;
};

/** Reads an OBJ file's faces without triangulating them, with read_obj's syntax and checks
 *  (errors say "cage '...', line N"). */
ObjPolygons read_obj_polygons(const std::string& path, const FileLoc& ref);

/** The counts of an OBJ file's `v` statements and of its faces of at least three corners, and
 *  their corners, from a scan of its lines (nothing parsed: for checking a sequence of meshes
 *  up front); false when the file cannot be read. */
bool obj_counts(const std::string& path, uint64_t& vertices, uint64_t& faces, uint64_t& corners);

}  // namespace spangle
