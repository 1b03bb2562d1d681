#pragma once
// The rest pose of a deforming mesh: a mesh of the same topology (a `rest_mesh`, or a sequence's
// file of frame_start) whose positions object-space patterns are laid out on, so that a flake
// stays on its spot of the surface while the surface bends. The deformed mesh carries the rest
// positions beside its own (TriangleMesh::rest_positions); shading reads them at the hit
// (render/surface.h).

#include <memory>

#include "core/error.h"
#include "geometry/cage.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** Throws SpangleError at `ref`, naming both meshes' files, unless `rest` has `mesh`'s topology:
 *  the same vertex count, triangle count and vertex indices. */
void check_same_topology(const TriangleMesh& mesh, const TriangleMesh& rest, const FileLoc& ref);

/** The same for subdivision cages: the same vertex count, faces (corner counts and vertex
 *  indices) and uv indices, so that both refine to meshes of one topology. */
void check_same_topology(const Cage& cage, const Cage& rest, const FileLoc& ref);

/** `mesh` with `rest`'s positions as its rest pose (topology checked as above). `mesh` itself,
 *  with no rest positions, when the positions are equal: a mesh in its rest pose needs none, and
 *  renders bit for bit as the plain mesh. */
std::shared_ptr<const TriangleMesh> with_rest_pose(std::shared_ptr<const TriangleMesh> mesh,
                                                   const TriangleMesh& rest, const FileLoc& ref);

/** How many triangles of a mesh with a rest pose have an area in the pose it is drawn in but
 *  none in the rest pose (its object-space patterns, flakes among them, have no room there: a
 *  patch without glitter). */
std::size_t flat_in_rest_pose(const TriangleMesh& posed);

}  // namespace spangle
