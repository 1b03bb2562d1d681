#pragma once
// Subdivision surfaces through OpenSubdiv (Far): a cage is refined uniformly to a level, and the
// refined vertices are moved to the limit surface with limit normals (from the limit tangents)
// and face-varying uvs refined and taken to the limit per channel, so seams stay seams. The
// result is an ordinary triangle mesh whose normals are those of the smooth surface.

#include <string>
#include <vector>

#include "core/math.h"
#include "core/progress.h"
#include "geometry/cage.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** How to subdivide one cage. */
struct SubdivOptions {
    enum class Scheme { CatmullClark, Loop };
    enum class Boundary { None, EdgeOnly, EdgeAndCorner };
    enum class UvInterpolation { Smooth, CornersOnly, Boundaries, All };
    Scheme scheme = Scheme::CatmullClark;
    Boundary boundary = Boundary::EdgeAndCorner;
    UvInterpolation uv_interpolation = UvInterpolation::CornersOnly;
    int level = 3;                        ///< uniform refinement level, 0..8
    std::vector<int> crease_vertices;     ///< pairs of cage vertex indices
    std::vector<float> crease_sharpness;  ///< one per pair
    std::vector<int> corner_vertices;     ///< cage vertex indices
    std::vector<float> corner_sharpness;  ///< one per corner
    bool operator==(const SubdivOptions&) const = default;
};

/** Refines `cage` to a triangle mesh at the limit surface. Throws SpangleError (at `ref`) for
 *  topology OpenSubdiv rejects or a crease/corner naming a vertex the cage lacks. `progress`
 *  (may be empty) is told how far it is, as `what`. */
TriangleMesh subdivide(const Cage& cage, const SubdivOptions& options, const FileLoc& ref,
                       const WorkProgress& progress = {}, const std::string& what = {});

/** Triangles subdivide() makes of `cage` with `options` (exact for uniform refinement). */
double subdivided_triangles(const Cage& cage, const SubdivOptions& options);

/** Refuses (SpangleError at `ref`, naming the setting to lower) a refinement whose triangles
 *  would not fit the memory available now (about 300 bytes each at the peak, BVH included) or
 *  32-bit indices. `from_camera`: the level was chosen by level = "auto". */
void check_subdivision_memory(const Cage& cage, const SubdivOptions& options, bool from_camera,
                              const FileLoc& ref);

/** The refinement level that brings the cage's longest edge under `pixel_budget` pixels when
 *  seen at distance `distance` with `pixel_angle` radians per pixel: each level halves edges. */
int level_for_camera(double longest_edge, double distance, double pixel_angle, double pixel_budget,
                     int max_level);

/** Longest edge of a cage after `to_world` (metres). */
double longest_edge(const Cage& cage, const Affine& to_world);

}  // namespace spangle
