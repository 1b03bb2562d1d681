#pragma once
// Values typed on the command line that CLI11 cannot check alone: image sizes, crop windows,
// sample ranges and frame ranges. Each parser throws UsageError (exit status 2) naming the
// option, what it expects and what it got.

#include <cstdint>
#include <string>
#include <utility>

#include "render/render_options.h"

namespace spangle {

/** A pixel count or coordinate: digits only, at most 5 of them (sscanf's "%u" would wrap
 *  4294967312 to 16 and accept trailing junk). False when `t` is not one. */
bool pixel_count(const std::string& t, uint32_t& value);

/** --size WIDTHxHEIGHT (render and bench): each side 1..16384, else a usage error. */
void parse_size(const std::string& size, uint32_t& width, uint32_t& height);

/** --crop x0,y0,x1,y1: four pixel bounds, digits only, x0 < x1 and y0 < y1 (whether the window
 *  lies inside the image is checked once the scene's size is known). */
CropWindow parse_crop(const std::string& text);

/** --spp-range A..B: samples [A, B) of the frame's (0 <= A < B <= 2^20). */
void parse_spp_range(const std::string& text, uint32_t& first, uint32_t& end);

/** --frames A..B or A: frame numbers, A <= B, fewer than a million of them. */
std::pair<int64_t, int64_t> parse_frames(const std::string& text);

}  // namespace spangle
