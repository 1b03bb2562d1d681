#pragma once
// Polygons as triangles, for the mesh readers (OBJ and PLY faces of more than three corners).

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/math.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** Appends the triangles of the polygon with vertex indices f[0..n) and corner positions
 *  p[0..n) to `out` (three indices each). A convex polygon (or one without area) is a fan about
 *  its first corner; a concave one (an L, a star, a ring cut open, text and logo outlines) is
 *  cut by ear clipping in the plane of its Newell normal, its reflex corners kept in a grid so
 *  that a face of a hundred thousand corners takes milliseconds. An outline that crosses itself
 *  leaves no ear at some point: the rest is a fan. */
void triangulate_polygon(const uint32_t* f, const Vec3* p, std::size_t n,
                         std::vector<uint32_t>& out);

/** Appends to mesh.indices the triangles of faces whose vertex indices stand one after another
 *  in `faces`, face k ending at ends[k], each by triangulate_polygon over the mesh's positions.
 *  An index beyond the vertices takes the origin's place here: the mesh's validation names it. */
void triangulate_faces(TriangleMesh& mesh, const std::vector<uint32_t>& faces,
                       const std::vector<std::size_t>& ends);

}  // namespace spangle
