#include "core/cryptomatte.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

namespace spangle {
namespace {

uint32_t rotl32(uint32_t x, int r) {
    return (x << r) | (x >> (32 - r));
}

/** MurmurHash3's finaliser: every input bit affects every output bit. */
uint32_t fmix32(uint32_t h) {
    h ^= h >> 16;
    h *= 0x85ebca6bu;
    h ^= h >> 13;
    h *= 0xc2b2ae35u;
    h ^= h >> 16;
    return h;
}

/** `text` as a JSON string literal. */
std::string json_string(std::string_view text) {
    std::string out = "\"";
    for (const char ch : text) {
        const auto c = static_cast<unsigned char>(ch);
        if (ch == '"' || ch == '\\')
            out += {'\\', ch};
        else if (c < 0x20)
            out += fmt::format("\\u{:04x}", c);
        else
            out += ch;
    }
    return out + "\"";
}

}  // namespace

uint32_t murmur3_32(std::string_view text, uint32_t seed) {
    constexpr uint32_t c1 = 0xcc9e2d51u, c2 = 0x1b873593u;
    const auto* data = reinterpret_cast<const unsigned char*>(text.data());
    const std::size_t len = text.size(), blocks = len / 4;
    uint32_t h = seed;
    // The body, four bytes at a time read as a little-endian word.
    for (std::size_t b = 0; b < blocks; ++b) {
        const unsigned char* q = data + 4 * b;
        uint32_t k = static_cast<uint32_t>(q[0]) | static_cast<uint32_t>(q[1]) << 8 |
                     static_cast<uint32_t>(q[2]) << 16 | static_cast<uint32_t>(q[3]) << 24;
        k = rotl32(k * c1, 15) * c2;
        h = rotl32(h ^ k, 13) * 5u + 0xe6546b64u;
    }
    // The last one to three bytes.
    const unsigned char* tail = data + 4 * blocks;
    uint32_t k = 0;
    switch (len & 3u) {
        case 3:
            k ^= static_cast<uint32_t>(tail[2]) << 16;
            [[fallthrough]];
        case 2:
            k ^= static_cast<uint32_t>(tail[1]) << 8;
            [[fallthrough]];
        case 1:
            k ^= tail[0];
            h ^= rotl32(k * c1, 15) * c2;
            break;
        default:
            break;
    }
    return fmix32(h ^ static_cast<uint32_t>(len));
}

float cryptomatte_id(std::string_view name) {
    const uint32_t h = murmur3_32(name);
    // Clamping the exponent keeps every id a normal, finite float (specification, "Floating
    // point conversion"); the sign and mantissa are the hash's own.
    const uint32_t exponent = std::clamp((h >> 23) & 0xffu, 1u, 254u);
    const uint32_t bits = (h & 0x807fffffu) | (exponent << 23);
    float f;
    std::memcpy(&f, &bits, sizeof(f));
    return f;
}

std::string cryptomatte_hex(float id) {
    uint32_t bits;
    std::memcpy(&bits, &id, sizeof(bits));
    return fmt::format("{:08x}", bits);
}

std::string cryptomatte_key(std::string_view layer) {
    return fmt::format("{:08x}", murmur3_32(layer)).substr(0, 7);
}

std::string cryptomatte_manifest(const std::vector<std::string>& names) {
    std::vector<std::string> seen;
    std::string out = "{";
    for (const std::string& n : names) {
        if (std::find(seen.begin(), seen.end(), n) != seen.end()) continue;
        seen.push_back(n);
        if (seen.size() > 1) out += ",";
        out += json_string(n) + ":\"" + cryptomatte_hex(cryptomatte_id(n)) + "\"";
    }
    return out + "}";
}

}  // namespace spangle
