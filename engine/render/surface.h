#pragma once
// A ray's hit turned into what shading needs: position, frames, uv and its derivatives, and the
// uv footprint of the pixel (from ray differentials, or a widened cone when the path has lost
// them at a rough bounce).

#include "accel/embree_scene.h"
#include "geometry/triangle_mesh.h"
#include "render/camera.h"

namespace spangle {

/** Everything known about a surface hit that shading needs. World space unless noted. */
struct SurfacePoint {
    Vec3 p, ng;          ///< position; geometric normal facing wo
    Vec3 n, s, t;        ///< shading frame (n facing wo's side of ng)
    float u = 0, v = 0;  ///< surface parameterisation
    Vec3 dpdu, dpdv;     ///< position derivatives (zero when the uv mapping is degenerate)
    Vec3 dndu, dndv;     ///< shading-normal derivatives
    float uv_area = 0;   ///< |dp/du x dp/dv|
    bool backface = false;
    Vec3 dpdx, dpdy;                               ///< footprint axes on the surface (world)
    float dudx = 0, dudy = 0, dvdx = 0, dvdy = 0;  ///< footprint axes in uv
    float footprint = 0;                           ///< world width of the footprint
    bool has_uv = false;  ///< the mesh has uvs here and they map the triangle to an area
    /** The mesh's vertex colour here (linear Rec.709), 1 where it has none. */
    Vec3 color{1.0f, 1.0f, 1.0f};
    /** Position and (unit) geometric normal in object space; on a mesh with a rest pose, in
     *  the rest pose (the same barycentrics on the rest triangle). */
    Vec3 p_obj, ng_obj;
    Vec3 dpdx_obj, dpdy_obj;  ///< footprint axes in object space (set by object_footprint)
    /** How far off its triangle's plane a ray leaving p may find that triangle again, beyond
     *  what offset_origin's ulps of p's own coordinates cover: Embree's float intersection is
     *  as precise as the triangle's vertices' coordinates, not the hit's. 0 except on
     *  triangles much larger than the hit's coordinates (a floor scaled to 1e7). */
    float p_error = 0;
    /** Where rays leaving towards the side the mesh's normals face start from, relative to p:
     *  the hit lifted onto the smooth surface its vertex normals describe (each corner's tangent
     *  plane, where p lies below it, blended by the barycentrics; Hanika, "Hacking the Shadow
     *  Terminator", Ray Tracing Gems II, 2021). Zero on flat-shaded meshes and where the
     *  surface is concave. Without it a coarse smooth-shaded mesh shadows itself along its
     *  triangles' edges where the shading says light arrives (a jagged terminator). */
    Vec3 lift{0.0f, 0.0f, 0.0f};
    /** The interpolated normal (n before any map or bend), on n's side: which side of the
     *  smooth surface a leaving ray is on. */
    Vec3 n_smooth;
};

/** Where a ray leaving sp along wi starts, before offset_origin, and the side of the surface it
 *  leaves towards (`side`: ng or -ng, for offset_origin). A ray that leaves towards the outside
 *  of the smooth surface (the side the interpolated normal faces, on the mesh's front) starts
 *  from p lifted by sp.lift, even where it runs below the flat triangle's plane (the light that
 *  smooth shading says arrives near the terminator: from p it was blocked by the triangle's
 *  neighbours); any other from p itself, on the side of ng it points to. */
inline Vec3 leaving_point(const SurfacePoint& sp, Vec3 wi, Vec3& side) {
    const float flip = sp.backface ? -1.0f : 1.0f;
    if (dot(wi, sp.n_smooth) * flip > 0.0f &&
        (sp.lift.x != 0.0f || sp.lift.y != 0.0f || sp.lift.z != 0.0f)) {
        side = sp.ng * flip;
        return sp.p + sp.lift;
    }
    side = dot(wi, sp.ng) >= 0.0f ? sp.ng : -sp.ng;
    return sp.p;
}

/** A shading frame around unit normal n: s is `along` made orthogonal to n and normalised
 *  (any tangent when that is degenerate), t = n x s. */
void shading_frame(Vec3 n, Vec3 along, Vec3& s, Vec3& t);

/** Resolves a hit of the ray from o along unit d on `inst` (whose mesh is `mesh`) to a surface
 *  point oriented towards -d. */
SurfacePoint surface_at(const TriangleMesh& mesh, const Instance& inst, const Hit& h, Vec3 o,
                        Vec3 d);

/** Fills sp's footprint. With has_diff, from the differential rays hitting sp's tangent plane
 *  (has_diff is cleared if they miss it); otherwise a square of world width `widened` along
 *  dp/du and dp/dv. */
void footprint_at(SurfacePoint& sp, const RayDifferential& ray, bool& has_diff, float widened);

/** Fills sp's object-space footprint axes from its world ones (after footprint_at), for a hit
 *  on triangle `prim` of `mesh` placed by `inst`. On a mesh with a rest pose the axes are those
 *  of the rest pose: carried through the triangle's deformed-to-rest affine map. */
void object_footprint(SurfacePoint& sp, const Instance& inst, const TriangleMesh& mesh,
                      uint32_t prim);

/** Bends sp's shading normal, where needed, so that the mirror reflection of wo (unit, towards
 *  the viewer, on ng's side) about it leaves the surface: at least min(0.9 cos, 0.01) above the
 *  geometric plane, cos = wo.ng (the limit Cycles uses). Interpolated normals near a coarse
 *  mesh's silhouette and strong normal or bump maps tilt the shading normal until wo is under
 *  it or barely above it; every material then reflects nothing there (a black rim) or only
 *  into the surface. The new normal is the half vector of wo and the valid direction nearest
 *  to the old reflection (the old one lifted along its great circle through ng), so it bends
 *  no further than it must; the frame is rebuilt around it. Returns whether it bent. */
bool keep_reflection_above(SurfacePoint& sp, Vec3 wo);

}  // namespace spangle
