#pragma once
// Counter-based random numbers: every random number is a pure function of integers (seed, pixel,
// sample, dimension), so images are identical on any thread count and flakes never need storing.

#include <cstdint>
#include <string_view>

namespace spangle {

/** 64-bit finaliser with full avalanche (the "mix13" constants of Stafford's variant 13). */
constexpr uint64_t mix64(uint64_t x) {
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    x ^= x >> 31;
    return x;
}

/** Hash of two 64-bit words; order matters. */
constexpr uint64_t hash2(uint64_t a, uint64_t b) {
    return mix64(mix64(a + 0x9e3779b97f4a7c15ull) ^ (b + 0x632be59bd9b4e019ull));
}

/** Hash of four words. */
constexpr uint64_t hash4(uint64_t a, uint64_t b, uint64_t c, uint64_t d) {
    return hash2(hash2(a, b), hash2(c, d));
}

/** Hash of text: FNV-1a over its bytes, then mix64. */
constexpr uint64_t hash_text(std::string_view s) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (const char c : s) h = (h ^ static_cast<unsigned char>(c)) * 0x100000001b3ull;
    return mix64(h);
}

/** Uniform float in [0, 1) from the top 24 bits of h: never returns 1.0f. */
constexpr float to_unit_float(uint64_t h) {
    return static_cast<float>(h >> 40) * 0x1p-24f;
}

/** Uniform double in [0, 1) from the top 53 bits of h. */
constexpr double to_unit_double(uint64_t h) {
    return static_cast<double>(h >> 11) * 0x1p-53;
}

/** The random number for one path: a pure function of (seed, pixel, sample, dimension). */
constexpr float sample_1d(uint64_t seed, uint64_t pixel, uint64_t sample, uint32_t dimension) {
    return to_unit_float(hash4(seed, pixel, sample, dimension));
}

}  // namespace spangle
