#include "geometry/cage.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "core/files.h"
#include "core/hash.h"
#include "geometry/obj_reader.h"

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
    add(cage.colors.data(), cage.colors.size() * sizeof(float));
    return h;
}

bool same_cage_content(const Cage& a, const Cage& b) {
    return a.positions == b.positions && a.face_sizes == b.face_sizes &&
           a.face_vertices == b.face_vertices && a.uvs == b.uvs && a.face_uvs == b.face_uvs &&
           a.colors == b.colors;
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
    // Spangle's own OBJ reader (the mesh reader's syntax: a byte order mark, continued lines,
    // negative indices, non-finite numbers named at their line), faces kept as written.
    const ObjPolygons obj = read_obj_polygons(path, ref);
    Cage cage;
    cage.source = path;
    cage.positions = obj.positions;
    cage.uvs = obj.uvs;
    cage.colors = obj.colors;
    bool any_uv = false, all_uv = true;
    std::size_t at = 0;
    for (std::size_t f = 0; f < obj.face_sizes.size(); ++f) {
        const int n = obj.face_sizes[f];
        const int line = obj.face_lines[f];
        // OpenSubdiv takes any size, but the refiner's tables are sized for ordinary meshes.
        if (n > 255)
            throw_error(ref,
                        "cage '{}', line {}: a face of {} corners; at most 255 are supported "
                        "(split the face)",
                        path, line, n);
        for (int k = 0; k < n; ++k) {
            const int64_t v = obj.face_vertices[at + static_cast<std::size_t>(k)];
            for (int j = 0; j < k; ++j)
                if (obj.face_vertices[at + static_cast<std::size_t>(j)] == v)
                    throw_error(ref,
                                "cage '{}', line {}: the face uses vertex {} twice (a degenerate "
                                "face)",
                                path, line, v + 1);
            const int64_t t = obj.face_uvs[at + static_cast<std::size_t>(k)];
            any_uv = any_uv || t >= 0;
            all_uv = all_uv && t >= 0;
            cage.face_vertices.push_back(static_cast<int>(v));
            cage.face_uvs.push_back(static_cast<int>(t));
        }
        cage.face_sizes.push_back(n);
        at += static_cast<std::size_t>(n);
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
    cage.turned_faces = orient_cage(cage);
    return cage;
}

std::size_t orient_cage(Cage& cage) {
    const std::size_t nf = cage.face_count();
    std::vector<std::size_t> first(nf + 1, 0);
    for (std::size_t f = 0; f < nf; ++f)
        first[f + 1] = first[f] + static_cast<std::size_t>(cage.face_sizes[f]);
    // Every edge with the faces that use it and the way each crosses it (+1: low to high).
    struct Use {
        std::size_t face;
        int way;
    };
    std::map<std::pair<int, int>, std::vector<Use>> edges;
    for_each_edge(cage, [&](std::size_t f, int a, int b) {
        if (a != b) edges[{std::min(a, b), std::max(a, b)}].push_back({f, a < b ? 1 : -1});
    });
    std::vector<std::vector<std::pair<std::size_t, bool>>> next(nf);  // neighbour, same way
    for (const auto& [edge, uses] : edges)
        if (uses.size() == 2 && uses[0].face != uses[1].face) {
            const bool same = uses[0].way == uses[1].way;
            next[uses[0].face].push_back({uses[1].face, same});
            next[uses[1].face].push_back({uses[0].face, same});
        }
    // Each piece: a flip per face relative to its first, then the winding most faces have.
    std::vector<int> flip(nf, -1);
    std::vector<std::size_t> piece, stack;
    std::size_t turned = 0;
    for (std::size_t seed = 0; seed < nf; ++seed) {
        if (flip[seed] >= 0) continue;
        piece.clear();
        flip[seed] = 0;
        stack.assign(1, seed);
        while (!stack.empty()) {
            const std::size_t f = stack.back();
            stack.pop_back();
            piece.push_back(f);
            for (const auto& [g, same] : next[f]) {
                if (flip[g] >= 0) continue;
                // Across a shared edge two faces wound alike cross it in opposite ways.
                flip[g] = same ? 1 - flip[f] : flip[f];
                stack.push_back(g);
            }
        }
        std::size_t flipped = 0;
        for (const std::size_t f : piece) flipped += static_cast<std::size_t>(flip[f]);
        const bool keep_majority = 2 * flipped > piece.size();
        for (const std::size_t f : piece) {
            const bool turn = keep_majority ? flip[f] == 0 : flip[f] == 1;
            if (!turn) continue;
            ++turned;
            // Reversed about the first corner.
            std::reverse(cage.face_vertices.begin() + static_cast<std::ptrdiff_t>(first[f] + 1),
                         cage.face_vertices.begin() + static_cast<std::ptrdiff_t>(first[f + 1]));
            if (!cage.face_uvs.empty())
                std::reverse(cage.face_uvs.begin() + static_cast<std::ptrdiff_t>(first[f] + 1),
                             cage.face_uvs.begin() + static_cast<std::ptrdiff_t>(first[f + 1]));
        }
    }
    return turned;
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
