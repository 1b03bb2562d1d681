#pragma once
// The pixel filters a scene can name. The scene reader checks the name; the camera samples the
// filter (render/camera.h).

#include <string>

namespace spangle {

/** Pixel filters; each is separable, f(x, y) = g(x) g(y), and non-negative. */
enum class FilterKind { Box, Gaussian, BlackmanHarris };

/** Parses "box", "gaussian" or "blackman-harris"; false for anything else. */
bool parse_filter(const std::string& name, FilterKind& out);

}  // namespace spangle
