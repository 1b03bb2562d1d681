#pragma once
// How much glitter flickers in a rendered sequence: each frame's glints are carried into the
// next frame through the surface points they lie on and compared there. A point is carried by
// its object (the Pobj and object layers and the next frame's spangle:objectToWorld placements,
// so a turning object is followed) and projected with the next frame's worldToNDC matrix, all
// written by `spangle render --layers`; frames without the object layers use the world P layer
// (right for a moving camera only). A deforming object's points (spangle:restPose: its Pobj is
// the rest pose's position) are found where the next frame shows the same rest position.
// Glints that are fixed to the surface land on glints; a per-frame random realisation does not.

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

}  // namespace spangle
