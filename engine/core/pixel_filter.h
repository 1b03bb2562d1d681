#pragma once
// The pixel filters a scene can name, their shape, and how a filter shares samples between
// pixels. The scene reader checks the name; the camera samples the filter (render/camera.h);
// with filter_samples = "shared" the film's pixel means are spread by spread_pixels().

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace spangle {

/** Pixel filters; each is separable, f(x, y) = g(x) g(y), and non-negative. */
enum class FilterKind { Box, Gaussian, BlackmanHarris };

/** Parses "box", "gaussian" or "blackman-harris"; false for anything else. */
bool parse_filter(const std::string& name, FilterKind& out);

/** The 1D filter g(x) on [-radius, radius], not normalised. */
double filter_value(FilterKind kind, double x, double radius);

/** The radius of a filter whose scene gives none (0): box 0.5, Gaussian 1.5, Blackman-Harris 2
 *  pixels. */
float default_filter_radius(FilterKind kind);

/** filter_samples = "shared": the weights by which a pixel's mean reaches the pixels at offsets
 *  -r..r along one axis (2r + 1 of them), summing to 1, as wide as the filter: the pixel's own
 *  samples spread over it (a box, variance 1/12), so the weights are the filter narrowed until
 *  their variance and 1/12 add up to the filter's, integrated over each pixel. {1} for a filter
 *  no wider than its pixel (a box of radius 0.5). */
std::vector<double> spread_weights(FilterKind kind, float radius);

/** Pixels [x0, x1) x [y0, y1) of the frame. */
struct PixelRect {
    uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

/** Spreads pixel means by `weights` (spread_weights(), the same along both axes): each pixel of
 *  `to` becomes the weighted mean of the pixels around it that lie in `have`, the weights of those
 *  outside left out and the rest renormalised. `values` holds `channels` values per pixel of
 *  `have`, row-major; only the channels whose `spread` entry is true change, and only in `to`
 *  (inside `have`). A pixel's result depends only on the values of its neighbours in `have`, in
 *  a fixed order: a window whose `have` holds every neighbour in the frame gives the whole
 *  frame's bits. */
void spread_pixels(float* values, std::size_t channels, const std::vector<bool>& spread,
                   const PixelRect& have, const PixelRect& to, const std::vector<double>& weights);

}  // namespace spangle
