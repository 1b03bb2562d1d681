#pragma once
// Exact sums of sample values. The film adds each sample as a 128-bit fixed-point number (a
// quantum of 2^-40), and integer addition is associative: any split of a pixel's samples -- into
// passes, into --spp-range parts rendered on different machines -- adds up to the same bits in
// any order, so a merge of parts is the whole render exactly. Float sums are not: (a + b) + c
// differs from a + (b + c) in the last bits.
//
// Range: a sample value is clamped to +-2^60 (beyond any radiance a scene makes); 2^20 samples
// of that stay below 2^120 < 2^127. Precision: 2^-40 (~1e-12) per sample, far below a float's
// at any value a pixel shows.

#include <cmath>
#include <cstdint>

namespace spangle {

__extension__ typedef __int128 SampleSum;

/** One sample value as a fixed-point addend (round to nearest; NaN counts as 0). */
inline SampleSum to_sample_sum(float x) {
    constexpr float kMax = 0x1p60f;
    if (!(x == x)) return 0;
    x = x > kMax ? kMax : (x < -kMax ? -kMax : x);
    const float y = std::nearbyint(x * 0x1p40f);
    // Values below 2^63 (radiance below 2^23: all but the brightest samples) through a 64-bit
    // integer, one instruction; a float's conversion to 128 bits is a libgcc call.
    if (std::fabs(y) < 0x1p63f) return static_cast<int64_t>(y);
    return static_cast<SampleSum>(y);
}

/** The mean of `count` samples whose fixed-point sum is `s` (0 when count is 0). */
inline float sample_mean(SampleSum s, uint64_t count) {
    if (count == 0) return 0.0f;
    return static_cast<float>(static_cast<double>(s) * 0x1p-40 / static_cast<double>(count));
}

/** The four 32-bit words of a sum, least significant first (for EXR UINT channels), and back. */
inline void sample_sum_words(SampleSum s, uint32_t w[4]) {
    __extension__ typedef unsigned __int128 U;
    const U u = static_cast<U>(s);
    for (int i = 0; i < 4; ++i) w[i] = static_cast<uint32_t>(u >> (32 * i));
}
inline SampleSum sample_sum_from_words(const uint32_t w[4]) {
    __extension__ typedef unsigned __int128 U;
    U u = 0;
    for (int i = 3; i >= 0; --i) u = (u << 32) | w[i];
    return static_cast<SampleSum>(u);
}

}  // namespace spangle
