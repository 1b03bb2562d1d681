#include "geometry/mesh_load.h"

#include "geometry/ply_reader.h"

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/Importer.hpp>

#include <cmath>
#include <filesystem>

namespace spangle {

namespace {

/** Appends one assimp mesh to `out`; vertices keep their order, faces become triangles. */
void append_mesh(const aiMesh& m, TriangleMesh& out, bool want_normals, bool want_uvs) {
    const auto base = static_cast<uint32_t>(out.vertex_count());
    for (unsigned i = 0; i < m.mNumVertices; ++i) {
        out.positions.insert(out.positions.end(),
                             {m.mVertices[i].x, m.mVertices[i].y, m.mVertices[i].z});
        if (want_normals)
            out.normals.insert(out.normals.end(),
                               {m.mNormals[i].x, m.mNormals[i].y, m.mNormals[i].z});
        if (want_uvs)
            out.uvs.insert(out.uvs.end(), {m.mTextureCoords[0][i].x, m.mTextureCoords[0][i].y});
    }
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
        const aiFace& face = m.mFaces[f];
        if (face.mNumIndices != 3) continue;  // points and lines after triangulation
        for (unsigned k = 0; k < 3; ++k) out.indices.push_back(base + face.mIndices[k]);
    }
}

}  // namespace

TriangleMesh load_mesh(const std::string& path, const FileLoc& ref) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!fs::exists(path, ec)) throw_error(ref, "mesh file '{}' not found", path);
    if (!fs::is_regular_file(path, ec))
        throw_error(ref, "mesh file '{}' is not a regular file (a folder, a device or a pipe)",
                    path);
    const std::string ext = fs::path(path).extension().string();
    if (ext != ".obj" && ext != ".OBJ" && ext != ".ply" && ext != ".PLY")
        throw_error(ref, "mesh file '{}' has extension '{}'; expected .obj or .ply", path, ext);
    if (ext == ".ply" || ext == ".PLY") {
        TriangleMesh mesh = read_ply(path, ref);
        validate_mesh(mesh, ref);
        return mesh;
    }

    Assimp::Importer importer;
    // Drop what Spangle does not use, so assimp neither computes nor checks it.
    importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS,
                                aiComponent_COLORS | aiComponent_TANGENTS_AND_BITANGENTS |
                                    aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS |
                                    aiComponent_LIGHTS | aiComponent_CAMERAS |
                                    aiComponent_MATERIALS | aiComponent_TEXTURES);
    // ValidateDataStructure rejects out-of-range indices before anything reads them.
    const unsigned flags = aiProcess_Triangulate | aiProcess_ValidateDataStructure |
                           aiProcess_RemoveComponent | aiProcess_SortByPType;
    const aiScene* scene = importer.ReadFile(path, flags);
    if (!scene || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || !scene->mRootNode)
        throw_error(ref, "cannot read mesh '{}': {}", path, importer.GetErrorString());

    TriangleMesh mesh;
    mesh.source = path;
    bool all_normals = scene->mNumMeshes > 0, all_uvs = scene->mNumMeshes > 0;
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
        all_normals = all_normals && scene->mMeshes[i]->HasNormals();
        all_uvs = all_uvs && scene->mMeshes[i]->HasTextureCoords(0);
    }
    // Meshes are concatenated in object space; node transforms are ignored because OBJ and PLY
    // have none (assimp gives them the identity).
    for (unsigned i = 0; i < scene->mNumMeshes; ++i)
        append_mesh(*scene->mMeshes[i], mesh, all_normals, all_uvs);
    validate_mesh(mesh, ref);
    return mesh;
}

void validate_mesh(const TriangleMesh& mesh, const FileLoc& ref) {
    if (mesh.triangle_count() == 0) throw_error(ref, "mesh '{}' has no triangles", mesh.source);
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
    for (float x : mesh.normals)
        if (!std::isfinite(x)) throw_error(ref, "mesh '{}' has a non-finite normal", mesh.source);
    for (float x : mesh.uvs)
        if (!std::isfinite(x)) throw_error(ref, "mesh '{}' has a non-finite uv", mesh.source);
}

}  // namespace spangle

namespace spangle {

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
