#pragma once
// Measurements of a rendered image, for `spangle inspect` and the tests.

#include <cstdint>
#include <vector>

namespace spangle {

/** Summary of an RGB image. */
struct ImageMetrics {
    double mean_luminance = 0.0;
    uint64_t nonfinite = 0;         ///< pixels with a NaN or infinite channel
    uint64_t negative = 0;          ///< pixels with a negative channel
    uint64_t fireflies = 0;         ///< pixels brighter than `ratio` x their neighbourhood median
    double firefly_fraction = 0.0;  ///< fireflies / pixels
};

/** Measures width x height RGB. A firefly is a pixel whose luminance exceeds `ratio` times the
 *  median luminance of its 3x3 neighbourhood (itself included), and exceeds `floor` (so that
 *  noise in black regions does not count). */
ImageMetrics measure_image(const std::vector<float>& rgb, int width, int height,
                           double ratio = 10.0, double floor = 1e-3);

}  // namespace spangle
