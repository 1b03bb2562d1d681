#pragma once
// Measurements of a rendered image, for `spangle inspect` and the tests.

#include <array>
#include <cstdint>
#include <vector>

#include "core/math.h"

namespace spangle {

/** Summary of an RGB image. */
struct ImageMetrics {
    double mean_luminance = 0.0;
    uint64_t nonfinite = 0;         ///< pixels with a NaN or infinite channel
    uint64_t negative = 0;          ///< pixels with a negative channel
    uint64_t fireflies = 0;         ///< outliers that are not glints (all, without glints)
    double firefly_fraction = 0.0;  ///< fireflies / pixels
    uint64_t glints = 0;            ///< outliers whose light came mostly through a glint
    bool told_apart = false;        ///< a glints layer told glints from fireflies
};

/** Luminance of linear Rec.709 RGB (the Y row of its RGB to XYZ matrix). */
inline constexpr std::array<double, 3> kRec709Luma = {kRec709YDouble[0], kRec709YDouble[1],
                                                      kRec709YDouble[2]};

/** Measures width x height RGB (luminance by `luma`, the weights of the image's primaries). An
 * outlier is a pixel whose luminance exceeds `ratio` times the median luminance of its 3x3
 * neighbourhood (itself included), and exceeds `floor` (so that noise in black regions does not
 * count). With `glints` (the glints layer, RGB per pixel), an outlier at least half of whose
 * luminance came through a glint is a glint -- a flake mirroring a light, which is meant to stand
 * out -- and the others are fireflies; without it every outlier counts as a firefly. */
ImageMetrics measure_image(const std::vector<float>& rgb, int width, int height,
                           double ratio = 10.0, double floor = 1e-3,
                           const std::vector<float>* glints = nullptr,
                           const std::array<double, 3>& luma = kRec709Luma);

/** relMSE of `image` against `reference` (the same size): the mean over pixels and channels of
 *  (x - r)^2 / (r^2 + 0.01), the 0.01 keeping dark pixels from dominating. */
double relative_mse(const std::vector<float>& image, const std::vector<float>& reference);

}  // namespace spangle
