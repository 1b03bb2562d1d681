#pragma once
// Low-discrepancy samples that are pure functions of (seed, pixel, sample index, dimension):
// Owen-scrambled Sobol points, two dimensions at a time, with the sample index shuffled per
// dimension pair so that pairs are decorrelated (Burley 2020, "Practical Hash-based Owen
// Scrambling"; the hash-based nested uniform scramble of Laine and Karras 2011). The same pixel
// gets the same points on any thread, so images do not depend on the thread count.

#include <cstdint>

#include "core/hash.h"

namespace spangle {

constexpr uint32_t reverse_bits(uint32_t x) {
    x = __builtin_bswap32(x);  // one instruction for the byte order; then the bits of each byte
    x = ((x & 0x0f0f0f0fu) << 4) | ((x & 0xf0f0f0f0u) >> 4);
    x = ((x & 0x33333333u) << 2) | ((x & 0xccccccccu) >> 2);
    return ((x & 0x55555555u) << 1) | ((x & 0xaaaaaaaau) >> 1);
}

/** A hash-based permutation that is an Owen scramble when applied to bit-reversed values. */
constexpr uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

/** Owen scramble of a 32-bit fixed-point value in [0, 1). */
constexpr uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
    return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

/** First Sobol dimension: the van der Corput sequence. */
constexpr uint32_t sobol_0(uint32_t i) {
    return reverse_bits(i);
}

/** Second Sobol dimension (primitive polynomial x + 1): direction numbers v_1 = 2^31,
 *  v_k = v_{k-1} ^ (v_{k-1} >> 1). Bit-serial reference version. */
constexpr uint32_t sobol_1_reference(uint32_t i) {
    uint32_t v = 0x80000000u, r = 0;
    for (; i; i >>= 1, v ^= v >> 1)
        if (i & 1u) r ^= v;
    return r;
}

namespace detail {
/** XOR of the direction numbers for every value of each of the four bytes of the index. */
struct Sobol1Tables {
    uint32_t t[4][256];
    constexpr Sobol1Tables() : t() {
        uint32_t v[32] = {};
        v[0] = 0x80000000u;
        for (int k = 1; k < 32; ++k) v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        for (int b = 0; b < 4; ++b)
            for (uint32_t x = 0; x < 256; ++x) {
                uint32_t r = 0;
                for (int k = 0; k < 8; ++k)
                    if (x & (1u << k)) r ^= v[8 * b + k];
                t[b][x] = r;
            }
    }
};
inline constexpr Sobol1Tables kSobol1Tables{};
}  // namespace detail

/** Second Sobol dimension, four table lookups. */
inline uint32_t sobol_1(uint32_t i) {
    const auto& t = detail::kSobol1Tables.t;
    return t[0][i & 0xffu] ^ t[1][(i >> 8) & 0xffu] ^ t[2][(i >> 16) & 0xffu] ^ t[3][i >> 24];
}

namespace detail {
/** The same tables bit-reversed (reversal is linear over XOR, so entry by entry). */
struct Sobol1ReversedTables {
    uint32_t t[4][256];
    constexpr Sobol1ReversedTables() : t() {
        for (int b = 0; b < 4; ++b)
            for (int x = 0; x < 256; ++x) t[b][x] = reverse_bits(kSobol1Tables.t[b][x]);
    }
};
inline constexpr Sobol1ReversedTables kSobol1ReversedTables{};
}  // namespace detail

/** reverse_bits(sobol_1(i)), four table lookups. */
inline uint32_t sobol_1_reversed(uint32_t i) {
    const auto& t = detail::kSobol1ReversedTables.t;
    return t[0][i & 0xffu] ^ t[1][(i >> 8) & 0xffu] ^ t[2][(i >> 16) & 0xffu] ^ t[3][i >> 24];
}

/** Direction numbers of the third Sobol dimension (primitive polynomial x^2 + x + 1, initial
 *  m_1 = 1, m_2 = 3; m_k = 2 m_{k-1} ^ 4 m_{k-2} ^ m_{k-2}), v_k = m_k 2^(32 - k). */
struct Sobol2Directions {
    uint32_t v[32];
    constexpr Sobol2Directions() : v() {
        uint64_t m[33] = {};
        m[1] = 1;
        m[2] = 3;
        for (int k = 3; k <= 32; ++k) m[k] = (2 * m[k - 1]) ^ (4 * m[k - 2]) ^ m[k - 2];
        for (int k = 1; k <= 32; ++k) v[k - 1] = static_cast<uint32_t>(m[k] << (32 - k));
    }
};
inline constexpr Sobol2Directions kSobol2Directions{};

/** Third Sobol dimension, bit-serial reference version. */
constexpr uint32_t sobol_2_reference(uint32_t i) {
    uint32_t r = 0;
    for (int k = 0; i; i >>= 1, ++k)
        if (i & 1u) r ^= kSobol2Directions.v[k];
    return r;
}

namespace detail {
/** reverse_bits of the third dimension's direction numbers XORed for every value of each byte. */
struct Sobol2ReversedTables {
    uint32_t t[4][256];
    constexpr Sobol2ReversedTables() : t() {
        for (int b = 0; b < 4; ++b)
            for (uint32_t x = 0; x < 256; ++x) {
                uint32_t r = 0;
                for (int k = 0; k < 8; ++k)
                    if (x & (1u << k)) r ^= kSobol2Directions.v[8 * b + k];
                t[b][x] = reverse_bits(r);
            }
    }
};
inline constexpr Sobol2ReversedTables kSobol2ReversedTables{};
}  // namespace detail

/** reverse_bits(sobol_2_reference(i)), four table lookups. */
inline uint32_t sobol_2_reversed(uint32_t i) {
    const auto& t = detail::kSobol2ReversedTables.t;
    return t[0][i & 0xffu] ^ t[1][(i >> 8) & 0xffu] ^ t[2][(i >> 16) & 0xffu] ^ t[3][i >> 24];
}

/** 24-bit fixed point to float in [0, 1). */
constexpr float fixed_to_unit(uint32_t x) {
    return static_cast<float>(x >> 8) * 0x1p-24f;
}

/** The key of one pixel's sequences, hashed once per path: (seed, pixel). */
constexpr uint64_t sobol_pixel_key(uint64_t seed, uint64_t pixel) {
    return hash2(seed, pixel);
}

namespace detail {
/** One dimension set's index shuffle and scramble hash, shared by its dimensions: one 64-bit hash
 *  per set gives the shuffle's seed and each dimension's scramble seed. */
struct SobolSet {
    uint32_t shuffled;
    uint64_t h;
    uint32_t seed(uint64_t multiplier) const {
        return static_cast<uint32_t>((h * multiplier) >> 32);
    }
};
inline SobolSet sobol_set(uint64_t key, uint32_t index, uint32_t set) {
    const uint64_t h = mix64(key ^ (static_cast<uint64_t>(set) + 1) * 0x9e3779b97f4a7c15ull);
    return {nested_uniform_scramble(index, static_cast<uint32_t>(h)), h};
}
/** A dimension's value from its bit-reversed Sobol value: nested_uniform_scramble(x) =
 *  reverse(permutation(reverse(x))), so with reversed Sobol values two reversals per dimension
 *  cancel (sobol_0(i) = reverse(i): its reversed value is the index itself). */
inline float scrambled(uint32_t reversed, uint32_t seed) {
    return fixed_to_unit(reverse_bits(laine_karras_permutation(reversed, seed)));
}
}  // namespace detail

/** The 2D point for sample `index` of the pixel whose key is `key`, in dimension pair `pair`. */
inline void sobol_2d_keyed(uint64_t key, uint32_t index, uint32_t pair, float& u0, float& u1) {
    const detail::SobolSet s = detail::sobol_set(key, index, pair);
    u0 = detail::scrambled(s.shuffled, s.seed(1));
    u1 = detail::scrambled(sobol_1_reversed(s.shuffled), s.seed(0xd1342543de82ef95ull));
}

/** The 3D point for sample `index` of the pixel whose key is `key`, in dimension set `set`: the
 *  first three Sobol dimensions under one index shuffle, each Owen-scrambled by its own seed.
 *  (u0, u1) is sobol_2d_keyed's point of the same number; u2 is stratified jointly with them
 *  (the three dimensions form a (1, 3)-sequence), so that a choice made with u2 (a BSDF lobe, a
 *  light) leaves the samples that make the same choice stratified in (u0, u1). */
inline void sobol_3d_keyed(uint64_t key, uint32_t index, uint32_t set, float& u0, float& u1,
                           float& u2) {
    const detail::SobolSet s = detail::sobol_set(key, index, set);
    u0 = detail::scrambled(s.shuffled, s.seed(1));
    u1 = detail::scrambled(sobol_1_reversed(s.shuffled), s.seed(0xd1342543de82ef95ull));
    u2 = detail::scrambled(sobol_2_reversed(s.shuffled), s.seed(0xaf251af3b0f025b5ull));
}

/** The 2D point for sample `index` of `pixel` in dimension pair `pair`. */
inline void sobol_2d(uint64_t seed, uint64_t pixel, uint32_t index, uint32_t pair, float& u0,
                     float& u1) {
    sobol_2d_keyed(sobol_pixel_key(seed, pixel), index, pair, u0, u1);
}

}  // namespace spangle
