#include "render/image_metrics.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace spangle {

ImageMetrics measure_image(const std::vector<float>& rgb, int width, int height, double ratio,
                           double floor, const std::vector<float>* glints,
                           const std::array<double, 3>& luma) {
    ImageMetrics m;
    m.told_apart = glints != nullptr;
    const auto n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    std::vector<double> lum(n, 0.0);
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double r = rgb[3 * i], g = rgb[3 * i + 1], b = rgb[3 * i + 2];
        if (!std::isfinite(r) || !std::isfinite(g) || !std::isfinite(b)) {
            ++m.nonfinite;
            continue;
        }
        if (r < 0 || g < 0 || b < 0) ++m.negative;
        lum[i] = luma[0] * r + luma[1] * g + luma[2] * b;
        sum += lum[i];
    }
    // Over the finite pixels (a non-finite one counted as black pulled the mean down, where the
    // channels' own means leave it out).
    const std::size_t finite = n - m.nonfinite;
    m.mean_luminance = finite ? sum / static_cast<double>(finite) : 0.0;
    std::array<double, 9> window{};
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            std::size_t k = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int xx = std::clamp(x + dx, 0, width - 1),
                              yy = std::clamp(y + dy, 0, height - 1);
                    window[k++] =
                        lum[static_cast<std::size_t>(yy) * static_cast<std::size_t>(width) +
                            static_cast<std::size_t>(xx)];
                }
            std::nth_element(window.begin(), window.begin() + 4, window.end());
            const double v = lum[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                                 static_cast<std::size_t>(x)];
            if (!(v > floor && v > ratio * window[4])) continue;
            const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                                  static_cast<std::size_t>(x);
            double g = 0.0;
            if (glints)
                g = luma[0] * static_cast<double>((*glints)[3 * i]) +
                    luma[1] * static_cast<double>((*glints)[3 * i + 1]) +
                    luma[2] * static_cast<double>((*glints)[3 * i + 2]);
            if (g >= 0.5 * v)
                ++m.glints;
            else
                ++m.fireflies;
        }
    m.firefly_fraction = n ? static_cast<double>(m.fireflies) / static_cast<double>(n) : 0.0;
    return m;
}

double relative_mse(const std::vector<float>& image, const std::vector<float>& reference) {
    double sum = 0.0;
    for (std::size_t i = 0; i < image.size(); ++i) {
        const double x = image[i], r = reference[i];
        sum += (x - r) * (x - r) / (r * r + 0.01);
    }
    return image.empty() ? 0.0 : sum / static_cast<double>(image.size());
}

}  // namespace spangle
