#pragma once
// The options of `spangle render`, as typed, and what the render modes derive from them alone:
// the render's options and the logger. The command registers them (render_command.cpp); each
// mode (one-shot, --frames, --watch, MPI ranks) reads them.

#include <cstdint>
#include <string>
#include <vector>

#include "core/log.h"
#include "render/render_options.h"

namespace spangle {

/** Options of `spangle render`. */
struct RenderArgs {
    std::string scene;                     ///< the scene file (any format Spangle reads)
    std::string camera;                    ///< --camera: by name, in a file with several
    std::string environment;               ///< --env: a lat-long map instead of the scene's
    std::string output;                    ///< -o: the EXR; empty = <scene name>.exr
    std::string preview;                   ///< the PNG preview; empty = the EXR's path with .png
    bool no_preview = false;               ///< write no PNG preview
    uint32_t spp = 0;                      ///< samples per pixel; 0 = the scene's
    int threads = 0;                       ///< worker threads; 0 = all cores
    std::vector<std::string> plugin_dirs;  ///< --plugin-path entries, searched first, in order
    bool stats = false;                    ///< print the systems that ran and render counters
    bool full_float = false;               ///< --float: 32-bit float EXR instead of half
    bool quiet = false;                    ///< no progress or info output
    std::string compression = "zip";       ///< EXR compression name
    std::string ocio;                      ///< OCIO config; empty = $OCIO, then the shipped one
    std::string strategy = "mis";          ///< light transport estimator: mis, nee or bsdf
    std::string size;                      ///< WIDTHxHEIGHT; empty = the scene's
    bool watch = false;                    ///< --watch: re-render on every save until a signal
    bool pass_output = false;              ///< write the images after every pass
    bool no_pass_output = false;           ///< with --watch: write only finished images
    std::string serve;                     ///< [ADDR:]PORT of the live preview page; empty = none
    std::string texture_cache;             ///< folder of converted textures; empty = default
    uint32_t texture_memory_mb = 1024;     ///< MiB the texture tile cache may hold
    std::string display, view;             ///< of the PNG preview; empty = the config's defaults
    bool layers = false;                   ///< write render layers beside the beauty
    std::string crop;                      ///< x0,y0,x1,y1; empty = the whole image
    std::string frames;                    ///< A..B or A; empty = one still at frame_start
    uint32_t band_rows = 1;                ///< under MPI: tile rows per unit of work
    std::string spp_range;                 ///< A..B: samples [A, B) of the frame's; empty = all
    double noise_threshold = -1.0;         ///< adaptive sampling's threshold; < 0: the scene's
    uint32_t min_spp = 0, max_spp = 0;     ///< adaptive sampling's bounds; 0: the scene's
    bool denoise = false;                  ///< --denoise: the final image denoised
    std::string denoise_glints;            ///< keep (pass through), apart or filter; "" = keep
};

/** The render's options from the command line (threads, size, spp, crop, strategy); throws
 *  UsageError for a malformed --size, --crop or --spp-range. */
RenderOptions render_options(const RenderArgs& a);

/** The logger of a render: notes and warnings, or warnings and errors only with --quiet. */
Logger render_logger(const RenderArgs& a);

}  // namespace spangle
