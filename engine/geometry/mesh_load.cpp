#include "geometry/mesh_load.h"

#include "geometry/obj_reader.h"
#include "geometry/ply_reader.h"

#include <cmath>
#include <cstring>
#include <filesystem>

#include "core/files.h"
#include "core/hash.h"

namespace spangle {

TriangleMesh load_mesh(const std::string& path, const FileLoc& ref) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!fs::exists(path, ec))
        throw_error(ref, "mesh file '{}' not found (looked for {})", path, absolute_path(path));
    if (!fs::is_regular_file(path, ec))
        throw_error(ref, "mesh file '{}' is not a regular file (a folder, a device or a pipe)",
                    path);
    std::string ext = fs::path(path).extension().string();
    // A gzip'd PLY (pbrt-v4's scenes: ".ply.gz") is read as the PLY it holds.
    const std::string inner = fs::path(path).stem().extension().string();
    if ((ext == ".gz" || ext == ".GZ") && (inner == ".ply" || inner == ".PLY")) ext = ".ply";
    if (ext != ".obj" && ext != ".OBJ" && ext != ".ply" && ext != ".PLY")
        throw_error(ref, "mesh file '{}' has extension '{}'; expected .obj, .ply or .ply.gz", path,
                    ext);
    if (ext == ".ply" || ext == ".PLY") {
        TriangleMesh mesh = read_ply(path, ref);
        validate_mesh(mesh, ref);
        return mesh;
    }

    TriangleMesh mesh = read_obj(path, ref);
    validate_mesh(mesh, ref);
    return mesh;
}

void validate_mesh(const TriangleMesh& mesh, const FileLoc& ref) {
    if (mesh.triangle_count() == 0)
        throw_error(
            ref, "mesh '{}' has no triangles{}", mesh.source,
            mesh.notes.empty() ? std::string() : fmt::format(" ({})", fmt::join(mesh.notes, "; ")));
    for (std::size_t i = 0; i < mesh.positions.size(); ++i)
        if (!std::isfinite(mesh.positions[i]))
            throw_error(ref, "mesh '{}': vertex {} has a non-finite position ({}, {}, {})",
                        mesh.source, i / 3, mesh.positions[i / 3 * 3],
                        mesh.positions[i / 3 * 3 + 1], mesh.positions[i / 3 * 3 + 2]);
    const std::size_t n = mesh.vertex_count();
    for (std::size_t i = 0; i < mesh.indices.size(); ++i)
        if (mesh.indices[i] >= n)
            throw_error(ref,
                        "mesh '{}': triangle {} refers to vertex {}, but there are {} vertices",
                        mesh.source, i / 3, mesh.indices[i], n);
    for (std::size_t i = 0; i < mesh.normals.size(); ++i)
        if (!std::isfinite(mesh.normals[i]))
            throw_error(ref, "mesh '{}': vertex {} has a non-finite normal ({}, {}, {})",
                        mesh.source, i / 3, mesh.normals[i / 3 * 3], mesh.normals[i / 3 * 3 + 1],
                        mesh.normals[i / 3 * 3 + 2]);
    for (std::size_t i = 0; i < mesh.colors.size(); ++i)
        if (!std::isfinite(mesh.colors[i]))
            throw_error(ref, "mesh '{}': vertex {} has a non-finite colour ({}, {}, {})",
                        mesh.source, i / 3, mesh.colors[i / 3 * 3], mesh.colors[i / 3 * 3 + 1],
                        mesh.colors[i / 3 * 3 + 2]);
    for (std::size_t i = 0; i < mesh.uvs.size(); ++i)
        if (!std::isfinite(mesh.uvs[i]))
            throw_error(ref, "mesh '{}': vertex {} has a non-finite uv ({}, {})", mesh.source,
                        i / 2, mesh.uvs[i / 2 * 2], mesh.uvs[i / 2 * 2 + 1]);
}

}  // namespace spangle

namespace spangle {

uint64_t mesh_content_hash(const TriangleMesh& mesh) {
    // Words of every array, each array's length first (so that [a][b] and [ab] differ).
    uint64_t h = 0x5350414e474c45ull;
    const auto words = [&h](const void* data, std::size_t bytes) {
        h = hash2(h, bytes);
        const auto* p = static_cast<const unsigned char*>(data);
        std::size_t i = 0;
        for (; i + 8 <= bytes; i += 8) {
            uint64_t w;
            std::memcpy(&w, p + i, 8);
            h = hash2(h, w);
        }
        uint64_t tail = 0;
        if (bytes > i) std::memcpy(&tail, p + i, bytes - i);
        h = hash2(h, tail);
    };
    words(mesh.positions.data(), mesh.positions.size() * sizeof(float));
    words(mesh.normals.data(), mesh.normals.size() * sizeof(float));
    words(mesh.uvs.data(), mesh.uvs.size() * sizeof(float));
    words(mesh.colors.data(), mesh.colors.size() * sizeof(float));
    words(mesh.indices.data(), mesh.indices.size() * sizeof(uint32_t));
    // Only when there is one (the hashes of meshes without a rest pose stay as they were).
    if (!mesh.rest_positions.empty())
        words(mesh.rest_positions.data(), mesh.rest_positions.size() * sizeof(float));
    return h;
}

void TriangleMesh::note_short_faces(std::size_t n) {
    if (n > 0)
        notes.push_back(
            fmt::format("{} face{} of fewer than 3 corners (points or edges, not surfaces) skipped",
                        n, n == 1 ? "" : "s"));
}

void TriangleMesh::reverse_winding() {
    for (std::size_t t = 0; t + 2 < indices.size(); t += 3)
        std::swap(indices[t + 1], indices[t + 2]);
}

double TriangleMesh::uv_mapped_fraction() const {
    if (uvs.empty()) return 0.0;
    double mapped = 0.0, total = 0.0;
    for (std::size_t t = 0; t < triangle_count(); ++t) {
        const uint32_t i0 = indices[3 * t], i1 = indices[3 * t + 1], i2 = indices[3 * t + 2];
        const double area = length(cross(position(i1) - position(i0), position(i2) - position(i0)));
        const double du1 = uvs[2 * i1] - uvs[2 * i0], dv1 = uvs[2 * i1 + 1] - uvs[2 * i0 + 1];
        const double du2 = uvs[2 * i2] - uvs[2 * i0], dv2 = uvs[2 * i2 + 1] - uvs[2 * i0 + 1];
        total += area;
        // The same test as shading's (render/surface.cpp): a uv determinant above 1e-20.
        if (std::fabs(du1 * dv2 - dv1 * du2) > 1e-20) mapped += area;
    }
    return total > 0.0 ? mapped / total : 0.0;
}

}  // namespace spangle
