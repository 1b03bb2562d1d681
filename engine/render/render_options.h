#pragma once
// How a render is asked for (RenderOptions: from the command line, not the scene), what it reports
// as it goes (PassImage) and when it ends (RenderStats), and the film's geometry (crop windows).

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/progress.h"
#include "render/denoise.h"
#include "render/lights.h"

namespace spangle {

/** A crop window in pixels of the full image: [x0, x1) x [y0, y1); x1 == 0: the whole image. */
struct CropWindow {
    uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    bool whole() const { return x1 == 0; }
    bool operator==(const CropWindow&) const = default;
};

/** The pixels `crop` renders of a width x height image (the whole image for whole()); throws
 *  SpangleError when the window is empty or not inside the image. */
CropWindow crop_within(const CropWindow& crop, uint32_t width, uint32_t height);

/** Where a (cropped) image lies in the full frame: its top-left pixel and the full size. */
struct ImageWindow {
    uint32_t x0 = 0, y0 = 0;
    uint32_t full_width = 0, full_height = 0;
};

/** The image after one pass of a progressive render. */
struct PassImage {
    const std::vector<float>& image;  ///< RGB, working space, divided by the samples reached
    uint32_t width, height;
    uint32_t spp;        ///< samples per pixel reached; 0 for a preview pass
    uint32_t target;     ///< samples per pixel the render is going to
    uint32_t block;      ///< 1, or the block side of a preview pass (each block one value)
    double seconds;      ///< render time so far
    ImageWindow window;  ///< where the image lies in the full frame (a crop)
    /** With the render layers: their channels so far (null: none, or a preview pass). */
    const std::vector<float>* layers = nullptr;
    const std::vector<std::string>* layer_names = nullptr;  ///< their names
};

/** How to render, from the command line; not part of the scene. */
struct RenderOptions {
    Strategy strategy = Strategy::Mis;  ///< for tests and debugging; MIS is always at least as good
    int threads = 0;                    ///< worker threads; 0 = all cores
    uint32_t spp_override = 0;          ///< replaces the scene's spp when non-zero
    uint32_t width_override = 0;        ///< replaces the scene's width when non-zero
    uint32_t height_override = 0;       ///< replaces the scene's height when non-zero
    /** Called with (samples done, samples total) from worker threads, serialised by the
     *  integrator; may be empty. */
    std::function<void(uint64_t, uint64_t)> progress;
    /** When set, the samples actually traced are added here as they are (the progress' done
     *  also counts, with adaptive sampling, the samples pixels that stopped will not take: a
     *  rate from it ran at 26-66 Msamples/s on one thread and its time left came out short). */
    std::atomic<uint64_t>* traced = nullptr;
    /** Told how far the long work before a render is (reading meshes, subdividing, building
     *  BVHs); may be empty. */
    WorkProgress work_progress;
    /** Called after each completed pass but the last with the image so far; may be empty. */
    std::function<void(const PassImage&)> on_pass;
    /** Polled between waves of tiles: when it returns true the render stops, keeping the
     *  passes completed so far. May be empty. */
    std::function<bool()> stop;
    /** Passes of 1, 1, 2, 4, ... samples (false: one pass of all samples; same image). */
    bool progressive = true;
    /** Before the first pass, a preview pass at reduced resolution (one path per block of
     *  preview_stride() pixels, shown through on_pass and then dropped): the first picture after
     *  an edit in a fraction of a full pass. The final image does not depend on it. */
    bool preview_pass = false;
    /** Render layers beside the beauty (RenderResult::layers): coverage, albedo, normal, depth,
     *  position, glints, one per light group. */
    bool layers = false;
    /** With the layers: the environment seen directly by camera rays goes to the layer
     *  `background` instead of the beauty and its light group, so that RGB is premultiplied
     *  by `A` (the beauty over the background is RGB + background). */
    bool background_apart = false;
    /** Renders only this window of the image (its pixels are those of the whole render, bit
     *  for bit: each pixel's samples depend on the pixel alone). */
    CropWindow crop;
    /** --spp-range: render samples [spp_first, spp_end) of the frame's (spp_end 0: all). The
     *  image is their mean; RenderResult::sums holds their exact sums, which add up across
     *  parts to the whole render's, bit for bit. */
    uint32_t spp_first = 0, spp_end = 0;
    /** Where converted textures are cached (empty: $SPANGLE_TEXTURE_CACHE or the user's cache
     *  directory) and how much memory the texture tile cache may hold. */
    std::string texture_cache;
    uint32_t texture_memory_mb = 1024;
    /** The camera to look through in a scene file with several (glTF: by name; empty: the
     *  file's first). */
    std::string camera;
    /** `--env`: a lat-long image lighting the scene instead of its environment; empty: none. */
    std::string environment;
    /** --noise-threshold, --min-spp, --max-spp: replace the scene's adaptive sampling settings
     *  ([render] noise_threshold, min_spp, max_spp) when set (threshold >= 0, counts > 0). */
    float noise_threshold_override = -1.0f;
    uint32_t min_spp_override = 0, max_spp_override = 0;
    /** --denoise: the final image denoised (render/denoise.h; needs the layers), its glints
     *  kept or filtered with the rest. Pass images are not denoised. */
    bool denoise = false;
    GlintDenoise denoise_glints = GlintDenoise::Keep;
    /** Computes every hit's footprint even where no material reads one (RenderJob::footprints):
     *  for tests that compare the two. */
    bool footprints_always = false;
    /** A load refuses a scene whose whole frame's film would not fit in memory (watch mode: the
     *  edit is refused as a load, and the last good scene's render goes on). Off elsewhere: an
     *  MPI rank renders bands, a crop part its window, and the render itself checks what it
     *  allocates. */
    bool film_memory_at_load = false;
};

/** The samples per pixel reached after each pass of a progressive render of `spp` samples:
 *  1, 2, 4, 8, ... doubling, the last pass ending exactly at spp. */
std::vector<uint32_t> pass_ends(uint32_t spp);

/** Side of the pixel blocks of a preview pass for a width x height film: a power of two up to
 *  16 that leaves at least 160 blocks along the longer side (1: no preview pass). */
uint32_t preview_stride(uint32_t width, uint32_t height);

/** Refuses (SpangleError naming the settings to lower) a film whose memory while rendering --
 *  the image and the copies passes need -- would not fit the memory available now. */
void check_film_memory(uint32_t width, uint32_t height, uint32_t spp, const RenderOptions& options,
                       uint32_t layer_channels = 0);

/** Counters of one render. */
struct RenderStats {
    uint64_t camera_rays = 0;  ///< primary rays
    uint64_t bounce_rays = 0;  ///< continuation rays after scattering
    uint64_t shadow_rays = 0;  ///< next-event visibility rays
    uint64_t samples = 0;      ///< camera samples (pixels x spp)
    uint64_t nonfinite = 0;    ///< contributions replaced by black
    uint32_t first_bad_pixel_x = 0, first_bad_pixel_y = 0, first_bad_sample = 0;
    /** Per material whose plugin returned outputs the host could not use (dropped or clamped):
     *  its label and what, with counts. Empty: none. */
    std::vector<std::string> plugin_problems;
    double seconds = 0.0;      ///< wall time of the render system
    uint32_t spp_reached = 0;  ///< samples per pixel of the passes completed
    uint32_t spp_target = 0;   ///< samples per pixel asked for
    uint32_t spp_frame = 0;    ///< the frame's samples per pixel (spp_target unless --spp-range)
    uint32_t passes = 0;       ///< passes completed
    /** Adaptive sampling: the noise threshold it rendered to (0: off, every pixel got
     *  spp_reached samples) and the fewest and most samples a pixel received. */
    float noise_threshold = 0.0f;
    uint32_t pixel_spp_min = 0, pixel_spp_max = 0;
    double pixel_spp_mean = 0.0;    ///< the image's pixels (a crop's halo not counted)
    uint32_t adaptive_min_spp = 0;  ///< adaptive sampling's min_spp (its max is spp_target)
    /** The image was denoised (--denoise), treating the glints so. */
    bool denoised = false;
    /** --denoise was asked for but a stop signal ended the denoise: the image is as rendered. */
    bool denoise_stopped = false;
    GlintDenoise denoise_glints = GlintDenoise::Keep;
    /** Hits got footprints (false: no material of the scene reads them, none was computed). */
    bool footprints = true;
    /** filter_samples = "shared": the weights that spread the pixels' means (spread_weights();
     *  empty: each pixel's own samples, or a filter within its pixel). */
    std::vector<double> filter_spread;
};

/** Records in `st` that its image was denoised, treating the glints so. */
inline void mark_denoised(RenderStats& st, GlintDenoise glints) {
    st.denoised = true;
    st.denoise_glints = glints;
}

}  // namespace spangle
