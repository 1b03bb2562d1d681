#pragma once
// The denoiser: Intel Open Image Denoise (OIDN 2, its C API), opened with dlopen when a render
// asks for it, so that Spangle builds and runs without it (docs/denoise.md).
//
// The glints apart: the beauty minus its glints layer (the light that came through a glint at
// the first surface) is denoised with the albedo and normal layers as guides (each guide
// filtered first, so that their own noise is not taken for detail); the glints layer is added
// back as rendered (or denoised on its own: GlintDenoise::Apart). A glint then stays the point
// it was rendered as, with its colour and brightness, instead of a blot the denoiser made.
//
// Where the library is looked for, in order: $SPANGLE_OIDN (the library file, or a folder
// holding it or lib/ with it), /opt/spangle/oidn/lib (where scripts/install-deps.sh unpacks it
// from the `pyoidn` wheel on PyPI), then the system's libOpenImageDenoise.so.2.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"

namespace spangle {

/** Whether the denoiser can run; when it cannot, `why` (if given) says what was tried. */
bool denoiser_available(std::string* why = nullptr);

/** How the glints are treated. */
enum class GlintDenoise {
    Apart,   ///< the glints layer filtered on its own, then added
    Keep,    ///< the glints layer passes through unfiltered (the default)
    Filter,  ///< the whole beauty is filtered, glints and all (for comparison)
};

/** The treatment a name says, as --denoise-glints and Python's denoise_glints take them ("keep",
 *  "apart", "filter"); none for another name. */
inline std::optional<GlintDenoise> glint_denoise_named(std::string_view name) {
    if (name == "keep") return GlintDenoise::Keep;
    if (name == "apart") return GlintDenoise::Apart;
    if (name == "filter") return GlintDenoise::Filter;
    return std::nullopt;
}

/** A render's image and layers, as the denoiser reads and writes them. */
struct DenoiseImage {
    std::vector<float>* image;              ///< RGB per pixel: replaced by the denoised beauty
    std::vector<float>* layers;             ///< layer_names per pixel: noisy.R/G/B added
    std::vector<std::string>* layer_names;  ///< must hold albedo.*, N.* and glints.*
    uint32_t width, height;                 ///< pixels
};

/** Images narrower or lower than this are not filtered (a 1-pixel strip came out at 0.2-1.2x
 *  its mean: the network needs neighbours). */
constexpr uint32_t kMinDenoiseSide = 8;

/** How far a denoise is, and whether to stop it (each may be empty). */
struct DenoiseControl {
    std::function<void(double fraction)> progress;  ///< 0 to 1, from the thread denoising
    std::function<bool()> stop;                     ///< polled; true: stop (DenoiseStopped)
};

/** Thrown by denoise() when its control's stop said so: the image is left as rendered (without
 *  a `noisy` layer). Needs a library that reports progress (OIDN 2 does). */
struct DenoiseStopped : SpangleError {
    DenoiseStopped() : SpangleError("denoising was stopped") {}
};

/** Denoises `im` in place: its image becomes the denoised beauty and its noisy beauty is kept
 *  as the layer `noisy` (added after the others). Pixels no camera ray covered (layer `A` 0)
 *  keep their rendered value (the denoiser spread light into them: a fringe in a composite).
 *  `threads`: 0 = all cores. Returns false, the image as rendered (and its `noisy` copy), when
 *  it is below kMinDenoiseSide pixels either way. Throws SpangleError when the library cannot
 *  be opened, a guide layer is missing or OIDN fails. */
bool denoise(DenoiseImage im, GlintDenoise glints, int threads, const DenoiseControl& control = {});

struct Logger;
struct RenderOptions;
struct RenderStats;

/** The control a render's denoise runs under: `o`'s stop, and its work progress as
 *  "denoising" (`o` must outlive it). */
DenoiseControl denoise_control(const RenderOptions& o);

/** denoise() with its outcome recorded in `st`: denoised (mark_denoised), too small to denoise
 *  (warned through `log`; written as rendered), or stopped by the control (st.denoise_stopped,
 *  the image as rendered: the caller says so). */
void denoise_and_record(DenoiseImage im, GlintDenoise glints, int threads,
                        const DenoiseControl& control, const Logger& log, RenderStats& st);

/** What to warn when denoise() returned false. */
inline std::string not_denoised_warning(uint32_t width, uint32_t height) {
    return "--denoise: a " + std::to_string(width) + "x" + std::to_string(height) +
           " image is too small to denoise (at least " + std::to_string(kMinDenoiseSide) +
           " pixels each way): written as rendered";
}

}  // namespace spangle
