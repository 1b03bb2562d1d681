#pragma once
// Where and how a render's images are written: the EXR and its PNG preview, checked before any
// work (names, folders, clashes), then written atomically from one ImageDescription. Every render
// mode writes through here: one-shot, --frames (a path per frame), --watch (passes and finished
// images), MPI rank 0.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cli/render_args.h"
#include "color/image_output.h"
#include "core/log.h"
#include "render/render_options.h"
#include "scene/scene_info.h"

namespace spangle {

class ColorConfig;
struct SceneInfo;

/** One image to write and what its EXR header says about it. Borrows what it points at: the
 *  vectors, the config and the scene info must outlive the write. */
struct ImageDescription {
    const std::vector<float>* image = nullptr;   ///< RGB, working space, width x height; required
    uint32_t width = 0, height = 0;              ///< of the image (the crop window's)
    const ColorConfig* color = nullptr;          ///< the config of its working space; required
    uint32_t spp = 0;                            ///< samples per pixel reached; 0: a preview pass
    bool partial = false;                        ///< stopped before its spp (a pass, a signal)
    uint32_t block = 1;                          ///< a preview pass's block side; 1: full detail
    const SceneInfo* info = nullptr;             ///< camera and objects for the header; null: none
    double seconds = -1.0;                       ///< render time for the header; < 0: none
    const std::vector<float>* layers = nullptr;  ///< render layers; null or empty: none
    const std::vector<std::string>* layer_names = nullptr;  ///< the layers' channel names
    ImageWindow window;                            ///< place in the full frame; full_width 0: all
    const std::vector<SampleSum>* sums = nullptr;  ///< exact sums, kept for a --spp-range part
    uint32_t spp_frame = 0;                        ///< the frame's samples per pixel (--spp-range)
    /** How the samples were taken: "adaptive T min_spp A max_spp B", or empty (fixed). */
    std::string sampling;
    /** The denoiser's glint treatment (keep, apart, filter), or empty (not denoised). */
    std::string denoised;
    /** filter_samples = "shared": the spread weights as spread_note() writes them; empty: none. */
    std::string spread;
};

struct RenderResult;

/** Unlinks the output lock files held now (".NAME.lock"); safe in a signal handler. */
void remove_locks_in_progress() noexcept;

/** The header's note of how a render took its samples (adaptive settings; empty: fixed spp). */
std::string sampling_note(const RenderStats& st);

/** The header's note of how a render was denoised (empty: it was not). */
std::string denoise_note(const RenderStats& st);

/** The weights a shared filter spread the pixels' means by, exactly (hexadecimal floats), for a
 *  --spp-range part: spangle merge spreads the merged means alike. Empty: none. */
std::string spread_note(const RenderStats& st);

/** The render as its outputs take it: `r` itself, or with --denoise (o.denoise) a denoised copy
 *  in `scratch` (every mode denoises its final image alike: one-shot, --frames, --watch). */
const RenderResult& for_output(const RenderResult& r, const RenderOptions& o, const Logger& log,
                               RenderResult& scratch);

/** The final (or stopped) image of a render: a RenderResult, FrameResult or DistributedImage,
 *  with its layers, window and, where the result has them, the exact sums. */
template <class Result>
ImageDescription final_image(const Result& r, const ColorConfig& color, const SceneInfo& info) {
    ImageDescription d;
    d.image = &r.image;
    d.width = r.width;
    d.height = r.height;
    d.color = &color;
    d.spp = r.stats.spp_reached;
    d.partial = r.stats.spp_reached < r.stats.spp_target;
    d.info = &info;
    d.seconds = r.stats.seconds;
    d.layers = &r.layers;
    d.layer_names = &r.layer_names;
    d.window = r.window;
    d.sampling = sampling_note(r.stats);
    d.denoised = denoise_note(r.stats);
    d.spread = spread_note(r.stats);
    if constexpr (requires { r.sums; }) {
        d.sums = &r.sums;
        d.spp_frame = r.stats.spp_frame;
    }
    return d;
}

/** The image of a pass that is not the last (partial, maybe a reduced-resolution preview);
 *  `info` may be null (a one-shot render's first pass can end before it is known). */
ImageDescription pass_image(const PassImage& p, const ColorConfig& color, const SceneInfo* info);

/** Where and how a render's images are written. */
struct Outputs {
    std::string exr;                      ///< the EXR's path
    std::string preview;                  ///< the PNG preview's path; empty = none
    std::string display, view;            ///< of the preview (empty: the config's defaults)
    uint32_t spp_first = 0, spp_end = 0;  ///< --spp-range (spp_end 0: none)
    ExrOptions exr_options;               ///< half or float, compression
    std::string scene;                    ///< the scene file, named in the header
    /** The light transport estimator when it is not MIS (--strategy nee or bsdf), named in the
     *  header: spangle merge refuses parts of different estimators. Empty: MIS. */
    std::string strategy;

