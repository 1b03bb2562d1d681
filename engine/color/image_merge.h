#pragma once
// Assembling a frame from crop-window renders (spangle render --crop): each part is an EXR whose
// data window is its part of the full frame (the display window). Every pixel of a crop is the
// whole render's pixel bit for bit (its samples depend on the pixel alone), so the merged image
// equals the whole render.

#include <string>
#include <vector>

namespace spangle {

/** What merge_exr_parts did. */
struct MergeReport {
    int width = 0, height = 0;  ///< the full frame
    std::size_t parts = 0;
    std::size_t overlap_pixels = 0;  ///< pixels more than one part held (with equal values)
    std::size_t sample_ranges = 0;   ///< --spp-range parts added up (0: crop windows placed)
    /** Parts a stop signal cut short (spangle:partial): the merged image is partial too. */
    std::vector<std::string> partial_parts;
    /** Values of R, G and B in the merged crop windows that are infinite (a half float's
     *  overflow, beyond 65504) or NaN (a render writes none: a part another program changed). */
    std::size_t infinite = 0, nan = 0;
};

/** Reads every part, checks they describe the same frame (display window, channels and their
 *  types, spangle:spp) and together cover every pixel (where two overlap, their values must be
 *  equal), and writes the full frame to `out` (header of the first part, data window = display
 *  window; whole or not at all). Throws SpangleError naming the file at fault. */
MergeReport merge_exr_parts(const std::vector<std::string>& parts, const std::string& out);
// Parts rendered with --spp-range (samples [A, B) of the same window) are added instead: each
// carries its samples' exact fixed-point sums (UINT channels), and the sums of ranges that
// cover the frame's samples 0..spp-1 once add up to the whole render's sums, whose mean is the
// whole render's image bit for bit. The output has R, G, B only.

}  // namespace spangle
