// The options of `spangle render` and what follows from them alone: see render_args.h.

#include "cli/render_args.h"

#include <unistd.h>

#include "cli/arguments.h"
#include "cli/progress.h"
#include "cli/usage.h"

namespace spangle {

RenderOptions render_options(const RenderArgs& a) {
    RenderOptions o;
    o.threads = a.threads;
    o.camera = a.camera;
    o.environment = a.environment;
    o.spp_override = a.spp;
    o.noise_threshold_override = static_cast<float>(a.noise_threshold);
    o.min_spp_override = a.min_spp;
    o.max_spp_override = a.max_spp;
    o.texture_cache = a.texture_cache;
    o.layers = a.layers || a.denoise;  // the denoiser's guides and the glints are layers
    // With the layers (--layers, or --denoise's) the beauty is premultiplied by its alpha: the
    // environment seen directly goes to a layer of its own (with --denoise alone the sky was in
    // RGB where A said 0, and in every light group).
    o.background_apart = o.layers;
    o.denoise = a.denoise;
    o.denoise_glints = glint_denoise_named(a.denoise_glints).value_or(GlintDenoise::Keep);
    if (!a.crop.empty()) o.crop = parse_crop(a.crop);
    if (!a.spp_range.empty()) parse_spp_range(a.spp_range, o.spp_first, o.spp_end);
    o.texture_memory_mb = a.texture_memory_mb;
    if (!a.size.empty()) parse_size(a.size, o.width_override, o.height_override);
    // Where the command line itself gives the size (or the samples), a window (or range) outside
    // it is a bad command line, exit 2; against the scene's own size it is said once the scene
    // is loaded.
    if (!a.size.empty() && !o.crop.whole() &&
        !(o.crop.x1 <= o.width_override && o.crop.y1 <= o.height_override))
        usage_error("--crop {} is not inside --size {} (it needs x1 <= width and y1 <= height)",
                    a.crop, a.size);
    if (a.spp > 0 && o.spp_end > a.spp)
        usage_error("--spp-range {} is not inside --spp {} (it needs B <= spp)", a.spp_range,
                    a.spp);
    o.strategy = a.strategy == "nee"    ? Strategy::NeeOnly
                 : a.strategy == "bsdf" ? Strategy::BsdfOnly
                                        : Strategy::Mis;
    if (!a.quiet) o.work_progress = work_meter(::isatty(STDERR_FILENO) != 0);
    return o;
}

Logger render_logger(const RenderArgs& a) {
    Logger log;
    if (a.quiet) log.threshold = LogLevel::Warning;
    return log;
}

}  // namespace spangle