    /** Writes the image and its preview, each atomically (the PNG on another thread). A partial
     *  image says so in the header, with how far it got. Returns how many values the half-float
     *  EXR could not hold. Throws SpangleError. */
    std::size_t write(const ImageDescription& d) const;
    /** Writes a render's image and warns when values were beyond half floats (see --float). */
    void write_image(const Logger& log, const ImageDescription& d) const;
    /** Writes the image of a pass that is not the last (pass_image). */
    void write_pass(const PassImage& p, const ColorConfig& color, const SceneInfo* info) const;
    /** The outputs of frame f of --frames (frame_path in output_paths.h). */
    Outputs for_frame(int64_t f) const;
    /** Throws SpangleError when the preview's display or view is not in `color`: an error before
     *  any rendering. */
    void check_view(const ColorConfig& color) const;
    /** Throws SpangleError when the EXR or the preview is one of `inputs` (the files the scene
     *  read: its scene files, meshes, textures, maps): the render would overwrite its input. */
    void check_not_inputs(const std::vector<std::string>& inputs, const char* exr_option = "-o",
                          const char* preview_option = "--preview") const;
    /** Removes the temporary images a killed render left in the folders of the EXR and the
     *  preview (color/temporary_files.h), saying which; what cannot be removed is a warning. */
    void remove_stale_temporaries(const Logger& log) const;
};

/** The outputs `spangle render` asked for, checked before any work: an .exr name, a known
 *  compression, a preview that is another file, neither the scene file, both writable (with
 *  --frames, every frame's, none a folder). Throws
 *  UsageError (a clash on the command line) or SpangleError (a path that cannot be written). */
Outputs outputs_for(const RenderArgs& a, bool check_paths = true);

/** Where -o gives no output, the outputs once the scene is read: the image it asks for
 *  ([render] output, pbrt's Film "filename"), as an EXR (another extension becomes .exr),
 *  relative to the working folder as pbrt writes it, else the scene file's name; checked as
 *  outputs_for() checks -o's (a render set up with its default unchecked: a working folder it
 *  cannot write is no error where the scene names another), temporaries a killed render left
 *  beside it removed, one line (unless --quiet) saying where the image the scene asks for goes.
 *  A name with a frame number ('#') where nothing numbers the image (`numbered` false) is an
 *  error at the scene's line. nullopt where -o gives one. */
std::optional<Outputs> scene_outputs(const RenderArgs& a, const SceneInfo& info, const Logger& log,
                                     bool numbered, int64_t first, int64_t last);

/** Says, once per process, that the EXRs carry no chromaticities (a foreign OCIO config whose
 *  working space Spangle can neither recognise nor measure), and what would fix it. */
void warn_if_no_chromaticities(const Logger& log, const ColorConfig& color);

/** Says that `values` values of `exr` were beyond half floats (65504: a bright light seen
 *  directly, a strong glint) and became +Inf, and what to do; nothing when there were none. */
void warn_half_overflow(const Logger& log, std::size_t values, const std::string& exr);

}  // namespace spangle
