#pragma once
// How much glitter flickers in a rendered sequence: each frame's glints are carried into the
// next frame through the surface points they lie on and compared there. A point is carried by
// its object (the Pobj and object layers and the next frame's spangle:objectToWorld placements,
// so a turning object is followed) and projected with the next frame's worldToNDC matrix, all
// written by `spangle render --layers`; frames without the object layers use the world P layer
// (right for a moving camera only). A deforming object's points (spangle:restPose: its Pobj is
// the rest pose's position) are found where the next frame shows the same rest position.
// Glints that are fixed to the surface land on glints; a per-frame random realisation does not.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace spangle {

/** What measure_flicker found over a sequence. */
struct FlickerReport {
    std::size_t pairs = 0;           ///< consecutive frame pairs compared
    double pixels = 0;               ///< reprojected pixels compared (visible in both frames)
    double threshold = 0;            ///< glint-mask threshold (glint layer luminance)
    double mask_flicker = 0;         ///< mean |mask_k - mask_k+1| over compared pixels
    double mask_fraction = 0;        ///< mean mask coverage (for scale: flicker <= 2 x this)
    double relative_difference = 0;  ///< mean |g_k - g_k+1| / mean g over compared pixels
    double mask_persistence = 0;     ///< of the glint pixels of frame k, the share still glints
    bool by_objects = false;         ///< points were carried by their objects (Pobj layers)
    bool by_rest = false;     ///< and a deforming object's by its rest position (spangle:restPose)
    bool reordered = false;   ///< the frames were not given in time order: sorted
    std::size_t blurred = 0;  ///< frames rendered with motion blur (spangle:shutter)
    /** Pixels wholly on a surface whose glint luminance is not finite (a half float's infinity:
     *  a glint brighter than 65504), over all frames: left out of every figure. */
    uint64_t nonfinite_glints = 0;
    /** The shortest and longest step between consecutive frames' times (seconds; both 0 where
     *  a frame has no spangle:time): unequal steps mean a frame is missing. */
    double step_min = 0, step_max = 0;
};

/** Reads the frames (EXRs with P.X/Y/Z, Z, A and glints.R/G/B layers and worldToNDC, and
 *  Pobj.X/Y/Z, object and spangle:objectToWorld when they have them), in the order of their
 *  spangle:time when every frame has one (else as given), and measures. A pixel is in a frame's
 *  glint mask when its glint luminance exceeds `threshold` (<= 0: 4 x the mean over covered
 *  pixels of all frames) and 3 x the mean of its 5x5 neighbourhood (a sparkle, not a broad
 *  highlight).
 *  A pixel is compared when its surface point projects inside the next frame and the next frame
 *  sees the same point there (positions within 1% of the depth; the same object), or, on an
 *  object that deforms in both frames, when a pixel of the same object within 8 pixels of
 *  where it projects shows its rest position (within 3/4 of that pixel's size). Throws
 *  SpangleError. */
FlickerReport measure_flicker(const std::vector<std::string>& frames, double threshold = 0.0);

/** Sums over the covered pixels (alpha above 0.999) of glint luminances whose mean sets the
 *  glint detector's threshold when none is given. */
struct GlintMean {
    double sum = 0, count = 0;
    /** Adds an image's covered pixels with a finite glint luminance. */
    void add(const std::vector<float>& glint, const std::vector<float>& alpha);
    /** 4 x the mean (1 when no pixel was covered). */
    double threshold() const { return count > 0.0 ? 4.0 * sum / count : 1.0; }
};

/** The glint detector of `spangle flicker`: 1 for the pixels whose glint luminance (row by row,
 *  width x height) exceeds `threshold` and 3 x the mean of the finite values of its 5x5
 *  neighbourhood (a sparkle; a broad highlight, bright whatever the flakes, is not a glint). */
std::vector<uint8_t> glint_pixels(const std::vector<float>& glint, int width, int height,
                                  double threshold);

/** How many of a reference's glints an image of the same scene keeps (`spangle inspect
 *  --against`). A glint's contrast is its pixel's luminance less the mean of its 8 neighbours; an
 *  image keeps it when its contrast there is at least half the reference's. */
struct GlintsKept {
    std::size_t found = 0;     ///< glint pixels of the reference
    std::size_t border = 0;    ///< of them on the image's border (fewer than 8 neighbours)
    std::size_t faint = 0;     ///< standing out of their neighbours by less than a tenth of
                               ///< their luminance (or not at all) in the reference
    std::size_t measured = 0;  ///< the others: the glints counted
    std::size_t kept = 0;      ///< of the measured, those the image keeps
    double median_ratio = 0;   ///< median of the image's contrast over the reference's
};

/** The reference's glints (`glints`, 1 per glint pixel) that `image` keeps, both luminances of
 *  width x height pixels row by row. A contrast that is not finite in the image keeps nothing.
 *  Throws SpangleError when a vector is not of width x height values. */
GlintsKept glints_kept(const std::vector<float>& image, const std::vector<float>& reference,
                       const std::vector<uint8_t>& glints, int width, int height);

}  // namespace spangle
