// Reading a glTF file's bytes and a .glb's chunks: see gltf_glb.h.

#include "scene/gltf/gltf_glb.h"

#include <cstring>
#include <fstream>
#include <iterator>

#include "core/error.h"
#include "core/files.h"

namespace spangle::gltf {

std::string read_file_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw_error(FileLoc{path, 0, 0}, "cannot open the file: {}", unreadable(path));
    // Read into a string of the file's size exactly (one allocation, and no spare capacity past
    // its end: a read past the end of the file's bytes is caught by AddressSanitizer, where the
    // capacity a growing string leaves hid one), then whatever more a growing file holds.
    std::string bytes;
    if (in.seekg(0, std::ios::end)) {
        const std::streamoff size = in.tellg();
        in.seekg(0, std::ios::beg);
        if (size > 0 && in) {
            bytes.resize(static_cast<std::size_t>(size));
            in.read(bytes.data(), size);
            bytes.resize(static_cast<std::size_t>(in.gcount()));
            in.clear();
        }
    }
    in.clear();
    bytes.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    return bytes;
}

uint32_t glb_u32(const std::string& b, std::size_t at) {
    uint32_t v;
    std::memcpy(&v, b.data() + at, 4);
    return v;
}

GlbChunks glb_chunks(const std::string& bytes, const std::string& path) {
    const FileLoc file{path, 0, 0};
    if (bytes.size() < 20)
        throw_error(file, "a .glb file needs at least 20 bytes, this has {}", bytes.size());
    if (bytes.compare(0, 4, "glTF") != 0)
        throw_error(file, "not a binary glTF file (it does not start with 'glTF')");
    if (glb_u32(bytes, 4) != 2)
        throw_error(file, "binary glTF version {}: only 2 is read", glb_u32(bytes, 4));
    if (glb_u32(bytes, 8) > bytes.size())
        throw_error(file, "the header gives {} bytes, the file has {}", glb_u32(bytes, 8),
                    bytes.size());
    const uint32_t length = glb_u32(bytes, 12);
    if (glb_u32(bytes, 16) != 0x4E4F534Au)
        throw_error(file, "the first chunk of a .glb file must be its JSON");
    if (length > bytes.size() - 20)
        throw_error(file, "the JSON chunk ({} bytes) runs past the end of the file", length);
    // Its length as the spec has it (tinygltf refuses others, in words that do not say where;
    // one off, the next chunk's header was read from inside the JSON text).
    if (length == 0) throw_error(file, "the JSON chunk is empty (its length in the header is 0)");
    if (length % 4 != 0)
        throw_error(file,
                    "the JSON chunk's length {} is not a multiple of 4 (a .glb pads its chunks to "
                    "4 bytes): the file is damaged or was written with wrong lengths",
                    length);
    // The chunk after it (the BIN chunk) must end inside the header's length: tinygltf checks
    // its length without its 8-byte header and copied up to 8 bytes from past the end of the
    // file's memory into the buffer.
    const std::size_t total = glb_u32(bytes, 8), next = 20 + std::size_t{length};
    // (Its type first: a JSON length that is wrong puts the next header inside the text.)
    if (next + 8 <= total && glb_u32(bytes, next + 4) != 0x004E4942u)
        throw_error(file,
                    "the chunk after the JSON (from byte {}) is not a BIN chunk (its type is "
                    "0x{:08x}, BIN is 0x004e4942): the file is damaged, or the JSON chunk's "
                    "length ({}) is wrong",
                    next, glb_u32(bytes, next + 4), length);
    if (next + 8 <= total && glb_u32(bytes, next) > total - next - 8)
        throw_error(file,
                    "the chunk after the JSON ({} bytes from byte {}) runs past the end of the "
                    "file ({} bytes, as its header says)",
                    glb_u32(bytes, next), next + 8, total);
    if (next < total && next + 8 > total)
        throw_error(file,
                    "{} bytes after the JSON chunk are too few for a chunk's header (8 bytes): the "
                    "file is damaged",
                    total - next);
    return {std::string_view(bytes).substr(20, length),
            next + 8 <= total ? std::optional<std::size_t>(glb_u32(bytes, next)) : std::nullopt};
}

}  // namespace spangle::gltf
