#pragma once
// A glTF file's bytes, and the chunks of a binary glTF (.glb, glTF 2.0, 4.4) checked before
// tinygltf reads them.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace spangle::gltf {

/** The whole file; throws SpangleError when it cannot be opened. */
std::string read_file_bytes(const std::string& path);

/** The little-endian 32-bit word at byte `at` of b (at + 4 <= b.size()). */
uint32_t glb_u32(const std::string& b, std::size_t at);

/** A .glb's JSON chunk (a view into the file's bytes) and the length of its BIN chunk (none
 *  when it has none). */
struct GlbChunks {
    std::string_view json;
    std::optional<std::size_t> bin;
};

/** The chunks of .glb `bytes` (read from `path`, which errors name), the header and the chunks'
 *  lengths and types checked: throws SpangleError where they are damaged. */
GlbChunks glb_chunks(const std::string& bytes, const std::string& path);

}  // namespace spangle::gltf
