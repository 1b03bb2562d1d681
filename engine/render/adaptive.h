#pragma once
// Adaptive sampling: every pixel stops taking samples once its own samples say that its value is
// known to the noise threshold (docs/adaptive.md).
//
// The estimate of a pixel's error comes from four interleaved quarter-sums of its samples (the
// sample numbers modulo 4): the spread of their means estimates the standard error of the mean
// with three degrees of freedom (two half-sums give one, and a noisy pixel whose one-degree
// estimate comes out small by chance stops far too early: about one in four at a true error of
// three times the threshold, against one in twenty with three). A
// pixel is looked at only at fixed checkpoints (sample counts that depend on min_spp alone) and
// stops after two checkpoints in a row within the threshold (the first look is at half of
// min_spp, so that a flat pixel stops at min_spp). Within the threshold means: the pixel and
// each of its 3 x 3 neighbours inside its 16 x 16 tile of the frame (a pixel that saw a rare
// bright path keeps its neighbours, which have not seen theirs yet, sampling).
//
// Because a decision reads only the pixel's tile, and each pixel's samples depend on the pixel
// alone, the samples a pixel receives are the same whatever the split of the work: threads,
// progressive passes, crop windows and MPI bands give the whole render's pixels bit for bit. A
// crop window is rendered as the whole tiles it meets (at most 15 pixels more on a side) and
// cut down to the window.
//
// Glints are signal: the part of a pixel that came through a glint (the glints layer) is judged
// apart from the rest. The rest must reach the threshold as a relative error of the pixel (as
// the relMSE metric measures it, with 0.1 as the floor of dark pixels); the glint part must know
// its own brightness to ten times the threshold relative to itself (at most 50%), or be below the
// threshold relative to the pixel. So a bright sparkle neither keeps its pixel sampling until its
// absolute noise is that of a dull pixel, nor lets the pixel stop while the glint was seen in one
// quarter of the samples only (the quarters then differ by all of it).

#include <cstdint>
#include <string>
#include <vector>

#include "core/sample_sum.h"
#include "render/render_options.h"
#include "scene/components.h"

namespace spangle {

/** Adaptive sampling's settings, resolved from the scene's film and the options. */
struct AdaptivePlan {
    float threshold = 0.0f;  ///< the relative standard error a pixel stops at; 0: off
    uint32_t min_spp = 0;    ///< samples every pixel takes (a multiple of 4)
    uint32_t max_spp = 0;    ///< samples no pixel goes beyond (the render's spp)
    bool on() const { return threshold > 0.0f; }
};

/** The plan for `film` under `options` (its overrides); off when the threshold is 0. Throws
 *  SpangleError for min_spp above max_spp. */
AdaptivePlan adaptive_plan(const Film& film, const RenderOptions& options);

/** Whether a render of `film` under `options` samples adaptively. */
bool adaptive_on(const Film& film, const RenderOptions& options);

/** Why --spp-range cannot split `render` (an adaptive render, named as the caller knows it:
 *  "an adaptive render (--noise-threshold)"), for every place that refuses it. */
std::string spp_range_refusal(const std::string& render);

/** The first checkpoint after `samples`: half of min_spp (rounded down to a multiple of 4,
 *  when at least 4), min_spp, then every max(8, c / 8) samples (a multiple of 4), capped at
 *  max_spp. A pixel stops at a checkpoint from min_spp on, after two in a row within the
 *  threshold. */
uint32_t next_checkpoint(const AdaptivePlan& plan, uint32_t samples);

/** Per pixel of the image: the samples taken, the quarter-sums of sample numbers 1, 2 and 3
 *  modulo 4 (beauty RGB, glints RGB each; the quarter of 0 is the total less them), checkpoints
 *  in a row within the threshold, and whether it still takes samples. */
struct AdaptiveFilm {
    static constexpr std::size_t kParts = 18;  ///< floats per pixel in `parts`
    std::vector<uint32_t> count;               ///< samples taken
    std::vector<float> parts;      ///< kParts per pixel: quarters 1..3, beauty then glint RGB
    std::vector<float> ratio;      ///< its error over the threshold at its last checkpoint
    std::vector<uint8_t> strikes;  ///< checkpoints in a row within the threshold
    std::vector<uint8_t> active;   ///< 1: takes more samples
    /** Sized for `pixels`, every pixel active with no samples. */
    void reset(std::size_t pixels);
};

/** What pixel `p`'s error estimate reads: the film's sums and the layers' glint sums. */
struct PixelSums {
    const SampleSum* beauty;  ///< RGB sums of all its samples
    const float* glints;      ///< RGB sums of its glint parts (null: no glints layer)
    const float* parts;       ///< AdaptiveFilm::parts of the pixel
    uint32_t samples;         ///< samples taken (a multiple of 4)
    /** RGB sums of the environment it saw directly, when the background layer keeps that out
     *  of the beauty (null otherwise): judged as part of the pixel. */
    const float* background = nullptr;
};

/** The pixel's error over what the plan allows (<= 1: within the threshold). */
float adaptive_error(const AdaptivePlan& plan, const PixelSums& s);

}  // namespace spangle
