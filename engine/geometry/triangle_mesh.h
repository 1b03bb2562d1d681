#pragma once
// Triangle meshes as loaded from files, in object space, structure of arrays.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/math.h"

namespace spangle {

/** An indexed triangle mesh in object space. normals, uvs and colors are empty or one per
 *  vertex. */
struct TriangleMesh {
    std::vector<float> positions;   ///< xyz per vertex, object space
    std::vector<float> normals;     ///< xyz per vertex (unit), or empty: use face normals
    std::vector<float> uvs;         ///< uv per vertex, or empty: uv from barycentrics
    std::vector<uint32_t> indices;  ///< three per triangle, each < vertex_count()
    /** rgb per vertex, linear Rec.709 (decoded from the file's encoding by its reader), or
     *  empty: a material parameter with `vertex_color` reads 1 there. */
    std::vector<float> colors;
    /** xyz per vertex of the rest pose (geometry/rest_pose.h), object space; empty: the mesh is
     *  its own rest pose. Object-space shading inputs are taken from it. */
    std::vector<float> rest_positions;
    std::string source;  ///< file it came from, for messages
    /** What its reader left out (faces of fewer than three corners), for the loader to say. */
    std::vector<std::string> notes;
    /** Notes `n` faces of fewer than three corners a reader skipped (none when n is 0). */
    void note_short_faces(std::size_t n);
    /** Turns every triangle's other side to the front: its second and third corners swapped. */
    void reverse_winding();

    std::size_t vertex_count() const { return positions.size() / 3; }
    std::size_t triangle_count() const { return indices.size() / 3; }
    Vec3 position(uint32_t i) const {
        return {positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]};
    }
    /** Vertex i's colour (only when colors is not empty). */
    Vec3 color(uint32_t i) const { return {colors[3 * i], colors[3 * i + 1], colors[3 * i + 2]}; }
    /** Vertex i in the rest pose (only when rest_positions is not empty). */
    Vec3 rest_position(uint32_t i) const {
        return {rest_positions[3 * i], rest_positions[3 * i + 1], rest_positions[3 * i + 2]};
    }
    /** The share of the surface (by area) whose uvs map its triangles to a non-zero uv area: 0
     *  without uvs, or with uvs that are all zero (as exported by some tools). */
    double uv_mapped_fraction() const;
};

/** A hash of a mesh's positions, normals, uvs, colours and indices (not its source name): equal for
 *  equal content. */
uint64_t mesh_content_hash(const TriangleMesh& mesh);

/** The area of a mesh whose points `place` carries where it stands (a placement's point map). */
template <class Place>
double placed_area(const TriangleMesh& m, Place&& place) {
    double a = 0.0;
    for (std::size_t t = 0; t < m.triangle_count(); ++t) {
        const Vec3 p0 = place(m.position(m.indices[3 * t])),
                   p1 = place(m.position(m.indices[3 * t + 1])),
                   p2 = place(m.position(m.indices[3 * t + 2]));
        a += 0.5 * static_cast<double>(length(cross(p1 - p0, p2 - p0)));
    }
    return a;
}

/** All meshes of a scene; objects refer to them by index, so one file loaded twice is shared. */
struct GeometryStore {
    /** Loaded meshes, shared with the build cache of a watch session (a reload that does not
     *  touch a mesh keeps the very same one). */
    std::vector<std::shared_ptr<const TriangleMesh>> meshes;
    const TriangleMesh& mesh(std::size_t i) const { return *meshes[i]; }
};

}  // namespace spangle
