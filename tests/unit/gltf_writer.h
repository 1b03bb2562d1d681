#pragma once
// A small glTF 2.0 writer for the tests: typed accessors over one buffer, the JSON put together
// from parts the test gives, written as a .gltf with a base64 buffer, a .gltf beside a .bin, or a
// .glb.

#include <fmt/format.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

namespace spangle::test {

/** Base64 (RFC 4648) of bytes. */
inline std::string base64(const std::string& bytes) {
    static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    std::size_t i = 0;
    for (; i + 2 < bytes.size(); i += 3) {
        const auto b = [&](std::size_t j) {
            return static_cast<uint32_t>(static_cast<uint8_t>(bytes[j]));
        };
        const uint32_t v = b(i) << 16 | b(i + 1) << 8 | b(i + 2);
        for (int s = 18; s >= 0; s -= 6) out += k[(v >> s) & 63];
    }
    if (i < bytes.size()) {
        uint32_t v = static_cast<uint32_t>(static_cast<uint8_t>(bytes[i])) << 16;
        if (i + 1 < bytes.size())
            v |= static_cast<uint32_t>(static_cast<uint8_t>(bytes[i + 1])) << 8;
        out += k[(v >> 18) & 63];
        out += k[(v >> 12) & 63];
        out += i + 1 < bytes.size() ? k[(v >> 6) & 63] : '=';
        out += '=';
    }
    return out;
}

/** A glTF document under construction: accessors and buffer views over one buffer. */
struct GltfWriter {
    std::string bin;                     ///< the buffer
    std::vector<std::string> views;      ///< bufferViews entries (JSON)
    std::vector<std::string> accessors;  ///< accessors entries (JSON)

    /** A buffer view of raw bytes (4-byte aligned); its index. */
    int view(const void* data, std::size_t size) {
        while (bin.size() % 4) bin += '\0';
        const std::size_t at = bin.size();
        bin.append(static_cast<const char*>(data), size);
        views.push_back(fmt::format(R"({{"buffer":0,"byteOffset":{},"byteLength":{}}})", at, size));
        return static_cast<int>(views.size()) - 1;
    }
    /** An accessor of floats, `type` "SCALAR", "VEC2", "VEC3" or "VEC4"; its index. */
    int floats(const std::vector<float>& v, const char* type, int comps) {
        const int bv = view(v.data(), v.size() * sizeof(float));
        accessors.push_back(
            fmt::format(R"({{"bufferView":{},"componentType":5126,"count":{},"type":"{}"}})", bv,
                        v.size() / static_cast<std::size_t>(comps), type));
        return static_cast<int>(accessors.size()) - 1;
    }
    /** An accessor of unsigned shorts (indices); its index. */
    int u16(const std::vector<uint16_t>& v) {
        const int bv = view(v.data(), v.size() * 2);
        accessors.push_back(
            fmt::format(R"({{"bufferView":{},"componentType":5123,"count":{},"type":"SCALAR"}})",
                        bv, v.size()));
        return static_cast<int>(accessors.size()) - 1;
    }
    /** An accessor of unsigned shorts with `comps` per element (`type` "VEC4": JOINTS_n); its
     *  index. */
    int u16s(const std::vector<uint16_t>& v, const char* type, int comps) {
        const int bv = view(v.data(), v.size() * 2);
        accessors.push_back(
            fmt::format(R"({{"bufferView":{},"componentType":5123,"count":{},"type":"{}"}})", bv,
                        v.size() / static_cast<std::size_t>(comps), type));
        return static_cast<int>(accessors.size()) - 1;
    }
    /** An accessor of unsigned ints (indices); its index. */
    int u32(const std::vector<uint32_t>& v) {
        const int bv = view(v.data(), v.size() * 4);
        accessors.push_back(
            fmt::format(R"({{"bufferView":{},"componentType":5125,"count":{},"type":"SCALAR"}})",
                        bv, v.size()));
        return static_cast<int>(accessors.size()) - 1;
    }

    /** The JSON: `body` holds the other top-level members (nodes, meshes, ...) without braces;
     *  the buffer is `uri` (empty: none, for a .glb). */
    std::string json(const std::string& body, const std::string& uri) const {
        std::string buffer =
            uri.empty() ? fmt::format(R"({{"byteLength":{}}})", bin.size())
                        : fmt::format(R"({{"byteLength":{},"uri":"{}"}})", bin.size(), uri);
        return fmt::format(
            R"({{"asset":{{"version":"2.0"}},"buffers":[{}],"bufferViews":[{}],"accessors":[{}],{}}})",
            buffer, fmt::join(views, ","), fmt::join(accessors, ","), body);
    }
    /** A .gltf with its buffer as a base64 data URI. */
    void write_gltf(const std::string& path, const std::string& body) const {
        std::ofstream(path, std::ios::binary)
            << json(body, "data:application/octet-stream;base64," + base64(bin));
    }
    /** A .gltf with its buffer in `bin_name` beside it. */
    void write_gltf_bin(const std::string& path, const std::string& bin_name,
                        const std::string& body) const {
        std::ofstream(path, std::ios::binary) << json(body, bin_name);
        const std::string dir = path.substr(0, path.find_last_of('/') + 1);
        std::ofstream(dir + bin_name, std::ios::binary) << bin;
    }
    /** A .glb: the JSON chunk and the BIN chunk (glTF 2.0, 4.4). */
    void write_glb(const std::string& path, const std::string& body) const {
        std::string j = json(body, "");
        while (j.size() % 4) j += ' ';
        std::string b = bin;
        while (b.size() % 4) b += '\0';
        const auto u32le = [](std::string& s, uint32_t v) {
            s.append(reinterpret_cast<const char*>(&v), 4);
        };
        std::string out = "glTF";
        u32le(out, 2);
        u32le(out, static_cast<uint32_t>(12 + 8 + j.size() + 8 + b.size()));
        u32le(out, static_cast<uint32_t>(j.size()));
        u32le(out, 0x4E4F534Au);
        out += j;
        u32le(out, static_cast<uint32_t>(b.size()));
        u32le(out, 0x004E4942u);
        out += b;
        std::ofstream(path, std::ios::binary) << out;
    }
};

}  // namespace spangle::test
