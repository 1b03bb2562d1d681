#include "geometry/ply_writer.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include "core/error.h"
#include "core/math.h"

namespace spangle {

void write_ply(const TriangleMesh& mesh, const std::string& path, const std::string& comment) {
    const std::size_t nv = mesh.vertex_count(), nf = mesh.triangle_count();
    const bool normals = !mesh.normals.empty(), uvs = !mesh.uvs.empty(),
               colors = !mesh.colors.empty();
    std::string header = "ply\nformat binary_little_endian 1.0\n";
    if (!comment.empty()) header += "comment " + comment + "\n";
    header += fmt::format(
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n", nv);
    if (normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
    if (uvs) header += "property float u\nproperty float v\n";
    // Linear, as floats (read_ply reads floating-point colours as linear, integer ones as sRGB).
    if (colors) header += "property float red\nproperty float green\nproperty float blue\n";
    header +=
        fmt::format("element face {}\nproperty list uchar uint vertex_indices\nend_header\n", nf);
    std::vector<char> body;
    body.reserve(nv * (12 + (normals ? 12 : 0) + (uvs ? 8 : 0) + (colors ? 12 : 0)) + nf * 13);
    const auto put = [&](const void* data, std::size_t bytes) {
        const auto* c = static_cast<const char*>(data);
        body.insert(body.end(), c, c + bytes);
    };
    for (std::size_t i = 0; i < nv; ++i) {
        put(&mesh.positions[3 * i], 12);
        if (normals) put(&mesh.normals[3 * i], 12);
        if (uvs) put(&mesh.uvs[2 * i], 8);
        if (colors) put(&mesh.colors[3 * i], 12);
    }
    for (std::size_t f = 0; f < nf; ++f) {
        const uint8_t three = 3;
        put(&three, 1);
        put(&mesh.indices[3 * f], 12);
    }
    const std::string tmp = fmt::format("{}.tmp{}", path, ::getpid());
    {
        std::ofstream out(tmp, std::ios::binary);
        out << header;
        out.write(body.data(), static_cast<std::streamsize>(body.size()));
        if (!out) {
            std::remove(tmp.c_str());
            throw_error("cannot write '{}'", path);
        }
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) {
        std::remove(tmp.c_str());
        throw_error("cannot write '{}': {}", path, ec.message());
    }
}

void write_obj_cage(const Cage& cage, const std::string& path, const std::string& comment) {
    std::string text = fmt::format("# {}\n", comment);
    const auto exact = [](float x) { return fmt::format("{}", static_cast<double>(x)); };
    // Colours as OBJ readers take them, sRGB-encoded (read_obj decodes them again).
    const auto encoded = [](float c) {
        return fmt::format("{}", linear_to_srgb(std::clamp(static_cast<double>(c), 0.0, 1.0)));
    };
    const bool colors = cage.colors.size() == cage.positions.size();
    for (std::size_t v = 0; v < cage.vertex_count(); ++v) {
        text += fmt::format("v {} {} {}", exact(cage.positions[3 * v]),
                            exact(cage.positions[3 * v + 1]), exact(cage.positions[3 * v + 2]));
        if (colors)
            text += fmt::format(" {} {} {}", encoded(cage.colors[3 * v]),
                                encoded(cage.colors[3 * v + 1]), encoded(cage.colors[3 * v + 2]));
        text += "\n";
    }
    for (std::size_t t = 0; t < cage.uvs.size() / 2; ++t)
        text += fmt::format("vt {} {}\n", exact(cage.uvs[2 * t]), exact(cage.uvs[2 * t + 1]));
    const bool uvs = !cage.face_uvs.empty();
    std::size_t at = 0;
    for (const int n : cage.face_sizes) {
        text += "f";
        for (int k = 0; k < n; ++k, ++at) {
            text += fmt::format(" {}", cage.face_vertices[at] + 1);
            if (uvs) text += fmt::format("/{}", cage.face_uvs[at] + 1);
        }
        text += "\n";
    }
    const std::string tmp = fmt::format("{}.tmp{}", path, ::getpid());
    {
        std::ofstream out(tmp, std::ios::binary);
        out << text;
        out.flush();
        if (!out) {
            std::remove(tmp.c_str());
            throw_error("cannot write '{}'", path);
        }
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) {
        std::remove(tmp.c_str());
        throw_error("cannot write '{}': {}", path, ec.message());
    }
}

}  // namespace spangle
