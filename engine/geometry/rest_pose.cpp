#include "geometry/rest_pose.h"

namespace spangle {

void check_same_topology(const TriangleMesh& mesh, const TriangleMesh& rest, const FileLoc& ref) {
    if (mesh.vertex_count() != rest.vertex_count() ||
        mesh.triangle_count() != rest.triangle_count())
        throw_error(ref,
                    "mesh '{}' ({} vertices, {} triangles) does not have the topology of its rest "
                    "pose '{}' ({} vertices, {} triangles): every frame of a deforming mesh needs "
                    "the same vertices and triangles",
                    mesh.source, mesh.vertex_count(), mesh.triangle_count(), rest.source,
                    rest.vertex_count(), rest.triangle_count());
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const uint32_t* a = &mesh.indices[3 * t];
        const uint32_t* b = &rest.indices[3 * t];
        if (a[0] != b[0] || a[1] != b[1] || a[2] != b[2])
            throw_error(ref,
                        "mesh '{}' does not have the topology of its rest pose '{}': triangle {} "
                        "joins vertices {} {} {} in the one and {} {} {} in the other",
                        mesh.source, rest.source, t, a[0], a[1], a[2], b[0], b[1], b[2]);
    }
}

void check_same_topology(const Cage& cage, const Cage& rest, const FileLoc& ref) {
    if (cage.vertex_count() != rest.vertex_count() || cage.face_count() != rest.face_count())
        throw_error(ref,
                    "cage '{}' ({} vertices, {} faces) does not have the topology of its rest "
                    "pose '{}' ({} vertices, {} faces): every frame of a deforming cage needs "
                    "the same vertices and faces",
                    cage.source, cage.vertex_count(), cage.face_count(), rest.source,
                    rest.vertex_count(), rest.face_count());
    if (cage.face_sizes != rest.face_sizes || cage.face_vertices != rest.face_vertices)
        throw_error(ref,
                    "cage '{}' does not have the topology of its rest pose '{}': the same "
                    "counts, but its faces join other vertices",
                    cage.source, rest.source);
    if (cage.face_uvs != rest.face_uvs)
        throw_error(ref,
                    "cage '{}' does not have the uv layout of its rest pose '{}': its faces' "
                    "corners use other uv indices",
                    cage.source, rest.source);
}

std::shared_ptr<const TriangleMesh> with_rest_pose(std::shared_ptr<const TriangleMesh> mesh,
                                                   const TriangleMesh& rest, const FileLoc& ref) {
    check_same_topology(*mesh, rest, ref);
    if (mesh->positions == rest.positions) return mesh;
    auto posed = std::make_shared<TriangleMesh>(*mesh);
    posed->rest_positions = rest.positions;
    return posed;
}

std::size_t flat_in_rest_pose(const TriangleMesh& posed) {
    if (posed.rest_positions.empty()) return 0;
    std::size_t flat = 0;
    for (std::size_t t = 0; t < posed.triangle_count(); ++t) {
        const uint32_t* v = &posed.indices[3 * t];
        const auto area2 = [&](auto at) {
            const Vec3 a = at(v[0]);
            return length(cross(at(v[1]) - a, at(v[2]) - a));
        };
        const float drawn = area2([&](uint32_t i) { return posed.position(i); });
        const float rest = area2([&](uint32_t i) { return posed.rest_position(i); });
        if (drawn > 0.0f && !(rest > 0.0f)) ++flat;
    }
    return flat;
}

}  // namespace spangle
