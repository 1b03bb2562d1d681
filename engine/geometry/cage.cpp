#include "geometry/cage.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/files.h"
#include "core/hash.h"

namespace spangle {

uint64_t cage_content_hash(const Cage& cage) {
    // Each array's byte count, then its bytes in 8-byte words (so that [a][b] and [ab] differ).
    uint64_t h = 0x43414745ull;
    const auto add = [&h](const void* data, std::size_t bytes) {
        h = hash2(h, bytes);
        const auto* p = static_cast<const unsigned char*>(data);
        for (std::size_t i = 0; i < bytes; i += 8) {
            uint64_t w = 0;
            std::memcpy(&w, p + i, std::min<std::size_t>(8, bytes - i));
            h = hash2(h, w);
        }
    };
    add(cage.positions.data(), cage.positions.size() * sizeof(float));
    add(cage.face_sizes.data(), cage.face_sizes.size() * sizeof(int));
    add(cage.face_vertices.data(), cage.face_vertices.size() * sizeof(int));
    add(cage.uvs.data(), cage.uvs.size() * sizeof(float));
    add(cage.face_uvs.data(), cage.face_uvs.size() * sizeof(int));
    return h;
}

bool same_cage_content(const Cage& a, const Cage& b) {
    return a.positions == b.positions && a.face_sizes == b.face_sizes &&
           a.face_vertices == b.face_vertices && a.uvs == b.uvs && a.face_uvs == b.face_uvs;
}

Cage load_cage(const std::string& path, const FileLoc& ref) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
        throw_error(ref, "cage file '{}' not found (looked for {})", path, absolute_path(path));
    if (!std::filesystem::is_regular_file(path, ec))
        throw_error(ref, "cage file '{}' is not a regular file (a folder, a device or a pipe)",
                    path);
    const std::string ext = std::filesystem::path(path).extension().string();
    if (ext != ".obj" && ext != ".OBJ")
        throw_error(ref, "cage file '{}' has extension '{}'; subdivision cages are read from .obj",
                    path, ext);
    // tinyobjloader reads "nan" and "inf" as ordinary numbers without a word, so positions are
    // checked here first, with the line they are on.
    {
        std::ifstream in(path);
        std::string line;
        for (int number = 1; std::getline(in, line); ++number) {
            // tinyobjloader skips leading blanks: so does this check.
            const std::size_t start = line.find_first_not_of(" \t");
            if (start == std::string::npos) continue;
            line.erase(0, start);
            if (line.size() >= 2 && line[0] == 'f' && (line[1] == ' ' || line[1] == '\t')) {
                // Its face sizes are bytes: a face of 256 or more corners would wrap silently.
                std::istringstream corners(line.substr(2));
                std::string corner;
                std::size_t count = 0;
                while (corners >> corner) ++count;
                if (count > 255)
                    throw_error(ref,
                                "cage '{}': line {}: a face of {} corners; at most 255 are "
                                "supported (split the face)",
                                path, number, count);
                continue;
            }
            if (line.size() < 2 || line[0] != 'v' || (line[1] != ' ' && line[1] != '\t')) continue;
            std::istringstream fields(line.substr(2));
            std::string token;
            for (int k = 0; k < 3 && fields >> token; ++k) {
                char* end = nullptr;
                const double x = std::strtod(token.c_str(), &end);
                if (end == token.c_str() || !std::isfinite(x))
                    throw_error(ref,
                                "cage '{}': line {}: vertex position '{}' is not a finite number",
                                path, number, token);
            }
        }
    }
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;  // keep quads and n-gons: they are the cage
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    if (!reader.ParseFromFile(path, config))
        throw_error(ref, "cannot read cage '{}': {}", path,
                    reader.Error().empty() ? "unknown error" : reader.Error());
    const auto& attrib = reader.GetAttrib();
    Cage cage;
    cage.source = path;
    cage.positions.assign(attrib.vertices.begin(), attrib.vertices.end());
    cage.uvs.assign(attrib.texcoords.begin(), attrib.texcoords.end());
    bool any_uv = false, all_uv = true;
    for (const auto& shape : reader.GetShapes()) {
        std::size_t at = 0;
        for (unsigned char n : shape.mesh.num_face_vertices) {
            cage.face_sizes.push_back(n);
            for (unsigned k = 0; k < n; ++k) {
                const tinyobj::index_t& idx = shape.mesh.indices[at + k];
                cage.face_vertices.push_back(idx.vertex_index);
                cage.face_uvs.push_back(idx.texcoord_index);
                any_uv = any_uv || idx.texcoord_index >= 0;
                all_uv = all_uv && idx.texcoord_index >= 0;
            }
            at += n;
        }
    }
    if (any_uv && !all_uv)
        throw_error(
            ref,
            "cage '{}' gives uvs for some face corners but not others; give them for all or none",
            path);
    if (!any_uv) {
        cage.uvs.clear();
        cage.face_uvs.clear();
    }
    validate_cage(cage, ref);
    return cage;
}

void validate_cage(const Cage& cage, const FileLoc& ref) {
    if (cage.face_count() == 0) throw_error(ref, "cage '{}' has no faces", cage.source);
    for (std::size_t i = 0; i < cage.positions.size(); ++i)
        if (!std::isfinite(cage.positions[i]))
            throw_error(ref, "cage '{}': vertex {} has a non-finite position", cage.source, i / 3);
    const auto nv = static_cast<int>(cage.vertex_count());
    const auto nuv = static_cast<int>(cage.uvs.size() / 2);
    std::size_t at = 0;
    for (std::size_t f = 0; f < cage.face_count(); ++f) {
        const int n = cage.face_sizes[f];
        if (n < 3)
            throw_error(ref, "cage '{}': face {} has {} corners; a face needs at least 3",
                        cage.source, f, n);
        for (int k = 0; k < n; ++k) {
            const int v = cage.face_vertices[at + static_cast<std::size_t>(k)];
            if (v < 0 || v >= nv)
                throw_error(ref,
                            "cage '{}': face {} refers to vertex {}, but there are {} vertices",
                            cage.source, f, v, nv);
            for (int j = 0; j < k; ++j)
                if (cage.face_vertices[at + static_cast<std::size_t>(j)] == v)
                    throw_error(ref, "cage '{}': face {} uses vertex {} twice (a degenerate face)",
                                cage.source, f, v);
            if (!cage.face_uvs.empty()) {
                const int t = cage.face_uvs[at + static_cast<std::size_t>(k)];
                if (t < 0 || t >= nuv)
                    throw_error(ref, "cage '{}': face {} refers to uv {}, but there are {} uvs",
                                cage.source, f, t, nuv);
            }
        }
        at += static_cast<std::size_t>(n);
    }
    for (float x : cage.uvs)
        if (!std::isfinite(x)) throw_error(ref, "cage '{}' has a non-finite uv", cage.source);
}

}  // namespace spangle
