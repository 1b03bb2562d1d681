// `spangle render SCENE`: its options, the checks of options that clash, and the choice of a
// mode: a one-shot render (here), --frames (frames_command.cpp), --watch (watch/) or, started
// by mpirun as one of several ranks, a render shared by the ranks (mpi_command.cpp).

#include <fmt/format.h>

#include <unistd.h>
#include <cmath>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "cli/frames_command.h"
#include "cli/launcher.h"
#include "cli/mpi_command.h"
#include "cli/outputs.h"
#include "cli/preview_server.h"
#include "cli/progress.h"
#include "cli/render_args.h"
#include "cli/render_setup.h"
#include "cli/signals.h"
#include "cli/usage.h"
#include "cli/watch/watch_command.h"
#include "core/error.h"
#include "pipeline/frame.h"
#include "render/adaptive.h"
#include "render/denoise.h"

namespace spangle {
namespace {

namespace fs = std::filesystem;

/** Registers the scene, the outputs' paths, the size and samples, plugins and --stats. */
void add_scene_options(CLI::App* r, RenderArgs& a) {
    r->add_option("scene", a.scene, "scene file (TOML, or any format Spangle reads)")->required();
    r->add_option("--camera", a.camera, "the camera to look through, by name (a glTF file's)");
    r->add_option("--env", a.environment,
                  "a lat-long image (EXR, HDR) lighting the scene instead of its environment")
        ->check(CLI::ExistingFile);
    r->add_option("-o,--output", a.output, "output EXR (default: <scene name>.exr)");
    r->add_option("--preview", a.preview, "PNG preview path (default: the output with .png)");
    r->add_flag("--no-preview", a.no_preview, "write no PNG preview");
    r->add_option("--size", a.size, "image size WIDTHxHEIGHT (overrides the scene)");
    r->add_option("--spp", a.spp, "samples per pixel (overrides the scene)")
        ->check(CLI::Range(1u, 1u << 20));
    r->add_option("--noise-threshold", a.noise_threshold,
                  "adaptive sampling: a pixel stops once its relative standard error is below "
                  "this (e.g. 0.01; 0 = off; overrides [render] noise_threshold; "
                  "docs/adaptive.md)")
        ->check(CLI::Range(0.0, 1.0));
    r->add_option("--min-spp", a.min_spp,
                  "adaptive sampling: samples every pixel takes first (default 16; rounded up to a "
                  "multiple of 4, at least 8)")
        ->check(CLI::Range(1u, 1u << 20));
    r->add_option("--max-spp", a.max_spp,
                  "adaptive sampling: most samples a pixel takes (default: --spp or the "
                  "scene's spp)")
        ->check(CLI::Range(1u, 1u << 20));
    r->add_option("--threads", a.threads, "worker threads (default: all cores)")
        ->check(CLI::Range(1, 1024));
    r->add_option("--plugin-path", a.plugin_dirs,
                  "directory searched for plugins first (repeatable)")
        ->allow_extra_args(false);  // one folder each: the scene after it is not a folder
    r->add_flag("--stats", a.stats, "print which systems ran and render statistics");
}

/** Registers what part of the render is made: frames, samples, a window, MPI bands, layers. */
void add_part_options(CLI::App* r, RenderArgs& a) {
    r->add_option("--frames", a.frames,
                  "render frames A..B (or A) of the scene's keyframed animation, each to the "
                  "output with its number ('#' runs in -o are the number, else .####)");
    r->add_option("--spp-range", a.spp_range,
                  "render samples A..B-1 of the frame's (A..B); spangle merge adds parts of "
                  "one frame into exactly the whole render (docs/crop_merge.md)");
    r->add_option("--crop", a.crop,
                  "render only the window x0,y0,x1,y1 of the image (pixels [x0, x1) x [y0, "
                  "y1)); the EXR's data window places it in the full frame; spangle merge "
                  "assembles the parts bit for bit");
    r->add_option("--band-rows", a.band_rows,
                  "under mpirun: tile rows (16 pixels each) per unit of work handed to a rank "
                  "(default 1)")
        ->check(CLI::Range(1u, 4096u));
    r->add_flag("--denoise", a.denoise,
                "denoise the final image with Intel Open Image Denoise (albedo and normal "
                "guides; glints pass through unfiltered); the noisy beauty and the guides are "
                "kept as layers (implies --layers; docs/denoise.md)");
    r->add_option("--denoise-glints", a.denoise_glints,
                  "keep: the glints layer passes the denoiser untouched, so glints stay points "
                  "(default); apart: it is denoised on its own and added back (smoother dense "
                  "glitter at low spp, softer glints); filter: the whole beauty at once (for "
                  "comparison)")
        ->check(CLI::IsMember({"apart", "keep", "filter"}));
    r->add_flag("--layers", a.layers,
                "write render layers into the EXR beside the beauty: A (coverage), albedo, "
                "N, Z, P, glints, and lightgroup_<name> per light group (docs/layers.md)");
}

/** Registers the preview's colours, textures, the EXR's format, OCIO, --quiet, the estimator. */
void add_look_options(CLI::App* r, RenderArgs& a) {
    r->add_option("--view", a.view,
                  "OCIO view of the PNG preview (default: the display's default view; the "
                  "shipped config's is \"Sparkle\": hue kept, very bright glints go to white; "
                  "\"Glint\" keeps their hue; \"Standard\" clips at 1)");
    r->add_option("--display", a.display,
                  "OCIO display of the PNG preview (default: the config's default display)");
    r->add_option("--texture-cache", a.texture_cache,
                  "folder for textures converted to the working space (default: "
                  "$SPANGLE_TEXTURE_CACHE, else $XDG_CACHE_HOME/spangle/textures, else "
                  "~/.cache/spangle/textures)");
    r->add_option("--texture-memory", a.texture_memory_mb,
                  "MiB the texture tile cache may hold (default 1024)")
        ->check(CLI::Range(16u, 1u << 20));
    r->add_flag("--float", a.full_float, "write 32-bit float EXR instead of half");
    r->add_option("--compression", a.compression, "EXR compression (default zip)");
    r->add_option("--ocio", a.ocio, "OpenColorIO config (default: $OCIO, then the shipped one)");
    r->add_flag("-q,--quiet", a.quiet, "no progress or info output");
    r->add_option("--strategy", a.strategy,
                  "light transport estimator: mis (default), nee or bsdf (for debugging)")
        ->check(CLI::IsMember({"mis", "nee", "bsdf"}));
}

/** Registers the look-development loop: --watch, pass outputs and the live preview page. */
void add_live_options(CLI::App* r, RenderArgs& a) {
    r->add_flag("--watch", a.watch,
                "keep running: re-render incrementally whenever the scene or a file it "
                "uses is saved (stop with Ctrl-C)");
    r->add_flag("--pass-output", a.pass_output,
                "write the EXR and preview after every pass (on by default with --watch)");
    r->add_flag("--no-pass-output", a.no_pass_output, "with --watch: write only finished images");
    r->add_option("--serve", a.serve,
                  "serve a live preview page on [ADDR:]PORT (127.0.0.1 unless ADDR is "
                  "given; port 0 picks a free one)")
        ->check(CLI::Validator(
            [](std::string& spec) {
                try {
                    parse_serve_address(spec);
                } catch (const SpangleError& e) {
                    return std::string(e.what());
                }
                return std::string();
            },
            "[ADDR:]PORT"));
}

/** --stats: which systems ran, plugins, the render's rates and counters, subdivision and the
 *  materials' own statistics. */
void print_stats(const FrameResult& r, const std::string& exr) {
    fmt::print("systems:\n");
    for (const auto& s : r.systems) {
        if (s.ran)
            fmt::print("  {:<16} ran      {:9.3f} s\n", s.name, s.seconds);
        else
            fmt::print("  {:<16} skipped  ({})\n", s.name, s.reason);
    }
    fmt::print("plugins opened: {}\n", r.plugins_opened.empty()
                                           ? std::string("none")
                                           : fmt::format("{}", fmt::join(r.plugins_opened, ", ")));
    const RenderStats& st = r.stats;
    if (st.samples > 0) {
        const double rays = static_cast<double>(st.camera_rays + st.bounce_rays + st.shadow_rays);
        fmt::print("render: {}x{}, {} samples in {:.3f} s: {:.3f} Msamples/s, {:.3f} Mrays/s\n",
                   r.width, r.height, st.samples, st.seconds,
                   static_cast<double>(st.samples) / st.seconds * 1e-6, rays / st.seconds * 1e-6);
        fmt::print("rays: {} camera, {} bounce, {} shadow\n", st.camera_rays, st.bounce_rays,
                   st.shadow_rays);
        fmt::print("non-finite samples replaced by black: {}\n", st.nonfinite);
        fmt::print("footprints: {}\n",
                   st.footprints ? "computed" : "not computed (no material or texture reads them)");
        if (st.noise_threshold > 0.0f)
            fmt::print(
                "adaptive sampling: noise threshold {}, {:.1f} samples per pixel on average "
                "({} to {}; the spp layer has each pixel's)\n",
                st.noise_threshold, st.pixel_spp_mean, st.pixel_spp_min, st.pixel_spp_max);
    }
    for (const auto& sd : r.subdiv)
        fmt::print("subdivision: {} level {}{}: {} cage faces -> {} triangles in {:.3f} s\n",
                   sd.cage, sd.level, sd.from_camera ? " (from the camera)" : "", sd.cage_faces,
                   sd.triangles, sd.seconds);
    for (const auto& [name, values] : r.material_stats) {
        fmt::print("material '{}':\n", name);
        for (const auto& [key, value] : values) fmt::print("  {:<44} {:.4g}\n", key, value);
    }
    fmt::print("working space: {}\noutput: {}\n", r.color.working_space(), exr);
}

/** Writes a one-shot render's image and says so; returns the exit status. */
int finish_one_shot(const RenderArgs& a, const RenderSetup& s, const FrameResult& frame) {
    if (frame.image.empty() && !stop_requested())
        throw_error("the scene has no camera to render from");
    warn_nonfinite(s.log, frame.stats);
    const ImageDescription image = final_image(frame, frame.color, frame.info);
    if (frame.stats.spp_reached == 0) {
        s.log.warn("stopped by a signal ({}) before the first pass ended: no image written",
                   stop_signal_name());
        return interrupted_status();
    }
    s.out.write_image(s.log, image);
    if (image.partial)
        s.log.warn("stopped by a signal ({}): wrote {} with {} of {} samples per pixel",
                   stop_signal_name(), s.out.exr, frame.stats.spp_reached, frame.stats.spp_target);
    if (a.stats)
        print_stats(frame, s.out.exr);
    else if (!a.quiet)
        s.log.info("wrote {}{}", s.out.exr, s.out.preview.empty() ? "" : " and " + s.out.preview);
    // A partial image is not a finished render: 130 after SIGINT, 143 after SIGTERM. A signal
    // that came after the last pass (while the image was written) leaves the image whole:
    // SIGTERM still ends the process as terminated (143), SIGINT's status is 0.
    if (image.partial) return interrupted_status();
    if (frame.stats.denoise_stopped) {
        s.log.warn("stopped by a signal ({}) while denoising: wrote {} as rendered, not denoised",
                   stop_signal_name(), s.out.exr);
        return interrupted_status();
    }
    // The signal came after the last pass: the image is whole, and the line says so (a farm
    // reading 143 alone took the finished image for a cut one). (The flag read once: a signal
    // between two reads exited 143 without the line.)
    if (!stop_requested()) return 0;
    const int status = exit_status_for_signal();
    s.log.warn("{} arrived after the last pass: wrote {} whole, {} samples per pixel{}",
               stop_signal_name(), s.out.exr, frame.stats.spp_reached, late_signal_status(status));
    return status;
}

/** The one-shot render: load, render (passes written with --pass-output, shown with --serve),
 *  write the image. */
int run_one_shot(const RenderArgs& a) {
    RenderSetup s = set_up_render(a, true);
    FrameRequest req;
    req.scene = a.scene;
    req.plugin_dirs = a.plugin_dirs;
    req.ocio_config = a.ocio;
    req.options = render_options(a);
    req.log = &s.log;
    Progress progress(::isatty(STDERR_FILENO) != 0);
    std::atomic<uint64_t> traced{0};
    req.options.traced = &traced;
    if (!a.quiet)
        req.options.progress = [&](uint64_t done, uint64_t total) {
            progress.update(done, total, traced.load(std::memory_order_relaxed));
        };
    req.options.stop = stop_requested;
    // The colour config is only known once the frame has loaded it: the pass callback gets it
    // through this pointer, set by on_loaded below before any pass ends.
    const ColorConfig* color = nullptr;
    const SceneInfo* info = nullptr;
    const std::unique_ptr<PreviewServer> server = start_preview_server(a.serve, s.log);
    if (server) {
        server->stage(fmt::format("loading {}", a.scene));
        req.options.work_progress = work_progress_to(server.get(), req.options.work_progress);
    }
    req.options.preview_pass = a.pass_output || server;
    if (a.pass_output || server)
        req.options.on_pass = [&](const PassImage& p) {
            if (!color) return;
            if (server)
                server->publish_pass(p.image, p.width, p.height, p.spp, p.target, p.block, *color);
            if (a.pass_output) s.out.write_pass(p, *color, info);
        };
    if (server)
        req.options.progress = [&, print = req.options.progress](uint64_t done, uint64_t total) {
            if (print) print(done, total);
            server->progress(done, total);
        };
    req.on_loaded = [&](const ColorConfig& c, const SceneInfo& i,
                        const std::vector<std::string>& inputs) {
        // The image the scene asks for (pbrt's Film "filename") when -o gives none, as an EXR
        // (its PNG preview beside it), relative to the working folder as pbrt writes it.
        if (auto asked = scene_outputs(a, i, s.log, false, 0, 0)) s.out = std::move(*asked);
        s.out.check_not_inputs(inputs);
        s.out.check_view(c);  // a display or view the config lacks: an error before rendering
        warn_if_no_chromaticities(s.log, c);
        color = &c;
        info = &i;
        if (server) server->stage("rendering");
    };
    const FrameResult frame = render_frame(req);
    progress.finish();
    if (server && !frame.image.empty())
        server->publish_pass(frame.image, frame.width, frame.height, frame.stats.spp_reached,
                             frame.stats.spp_target, 1, frame.color);
    return finish_one_shot(a, s, frame);
}

/** Refuses options that clash (UsageError) and runs the mode they ask for. */
int run_render_command(const RenderArgs& a, int& argc, char**& argv) {
    // CLI11's range checks let NaN through (every comparison with it is false).
    if (a.stats && !a.frames.empty())
        usage_error(
            "--stats reports one render: render a frame of the sequence alone for them "
            "(each frame's line already gives its time)");
    // (Negative: not given, the scene's; CLI11 refuses other values outside [0, 1].)
    if (!(a.noise_threshold < 0.0))
        if (const std::string why = noise_threshold_problem(a.noise_threshold); !why.empty())
            usage_error("--noise-threshold {}", why);
    // Options that contradict each other, or name what is not there, are refused rather than
    // one of them silently winning.
    // (An adaptive threshold from the scene file meets --spp-range when the scene is loaded:
    // refused there, exit 1; two options that clash are a usage error before any work.)
    if (a.noise_threshold > 0.0 && !a.spp_range.empty())
        usage_error("{}", spp_range_refusal("an adaptive render (--noise-threshold)"));
    if (a.min_spp > 0 && a.max_spp > 0 && a.min_spp > a.max_spp)
        usage_error("--min-spp {} is more than --max-spp {}", a.min_spp, a.max_spp);
    if (a.min_spp > 0 && a.max_spp == 0 && a.spp > 0 && a.min_spp > a.spp)
        usage_error("--min-spp {} is more than --spp {} (the most a pixel takes without --max-spp)",
                    a.min_spp, a.spp);
    if (!a.preview.empty() && a.no_preview)
        usage_error("--preview names a preview and --no-preview asks for none: choose one");
    if (a.pass_output && a.no_pass_output)
        usage_error("--pass-output and --no-pass-output: choose one");
    if (!a.denoise_glints.empty() && !a.denoise)
        usage_error("--denoise-glints says how --denoise treats the glints: add --denoise");
    check_plugin_dirs(a.plugin_dirs);
    if (!a.spp_range.empty()) {
        if (a.layers)
            usage_error(
                "--spp-range parts carry the beauty's exact sums, not the layers': render "
                "--layers without --spp-range");
        if (a.watch) usage_error("--spp-range renders a part of a frame; --watch a whole one");
        if (a.denoise)
            usage_error(
                "--spp-range parts are sums to merge: a denoised part could not be added; render "
                "the frame whole (or by --crop or MPI) with --denoise");
        if (launcher_info().size > 1)
            usage_error("--spp-range is for one process (under mpirun, ranks share the image)");
    }
    // A denoiser that cannot run is said before the render, not after it.
    if (std::string why; a.denoise && !denoiser_available(&why)) throw_error("{}", why);
    if (launcher_info().size > 1) {
        // Started by mpirun (or srun) as one of several ranks.
        if (a.watch || a.pass_output || !a.serve.empty())
            usage_error(
                "--watch, --pass-output and --serve are for one process; under mpirun "
                "spangle renders a still or --frames and rank 0 writes them");
#ifdef SPANGLE_HAVE_MPI
        return run_render_mpi(a, argc, argv);
#else
        (void)argc;
        (void)argv;
        usage_error(
            "this spangle was built without MPI, so each of the {} ranks would render the "
            "whole image: run it as one process, or rebuild with libopenmpi-dev installed "
            "(SPANGLE_MPI=ON)",
            launcher_info().size);
#endif
    }
    if (!a.frames.empty() && a.watch)
        usage_error(
            "--frames renders a sequence and ends; --watch keeps one frame live: choose one");
    if (!a.frames.empty()) return run_frames(a);
    return a.watch ? run_watch(a) : run_one_shot(a);
}

}  // namespace

Command add_render_command(CLI::App& app, int& argc, char**& argv) {
    auto a = std::make_shared<RenderArgs>();
    CLI::App* r = app.add_subcommand("render", "render a scene file to a colour-managed EXR");
    add_scene_options(r, *a);
    add_part_options(r, *a);
    add_look_options(r, *a);
    add_live_options(r, *a);
    return {r, [a, &argc, &argv] { return run_render_command(*a, argc, argv); }};
}

}  // namespace spangle
