#pragma once
// What a flake reflects: its Fresnel reflectance against the cosine at the flake (conductor
// preset, dielectric or Schlick), and the colour table flakes draw their tint from (hues of an
// HSL wheel converted to the working space through the scene's OCIO config, biased towards the
// base colour's hue). The discrete and the smooth lobe read the same tables, so the smooth lobe's
// colour and Fresnel are exactly the discrete lobe's expectation.

#include <spangle/plugin.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "../common/plugin_support.h"
#include "field.h"

namespace spangle::flake {

/** RGB Fresnel reflectance of a flake against cos(theta) at the flake, working space, linearly
 *  interpolated between kNodes nodes at cos = i / (kNodes - 1). */
struct FresnelTable {
    static constexpr int kNodes = 257;
    float rgb[kNodes][3] = {};
    /** Reflectance at cos_theta (clamped to [0, 1]). */
    void eval(float cos_theta, float out[3]) const {
        const float x = std::clamp(cos_theta, 0.0f, 1.0f) * static_cast<float>(kNodes - 1);
        const int i = std::min(static_cast<int>(x), kNodes - 2);
        const float f = x - static_cast<float>(i);
        for (int c = 0; c < 3; ++c) out[c] = rgb[i][c] + f * (rgb[i + 1][c] - rgb[i][c]);
    }
    /** Luminance of the reflectance at normal incidence. */
    float normal_luminance() const;
};

/** Builds the table from the parameters `fresnel`, `preset`, `flake_ior`, `flake_f0`. Returns
 *  false and sets `why` when the working space cannot be reached. */
bool build_fresnel(FresnelTable& t, const SpangleParams_v3* p, const SpangleHost_v3* host,
                   std::string& why);

/** The tint of flakes: one colour (table off), or a table of hues with a probability each. */
struct ColorTable {
    static constexpr int kGuide = 256;
    std::vector<float> rgb;       ///< entries, working space, 3 floats each (empty: table off)
    std::vector<float> cdf;       ///< cumulative probabilities of the entries
    std::vector<uint16_t> guide;  ///< first entry whose cdf exceeds b / kGuide, per bucket b
    float single[3] = {1, 1, 1};  ///< the colour when the table is off
    float mean[3] = {1, 1, 1};    ///< expected flake colour (the variation's mean included)
    /** Varied colours a flake may take: kVariants per entry (one entry, `single`, when the table
     *  is off), 3 floats each, entry-major (empty: no hue, saturation or value variation). */
    static constexpr uint32_t kVariants = 256;
    std::vector<float> varied;
    /** The entry picked by a uniform number in [0, 1): the first whose cdf exceeds it (the guide
     *  table starts the search in u's bucket, so it is O(1) on average); 0 when the table is off.
     */
    std::size_t index(float u) const {
        if (cdf.empty()) return 0;
        const int b = std::min(static_cast<int>(u * kGuide), kGuide - 1);
        std::size_t k = guide[static_cast<std::size_t>(b)];
        while (k + 1 < cdf.size() && cdf[k] <= u) ++k;
        return k;
    }
    /** Whether flakes differ in colour (a table or variation); else every flake is `single`. */
    bool varies() const { return !cdf.empty() || !varied.empty(); }
    /** The colour picked by a uniform number in [0, 1), without variation. */
    const float* pick(float u) const { return cdf.empty() ? single : &rgb[3 * index(u)]; }
    /** The colour of the flake whose own hash is `id` and whose colour number is u: its entry,
     *  varied by the variant its hash selects (each of the kVariants equally likely). */
    const float* pick(float u, uint64_t id) const {
        if (varied.empty()) return pick(u);
        const auto v = static_cast<std::size_t>(mix(id, 0xc0107) >> 56);
        return &varied[3 * (index(u) * kVariants + v)];
    }
};

/** Builds the table from `flake_color`, `color_table`, `table_size`, `table_s`, `table_l`,
 *  `table_space` and `hue_spread` (the bias towards base_rgb's hue, base_rgb in the working
 *  space), and its variants from `hue_variation`, `saturation_variation` and `value_variation`.
 *  Returns false and sets `why` on a colour-management failure. */
bool build_colors(ColorTable& t, const float base_rgb[3], const SpangleParams_v3* p,
                  const SpangleHost_v3* host, std::string& why);

/** Rec.709 luminance weights (the tables are in the working space; the weights only steer
 *  sampling, so any fixed positive weights are correct). */
using plugin_support::rec709_luminance;
inline float luminance(const float c[3]) {
    return rec709_luminance(c);
}

}  // namespace spangle::flake
