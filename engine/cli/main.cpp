// The spangle command. The only place in Spangle that prints errors as exit codes:
//   0  success
//   1  a problem with the input (scene, mesh, plugin, output path): one message, file:line:col
//   2  bad command line
//   3  internal error (a bug in Spangle)

#include <fcntl.h>
#include <fmt/format.h>
#include <sched.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "cli/bench.h"
#include "cli/interior_scene.h"
#include "cli/launcher.h"
#include "cli/mpi_render.h"
#include "cli/preview_server.h"
#include "cli/progress.h"
#include "cli/watch/file_watcher.h"
#include "color/flicker.h"
#include "color/image_io.h"
#include "color/image_merge.h"
#include "color/image_output.h"
#include "core/error.h"
#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "render/camera.h"
#include "render/image_metrics.h"
#include "scene/toml_reader.h"

#include "shading/material.h"
#include "shading/plugin_loader.h"

#ifndef SPANGLE_VERSION
#define SPANGLE_VERSION "0.0.0"
#endif

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** Options of `spangle render`. */
struct RenderArgs {
    std::string scene;
    std::string output;
    std::string preview;
    bool no_preview = false;
    uint32_t spp = 0;
    int threads = 0;
    std::vector<std::string> plugin_dirs;
    bool stats = false;
    bool full_float = false;
    bool quiet = false;
    std::string compression = "zip";
    std::string ocio;
    std::string strategy = "mis";
    std::string size;
    bool watch = false;
    bool pass_output = false;
    bool no_pass_output = false;
    std::string serve;  ///< [ADDR:]PORT of the live preview page; empty = none
    std::string texture_cache;
    uint32_t texture_memory_mb = 1024;
    std::string display, view;  ///< of the PNG preview; empty = the config's defaults
    bool layers = false;
    std::string crop;        ///< x0,y0,x1,y1; empty = the whole image
    std::string frames;      ///< A..B or A; empty = one still at the scene's frame_start
    uint32_t band_rows = 1;  ///< under MPI: tile rows per unit of work
    std::string spp_range;   ///< A..B: samples [A, B) of the frame's; empty = all
};

/** A bad command line (exit status 2), found after parsing (sizes, names, paths that clash). */
class UsageError : public SpangleError {
public:
    using SpangleError::SpangleError;
};

template <class... Args>
[[noreturn]] void usage_error(fmt::format_string<Args...> f, Args&&... args) {
    throw UsageError(fmt::format(f, std::forward<Args>(args)...));
}

void print_error(const std::string& msg) {
    // Located messages already read "file:line:col: error: ..."; others get the prefix here.
    if (msg.find(": error: ") != std::string::npos)
        fmt::print(stderr, "{}\n", msg);
    else
        fmt::print(stderr, "spangle: error: {}\n", msg);
}

// ------------------------------------------------------------------------------------ signals

/** The first SIGINT or SIGTERM: renders stop at the next wave of tiles and write what they
 *  have. A second SIGINT exits at once, removing the temporary file of an image being written
 *  (outputs are renamed into place whole, so none is ever half-written). */
volatile std::sig_atomic_t stop_signal = 0;

extern "C" void on_stop_signal(int sig) {
    if (sig == SIGINT && stop_signal == SIGINT) {
        remove_image_in_progress();
        ::_exit(130);
    }
    if (stop_signal == 0) stop_signal = sig;
}

void install_signal_handlers() {
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;  // no SA_RESTART: a blocking wait returns early
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
}

/** Exit status after a stop signal: 0 for SIGINT (the user asked), 128 + 15 for SIGTERM. */
int exit_status_for_signal() {
    return stop_signal == SIGTERM ? 143 : 0;
}

/** Where and how a render's images are written. */
struct Outputs {
    std::string exr, preview;
    std::string display, view;            ///< of the preview (empty: the config's defaults)
    uint32_t spp_first = 0, spp_end = 0;  ///< --spp-range (spp_end 0: none)
    ExrOptions exr_options;
    std::string scene;

    /** Writes image (working space) and its preview, each atomically. `partial`: the render
     *  stopped before its spp; the EXR header says so and how far it got. Returns how many
     *  values the half-float EXR could not hold (see warn_half_overflow). */
    /** `info` (the scene's camera) and `seconds` (the render time) go into the EXR header when
     *  given (pass outputs during a one-shot render have neither yet). */
    /** `layers` / `layer_names`: the render layers (--layers), written into the same EXR. */
    std::size_t write(const std::vector<float>& image, uint32_t width, uint32_t height,
                      const ColorConfig& color, uint32_t spp, bool partial, uint32_t block = 1,
                      const SceneInfo* info = nullptr, double seconds = -1.0,
                      const std::vector<float>* layers = nullptr,
                      const std::vector<std::string>* layer_names = nullptr,
                      const ImageWindow* window = nullptr,
                      const std::vector<SampleSum>* sums = nullptr, uint32_t spp_frame = 0) const {
        ExrOptions o = exr_options;
        // A crop: the image is a data window of the full frame; the camera is the frame's.
        uint32_t frame_w = width, frame_h = height;
        if (window && window->full_width > 0) {
            frame_w = window->full_width;
            frame_h = window->full_height;
            o.origin_x = static_cast<int>(window->x0);
            o.origin_y = static_cast<int>(window->y0);
            o.display_width = static_cast<int>(frame_w);
            o.display_height = static_cast<int>(frame_h);
        }
        if (layers && layer_names && !layers->empty()) {
            o.layers = layers;
            o.layer_names = *layer_names;
        }
        o.metadata = {{"spangle:scene", scene},
                      {"spangle:version", SPANGLE_VERSION},
                      {"spangle:spp", std::to_string(spp)},
                      {"spangle:partial", partial ? "1" : "0"}};
        // A --spp-range part: its samples' exact sums, for spangle merge.
        if (spp_end > 0 && sums && !partial) {
            o.sums = sums;
            o.metadata.emplace_back("spangle:spp_range", fmt::format("{}..{}", spp_first, spp_end));
            o.metadata.emplace_back("spangle:spp_frame", std::to_string(spp_frame));
        }
        if (seconds >= 0.0) o.floats.emplace_back("renderTimeSeconds", static_cast<float>(seconds));
        if (info) {
            // The names pbrt-v4 writes and Nuke reads (OpenEXR's standard attributes).
            const Camera& c = info->camera;
            const CameraMatrices m = CameraModel(c.position, c.look_at, c.up, c.fov_deg, c.aperture,
                                                 c.focus_distance, frame_w, frame_h)
                                         .matrices();
            o.matrices = {{"worldToCamera", m.world_to_camera}, {"worldToNDC", m.world_to_ndc}};
            // With the layers: where each object stands (12 floats each, the rows of its 3x4
            // object-to-world matrix), so that Pobj carries a point into world space and a
            // sequence's frames can follow a turning object (spangle flicker).
            if (layers && !layers->empty()) {
                std::vector<float> xf;
                for (const Affine& a : info->object_to_world)
                    for (int r = 0; r < 3; ++r)
                        xf.insert(xf.end(), {a.m[r][0], a.m[r][1], a.m[r][2], a.t[r]});
                o.float_vectors.emplace_back("spangle:objectToWorld", std::move(xf));
            }
        }
        // A reduced-resolution preview pass (0 spp, blocks of `block` pixels).
        if (block > 1) o.metadata.emplace_back("spangle:preview_stride", std::to_string(block));
        // The PNG is written beside the EXR, on another thread.
        std::future<void> png_done;
        if (!preview.empty()) {
            PngOptions png;
            if (partial) png.compression_level = 1;  // passes come often: speed over size
            png.block = block;
            png.display = display;
            png.view = view;
            png_done = std::async(std::launch::async, [&, png] {
                write_png_preview(preview, image, static_cast<int>(width), static_cast<int>(height),
                                  color, png);
            });
        }
        std::size_t overflow = 0;
        try {
            overflow =
                write_exr(exr, image, static_cast<int>(width), static_cast<int>(height), color, o);
        } catch (...) {
            if (png_done.valid()) png_done.wait();
            throw;
        }
        if (png_done.valid()) png_done.get();  // rethrows its error
        return overflow;
    }
    /** The image of a pass that is not the last (partial, maybe a preview pass). */
    void write_pass(const PassImage& p, const ColorConfig& color,
                    const SceneInfo* info = nullptr) const {
        write(p.image, p.width, p.height, color, p.spp, true, p.block, info, p.seconds, nullptr,
              nullptr, &p.window);
    }
};

/** Says, once per process, that the EXRs carry no chromaticities (a foreign OCIO config whose
 *  working space Spangle can neither recognise nor measure), and what would fix it. */
void warn_if_no_chromaticities(const Logger& log, const ColorConfig& color) {
    static std::atomic<bool> said{false};
    if (color.working_chromaticities() || said.exchange(true)) return;
    log.warn(
        "the EXR carries no chromaticities attribute: the working space '{}' of the OCIO config "
        "'{}' is not one Spangle knows the primaries of, and the config has no "
        "cie_xyz_d65_interchange role to measure them through (add that role, or use a working "
        "space such as ACEScg or lin_rec709); its colorSpace attribute still names the space",
        color.working_space(), color.path());
}

/** Half floats end at 65504: brighter values (a bright light seen directly, a strong glint)
 *  become +Inf in a half EXR. Says so, and what to do. */
void warn_half_overflow(const Logger& log, std::size_t values, const std::string& exr) {
    if (values > 0)
        log.warn(
            "{} values in {} are brighter than a half float holds (65504) and were stored as "
            "infinity; write 32-bit floats with --float",
            values, exr);
}

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

/** A pixel count or coordinate on the command line: digits only, at most 5 of them (sscanf's
 *  "%u" would wrap 4294967312 to 16 and accept trailing junk). False when `t` is not one. */
bool pixel_count(const std::string& t, uint32_t& value) {
    if (t.empty() || t.size() > 5 || t.find_first_not_of("0123456789") != std::string::npos)
        return false;
    value = static_cast<uint32_t>(std::stoul(t));
    return true;
}

/** --size WIDTHxHEIGHT (render and bench): each side 1..16384, else a usage error. */
void parse_size(const std::string& size, uint32_t& width, uint32_t& height) {
    const auto x = size.find('x');
    const auto side = [&](const std::string& t) -> uint32_t {
        uint32_t v = 0;
        return pixel_count(t, v) ? v : 0;
    };
    width = x == std::string::npos ? 0 : side(size.substr(0, x));
    height = x == std::string::npos ? 0 : side(size.substr(x + 1));
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        usage_error("--size must be WIDTHxHEIGHT with each in 1..16384, got '{}'", size);
}

/** --crop x0,y0,x1,y1: four pixel bounds, digits only, x0 < x1 and y0 < y1 (whether the window
 *  lies inside the image is checked once the scene's size is known). */
CropWindow parse_crop(const std::string& text) {
    uint32_t v[4] = {0, 0, 0, 0};
    std::size_t at = 0;
    for (int i = 0; i < 4; ++i) {
        const std::size_t end = i < 3 ? text.find(',', at) : text.size();
        const std::string t = end == std::string::npos ? std::string() : text.substr(at, end - at);
        if (!pixel_count(t, v[i]))
            usage_error(
                "--crop must be x0,y0,x1,y1 (pixels, the window [x0, x1) x [y0, y1)), got '{}'",
                text);
        at = end + 1;
    }
    if (!(v[0] < v[2] && v[1] < v[3])) usage_error("--crop {}: it needs x0 < x1 and y0 < y1", text);
    return CropWindow{v[0], v[1], v[2], v[3]};
}

/** --spp-range A..B: samples [A, B) of the frame's (0 <= A < B). */
void parse_spp_range(const std::string& text, uint32_t& first, uint32_t& end) {
    const auto number = [](const std::string& t, uint32_t& v) {
        if (t.empty() || t.size() > 7 || t.find_first_not_of("0123456789") != std::string::npos)
            return false;
        v = static_cast<uint32_t>(std::stoul(t));
        return v <= (1u << 20);
    };
    const std::size_t dots = text.find("..");
    if (dots == std::string::npos || !number(text.substr(0, dots), first) ||
        !number(text.substr(dots + 2), end))
        usage_error("--spp-range must be A..B (sample numbers, samples A to B-1), got '{}'", text);
    if (!(first < end)) usage_error("--spp-range {}: it needs A < B", text);
}

/** Options of a render from the command line (threads, size, spp, strategy). */
RenderOptions render_options(const RenderArgs& a) {
    RenderOptions o;
    o.threads = a.threads;
    o.spp_override = a.spp;
    o.texture_cache = a.texture_cache;
    o.layers = a.layers;
    if (!a.crop.empty()) o.crop = parse_crop(a.crop);
    if (!a.spp_range.empty()) parse_spp_range(a.spp_range, o.spp_first, o.spp_end);
    o.texture_memory_mb = a.texture_memory_mb;
    if (!a.size.empty()) parse_size(a.size, o.width_override, o.height_override);
    o.strategy = a.strategy == "nee"    ? Strategy::NeeOnly
                 : a.strategy == "bsdf" ? Strategy::BsdfOnly
                                        : Strategy::Mis;
    return o;
}

/** Checks, before any work, that an image can be written at `path`: its folder exists and is
 *  writable, the path is not a folder, its names are not too long. Throws SpangleError. */
void check_writable(const std::string& path, const char* what) {
    const fs::path p(path);
    const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
    if (path.size() >= PATH_MAX)
        throw_error("cannot write the {} '{}': the path is longer than {} bytes", what, path,
                    PATH_MAX - 1);
    // The image goes to a temporary name beside it first (".NAME.tmpPID.N"), also a name.
    if (p.filename().string().size() + 24 > NAME_MAX)
        throw_error("cannot write the {} '{}': the file name is longer than {} bytes", what, path,
                    NAME_MAX - 24);
    std::error_code ec;
    if (!fs::exists(dir, ec))
        throw_error("cannot write the {} '{}': folder '{}' does not exist", what, path,
                    dir.string());
    if (!fs::is_directory(dir, ec))
        throw_error("cannot write the {} '{}': '{}' is not a folder", what, path, dir.string());
    if (fs::is_directory(p, ec))
        throw_error("cannot write the {} '{}': it is a folder", what, path);
    // Creating a file there is the only test that holds for every case (permissions, root,
    // read-only or special file systems): the image's own temporary file is made the same way.
    const fs::path probe = dir / fmt::format(".spangle-probe-{}", ::getpid());
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0)
        throw_error("cannot write the {} '{}': cannot create files in folder '{}' ({})", what, path,
                    dir.string(), std::strerror(errno));
    ::close(fd);
    ::unlink(probe.c_str());
}

/** Whether two output paths name the same file (existing or not). */
bool same_file(const std::string& a, const std::string& b) {
    std::error_code ec1, ec2;
    const fs::path pa = fs::weakly_canonical(fs::absolute(a), ec1),
                   pb = fs::weakly_canonical(fs::absolute(b), ec2);
    if (ec1 || ec2) return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
    return pa == pb;
}

Outputs outputs_for(const RenderArgs& a) {
    Outputs out;
    out.exr = a.output.empty() ? fs::path(a.scene).stem().string() + ".exr" : a.output;
    if (fs::path(out.exr).extension() != ".exr")
        usage_error("output '{}' must end in .exr", out.exr);
    const auto& comps = exr_compressions();
    if (std::find(comps.begin(), comps.end(), a.compression) == comps.end())
        usage_error("unknown EXR compression '{}' (valid: {})", a.compression,
                    fmt::join(comps, ", "));
    out.preview = a.no_preview
                      ? std::string()
                      : (a.preview.empty() ? fs::path(out.exr).replace_extension(".png").string()
                                           : a.preview);
    if (!out.preview.empty() && same_file(out.exr, out.preview))
        usage_error(
            "the EXR and the PNG preview are the same file '{}': give --preview another "
            "path or --no-preview",
            out.exr);
    if (same_file(out.exr, a.scene)) usage_error("the output '{}' is the scene file", out.exr);
    check_writable(out.exr, "EXR");
    if (!out.preview.empty()) check_writable(out.preview, "PNG preview");
    out.exr_options.half = !a.full_float;
    out.exr_options.compression = a.compression;
    out.scene = a.scene;
    out.display = a.display;
    out.view = a.view;
    if (!a.spp_range.empty()) parse_spp_range(a.spp_range, out.spp_first, out.spp_end);
    return out;
}

void warn_nonfinite(const Logger& log, const RenderStats& st) {
    if (st.nonfinite > 0)
        log.warn(
            "{} non-finite sample values were replaced by black; the first at pixel ({}, {}), "
            "sample {}",
            st.nonfinite, st.first_bad_pixel_x, st.first_bad_pixel_y, st.first_bad_sample);
}

/** The live preview page when --serve asks for one. */
std::unique_ptr<PreviewServer> start_server(const RenderArgs& a) {
    if (a.serve.empty()) return nullptr;
    auto server = std::make_unique<PreviewServer>(a.serve);
    fmt::print("live preview at {}\n", server->url());  // even with --quiet: it was asked for
    std::fflush(stdout);
    return server;
}

int run_render(const RenderArgs& a) {
    Logger log;
    if (a.quiet) log.threshold = LogLevel::Warning;
    const Outputs out = outputs_for(a);
    install_signal_handlers();

    FrameRequest req;
    req.scene = a.scene;
    req.plugin_dirs = a.plugin_dirs;
    req.ocio_config = a.ocio;
    req.options = render_options(a);
    req.log = &log;
    Progress progress(::isatty(STDERR_FILENO) != 0);
    if (!a.quiet)
        req.options.progress = [&](uint64_t done, uint64_t total) { progress.update(done, total); };
    req.options.stop = [] { return stop_signal != 0; };
    // The colour config is only known once the frame has loaded it: the pass callback gets it
    // through this pointer, set by render_frame's caller below before any pass ends.
    const ColorConfig* color = nullptr;
    const SceneInfo* info = nullptr;
    std::unique_ptr<PreviewServer> server = start_server(a);
    req.options.preview_pass = a.pass_output || server;
    if (a.pass_output || server)
        req.options.on_pass = [&](const PassImage& p) {
            if (!color) return;
            if (server)
                server->publish_pass(p.image, p.width, p.height, p.spp, p.target, p.block, *color);
            if (a.pass_output) out.write_pass(p, *color, info);
        };
    if (server) {
        auto print = req.options.progress;
        req.options.progress = [&, print](uint64_t done, uint64_t total) {
            if (print) print(done, total);
            server->progress(done, total);
        };
    }
    req.on_loaded = [&](const ColorConfig& c, const SceneInfo& i) {
        // A display or view the config lacks is an error before any rendering.
        std::string display = out.display, view = out.view;
        c.resolve_view(display, view);
        warn_if_no_chromaticities(log, c);
        color = &c;
        info = &i;
    };

    FrameResult frame = render_frame(req);
    progress.finish();
    if (server && !frame.image.empty())
        server->publish_pass(frame.image, frame.width, frame.height, frame.stats.spp_reached,
                             frame.stats.spp_target, 1, frame.color);
    if (frame.image.empty() && stop_signal == 0)
        throw_error("the scene has no camera to render from");
    warn_nonfinite(log, frame.stats);
    const bool partial = frame.stats.spp_reached < frame.stats.spp_target;
    if (frame.stats.spp_reached == 0) {
        log.warn("stopped by a signal before the first pass ended: no image written");
        return exit_status_for_signal();
    }
    warn_half_overflow(
        log,
        out.write(frame.image, frame.width, frame.height, frame.color, frame.stats.spp_reached,
                  partial, 1, &frame.info, frame.stats.seconds, &frame.layers, &frame.layer_names,
                  &frame.window, &frame.sums, frame.stats.spp_frame),
        out.exr);
    if (partial)
        log.warn("stopped by a signal: wrote {} with {} of {} samples per pixel", out.exr,
                 frame.stats.spp_reached, frame.stats.spp_target);
    if (a.stats)
        print_stats(frame, out.exr);
    else if (!a.quiet)
        log.info("wrote {}{}", out.exr, out.preview.empty() ? "" : " and " + out.preview);
    return partial ? exit_status_for_signal() : 0;
}

/** The output path of frame f: a run of '#' in `pattern` becomes f zero-padded to the run's
 *  length; without one, ".####" goes before the extension. */
std::string frame_path(const std::string& pattern, int64_t f) {
    const std::string name = fs::path(pattern).filename().string();
    const std::size_t at = name.find('#');
    std::string out;
    if (at != std::string::npos) {
        std::size_t run = at;
        while (run < name.size() && name[run] == '#') ++run;
        const std::string num = fmt::format("{:0{}d}", f, run - at);
        out = name.substr(0, at) + num + name.substr(run);
    } else {
        const fs::path p(name);
        out = fmt::format("{}.{:04d}{}", p.stem().string(), f, p.extension().string());
    }
    return (fs::path(pattern).parent_path() / out).string();
}

/** --frames A..B or A (frame numbers, A <= B). */
std::pair<int64_t, int64_t> parse_frames(const std::string& text) {
    const auto number = [&](const std::string& t) -> int64_t {
        const std::size_t digits = t.find_first_not_of("-0123456789");
        if (t.empty() || t.size() > 10 || digits != std::string::npos ||
            t.find('-', 1) != std::string::npos || t == "-")
            usage_error("--frames must be A..B or A (frame numbers), got '{}'", text);
        return std::stoll(t);
    };
    const std::size_t dots = text.find("..");
    const int64_t a = number(dots == std::string::npos ? text : text.substr(0, dots));
    const int64_t b = dots == std::string::npos ? a : number(text.substr(dots + 2));
    if (b < a) usage_error("--frames {}: the last frame comes before the first", text);
    if (b - a >= 1000000) usage_error("--frames {}: more than a million frames", text);
    return {a, b};
}

/** `spangle render --frames A..B`: one session renders frame after frame; between frames only
 *  what the keyframes moved is rebuilt (transforms: the top-level BVH; the camera: nothing). */
int run_frames(const RenderArgs& a) {
    Logger log;
    if (a.quiet) log.threshold = LogLevel::Warning;
    const auto [first, last] = parse_frames(a.frames);
    const Outputs pattern = outputs_for(a);
    install_signal_handlers();
    RenderOptions options = render_options(a);
    Session session(a.plugin_dirs, a.ocio, options, log);
    session.options().stop = [] { return stop_signal != 0; };
    for (int64_t f = first; f <= last; ++f) {
        const auto t0 = std::chrono::steady_clock::now();
        // The frame's time comes from the scene's frame_start and fps (read once loaded).
        const double time = session.has_scene() ? frame_time(session.info(), f) : 0.0;
        ReloadReport rep = session.load(a.scene, time);
        if (rep.first && frame_time(session.info(), f) != time)
            rep = session.load(a.scene, frame_time(session.info(), f));
        if (f == first) {
            std::string display = pattern.display, view = pattern.view;
            session.color().resolve_view(display, view);
            if (!session.info().animated)
                log.warn("{}: nothing in the scene has keyframes: every frame is the same image",
                         a.scene);
        }
        session.render();
        const RenderResult& w = session.result();
        const RenderStats& st = w.stats;
        const bool complete = st.spp_reached == st.spp_target;
        if (st.spp_reached == 0) {
            log.warn("stopped by a signal before frame {} had a pass: not written", f);
            return exit_status_for_signal();
        }
        Outputs out = pattern;
        out.exr = frame_path(pattern.exr, f);
        if (!out.preview.empty()) out.preview = frame_path(pattern.preview, f);
        warn_half_overflow(log,
                           out.write(w.image, w.width, w.height, session.color(), st.spp_reached,
                                     !complete, 1, &session.info(), st.seconds, &w.layers,
                                     &w.layer_names, &w.window, &w.sums, st.spp_frame),
                           out.exr);
        warn_nonfinite(log, st);
        if (!a.quiet)
            fmt::print("frame {} ({:.3f} s): {:.2f} s, ran: {}; wrote {}\n", f,
                       frame_time(session.info(), f),
                       std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                       rep.ran.empty() ? std::string("nothing")
                                       : fmt::format("{}", fmt::join(rep.ran, ", ")),
                       out.exr);
        std::fflush(stdout);
        if (!complete) {
            log.warn("stopped by a signal: frame {} has {} of {} samples per pixel", f,
                     st.spp_reached, st.spp_target);
            return exit_status_for_signal();
        }
    }
    return 0;
}

#ifdef SPANGLE_HAVE_MPI
/** Ends a rank quietly with `code` after the rank that should speak has printed why. */
struct RankExit {
    int code;
};

/** `mpirun -np N spangle render ...`: every rank loads the scene; the image (or each frame of
 *  --frames) is cut into bands handed out on request; rank 0 writes it. */
int run_render_mpi(const RenderArgs& a, const MpiJob& job) {
    Logger log;
    // The other ranks would repeat rank 0's notes and warnings: they report errors only.
    if (a.quiet || job.rank() != 0)
        log.threshold = job.rank() != 0 ? LogLevel::Error : LogLevel::Warning;
    // A step every rank takes: when one fails, the first rank that failed says why (rank 0
    // with the one-process message, another rank naming itself) and every rank ends.
    const auto together = [&](const std::function<void()>& step) {
        std::string error;
        int code = 1;
        try {
            step();
        } catch (const UsageError& e) {
            error = e.what();
            code = 2;
        } catch (const std::exception& e) {
            error = e.what();
        }
        const std::vector<int> failed = job.failed_ranks(error.empty());
        if (failed.empty()) return;
        if (!error.empty() && failed.front() == job.rank())
            print_error(job.rank() == 0 ? error : job.who() + ": " + error);
        throw RankExit{code};
    };
    Outputs out;
    RenderOptions options = render_options(a);
    options.progressive = false;  // one pass per band: the same sums, bit for bit
    options.preview_pass = false;
    if (a.threads == 0) {
        // Ranks sharing a machine share its cores (unless the launcher bound each to its own).
        const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
        cpu_set_t set;
        const bool bound = sched_getaffinity(0, sizeof(set), &set) == 0 &&
                           static_cast<unsigned>(CPU_COUNT(&set)) < cores;
        const int local = launcher_info().local_size;
        options.threads = bound ? CPU_COUNT(&set) : std::max(1, static_cast<int>(cores) / local);
        if (bound && job.rank() == 0 && options.threads * local < static_cast<int>(cores))
            log.warn(
                "the launcher bound each rank to {} of this machine's {} cores ({} ranks here): "
                "run mpirun with --bind-to none (spangle then shares the cores among the ranks) "
                "or give each rank its cores (--map-by node:PE=N)",
                options.threads, cores, local);
    }
    std::unique_ptr<Session> session;
    together([&] {
        if (job.rank() == 0) out = outputs_for(a);
        session = std::make_unique<Session>(a.plugin_dirs, a.ocio, options, log);
    });
    std::vector<std::pair<int64_t, bool>> frames;  // (frame, is a frame of --frames)
    if (a.frames.empty()) {
        frames.emplace_back(0, false);
    } else {
        const auto [first, last] = parse_frames(a.frames);
        for (int64_t f = first; f <= last; ++f) frames.emplace_back(f, true);
    }
    Progress progress(::isatty(STDERR_FILENO) != 0);
    for (const auto& [f, numbered] : frames) {
        together([&] {
            const double time =
                numbered && session->has_scene() ? frame_time(session->info(), f) : 0.0;
            const ReloadReport rep = session->load(a.scene, time);
            if (numbered && rep.first && frame_time(session->info(), f) != time)
                session->load(a.scene, frame_time(session->info(), f));
            if (job.rank() == 0 && f == frames.front().first) {
                std::string display = out.display, view = out.view;
                session->color().resolve_view(display, view);
                warn_if_no_chromaticities(log, session->color());
            }
        });
        DistributedImage img;
        if (!job.render(
                *session, options.crop, a.band_rows,
                a.quiet ? std::function<void(uint64_t, uint64_t)>()
                        : [&](uint64_t d, uint64_t t) { progress.update(d, t); },
                img))
            throw RankExit{1};
        if (job.rank() != 0) continue;
        progress.finish();
        try {
            Outputs o = out;
            if (numbered) {
                o.exr = frame_path(out.exr, f);
                if (!o.preview.empty()) o.preview = frame_path(out.preview, f);
            }
            warn_nonfinite(log, img.stats);
            warn_half_overflow(
                log,
                o.write(img.image, img.width, img.height, session->color(), img.stats.spp_reached,
                        false, 1, &session->info(), img.stats.seconds, &img.layers,
                        &img.layer_names, &img.window),
                o.exr);
            if (!a.quiet) {
                std::string ranks;
                for (std::size_t r = 0; r < img.loads.size(); ++r)
                    ranks += fmt::format("{}{}: {} bands {:.2f} s", r ? "; " : "", r,
                                         img.loads[r].units, img.loads[r].busy);
                fmt::print(
                    "{}{:.2f} s over {} ranks ({} bands of {} tile rows; {}); balance "
                    "(busiest / mean) {:.3f}; wrote {}\n",
                    numbered ? fmt::format("frame {}: ", f) : std::string(), img.stats.seconds,
                    img.loads.size(), img.units, std::max(a.band_rows, 1u), ranks, img.balance(),
                    o.exr);
                std::fflush(stdout);
            }
        } catch (const std::exception& e) {
            // The other ranks wait for the next step: end them all.
            print_error(e.what());
            job.abort(1);
        }
    }
    return 0;
}
#endif

/** `spangle render --watch`: render, then watch every input and re-render incrementally on each
 *  save until a signal. */
int run_watch(const RenderArgs& a) {
    Logger log;
    if (a.quiet) log.threshold = LogLevel::Warning;
    const Outputs out = outputs_for(a);
    const bool pass_output = !a.no_pass_output;
    install_signal_handlers();

    RenderOptions options = render_options(a);
    options.preview_pass = pass_output || !a.serve.empty();
    Session session(a.plugin_dirs, a.ocio, options, log);
    {
        // A display or view the config lacks is an error before any rendering.
        std::string display = out.display, view = out.view;
        session.color().resolve_view(display, view);
    }
    std::atomic<bool> reload{false};
    session.options().stop = [&] { return stop_signal != 0 || reload.load(); };
    // Declared after the session: it shows images in the session's colour config.
    const std::unique_ptr<PreviewServer> server = start_server(a);
    if (server)
        session.options().progress = [&](uint64_t done, uint64_t total) {
            server->progress(done, total);
        };
    // Reload lines and errors go to the terminal and the page.
    auto say = [&](const std::string& line) {
        fmt::print("{}\n", line);
        std::fflush(stdout);
        if (server) server->log("info", line);
    };
    auto report_error = [&](const std::string& message) {
        print_error(message);
        if (server) server->log("error", message);
    };

    // What the render thread reports back.
    std::mutex mutex;
    std::string pending_line;  // the reload line, printed when the first pass is written
    std::chrono::steady_clock::time_point changed_at;
    bool finished = false;

    std::string preview_note;  // when the preview pass of the pending change was written
    // The reload line goes out once the first full pass is written (with the preview's time
    // when there was one); a change that interrupts the render first prints it as it stands.
    auto announce = [&](uint32_t spp, uint32_t block) {
        std::lock_guard<std::mutex> lock(mutex);
        if (pending_line.empty()) return;
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - changed_at).count();
        if (spp == 0) {
            preview_note = fmt::format("preview (1/{} resolution) written {:.3f} s, ", block, s);
            return;
        }
        say(fmt::format("{}; {}first pass ({} spp) written {:.3f} s after the change", pending_line,
                        preview_note, spp, s));
        pending_line.clear();
        preview_note.clear();
    };
    auto flush_unannounced = [&] {
        std::lock_guard<std::mutex> lock(mutex);
        if (pending_line.empty()) return;
        say(fmt::format("{}; {}interrupted by the next change", pending_line, preview_note));
        pending_line.clear();
        preview_note.clear();
    };
    session.options().on_pass = [&](const PassImage& p) {
        if (server)
            server->publish_pass(p.image, p.width, p.height, p.spp, p.target, p.block,
                                 session.color());
        if (!pass_output) return;
        try {
            out.write_pass(p, session.color(), &session.info());
        } catch (const SpangleError& e) {
            report_error(e.what());
        }
        announce(p.spp, p.block);
    };

    auto render_thread = [&] {
        return std::thread([&] {
            try {
                session.render();
            } catch (const std::exception& e) {
                // A render that fails (a texture whose cached tiles vanished, memory) is
                // reported; the session waits for the next save.
                report_error(e.what());
                return;
            }
            const RenderResult& w = session.result();
            if (w.image.empty()) return;
            warn_if_no_chromaticities(log, session.color());
            const RenderStats& st = w.stats;
            const bool complete = st.spp_reached == st.spp_target;
            if (complete || (stop_signal != 0 && st.spp_reached > 0)) {
                if (server)
                    server->publish_pass(w.image, w.width, w.height, st.spp_reached, st.spp_target,
                                         1, session.color());
                try {
                    warn_half_overflow(log,
                                       out.write(w.image, w.width, w.height, session.color(),
                                                 st.spp_reached, !complete, 1, &session.info(),
                                                 st.seconds, &w.layers, &w.layer_names, &w.window),
                                       out.exr);
                } catch (const SpangleError& e) {
                    report_error(e.what());
                }
                announce(st.spp_reached, 1);
            }
            if (complete) {
                warn_nonfinite(log, st);
                log.info("wrote {} ({} spp); watching for changes", out.exr, st.spp_reached);
                if (server)
                    server->log("info", fmt::format("wrote {} ({} spp); watching for changes",
                                                    out.exr, st.spp_reached));
                std::lock_guard<std::mutex> lock(mutex);
                finished = true;
            }
        });
    };

    auto load = [&](const std::string& what) {
        try {
            const ReloadReport rep = session.load(a.scene);
            std::lock_guard<std::mutex> lock(mutex);
            pending_line = rep.first ? fmt::format("loaded {} in {:.3f} s", a.scene, rep.seconds)
                                     : fmt::format("reload ({}): {}; applied in {:.3f} s", what,
                                                   rep.summary(), rep.seconds);
            return true;
        } catch (const SpangleError& e) {
            report_error(e.what());
            say(fmt::format("reload failed; {}", session.has_scene()
                                                     ? "still showing the last good scene"
                                                     : "waiting for a good save"));
            return false;
        }
    };

    FileWatcher watcher;
    changed_at = std::chrono::steady_clock::now();
    load("first load");
    std::thread worker;
    if (session.has_scene()) worker = render_thread();
    for (;;) {
        std::vector<std::string> files = session.watched_files();
        files.push_back(a.scene);
        watcher.watch(files);
        std::vector<std::string> touched;
        while (touched.empty() && stop_signal == 0) touched = watcher.wait(250);
        if (stop_signal != 0) break;
        {
            std::lock_guard<std::mutex> lock(mutex);  // the render thread reads it in announce
            changed_at = std::chrono::steady_clock::now();
        }
        reload = true;
        if (worker.joinable()) worker.join();
        reload = false;
        flush_unannounced();
        std::string what;
        for (const auto& f : touched)
            what += (what.empty() ? "" : ", ") + fs::path(f).filename().string();
        bool interrupted = false;
        {
            std::lock_guard<std::mutex> lock(mutex);
            interrupted = !finished;
            finished = false;
        }
        const bool ok = load(what);
        // A failed reload keeps the last good scene: its image stays on disk, and a render of it
        // that the change interrupted goes on.
        if (session.has_scene() && (ok || interrupted))
            worker = render_thread();
        else {
            std::lock_guard<std::mutex> lock(mutex);
            finished = true;
        }
    }
    if (worker.joinable()) worker.join();
    return exit_status_for_signal();
}

int run_plugins(const std::vector<std::string>& dirs) {
    PluginLoader loader(plugin_search_path(dirs));
    fmt::print("plugin search path:\n");
    for (const auto& d : loader.search_path()) fmt::print("  {}\n", d);
    const auto files = loader.discover();
    if (files.empty()) fmt::print("no plugins found\n");
    int bad = 0;
    for (const auto& f : files) {
        try {
            auto p = PluginLoader::open_file(f, "");
            const SpangleMaterialPlugin_v3& t = p->table();
            fmt::print("\n{} ({}): {}\n", t.name, f, t.doc ? t.doc : "");
            for (uint32_t m = 0; m < t.model_count; ++m) {
                const SpangleMaterialModel_v3& model = t.models[m];
                fmt::print("  model {}: {}\n", model.name, model.doc ? model.doc : "");
                for (uint32_t k = 0; k < model.param_count; ++k)
                    fmt::print("    {}\n", describe_param(model.params[k]));
            }
        } catch (const SpangleError& e) {
            fmt::print("\n{}: not usable: {}\n", f, e.what());
            ++bad;
        }
    }
    return bad > 0 ? 1 : 0;
}

int run_inspect(const std::string& path) {
    ImageHeader spec;
    const std::vector<float> all = read_image(path, 3, spec);
    if (spec.channels < 3) throw_error("'{}' has {} channels; expected RGB", path, spec.channels);
    const std::vector<float>& rgb = all;
    const ImageMetrics m = measure_image(rgb, spec.width, spec.height);
    fmt::print("{}: {}x{}\n", path, spec.width, spec.height);
    fmt::print("mean luminance: {:.6g}\nnon-finite pixels: {}\nnegative pixels: {}\n",
               m.mean_luminance, m.nonfinite, m.negative);
    fmt::print("fireflies (> 10x the 3x3 median): {} ({:.4f}% of pixels)\n", m.fireflies,
               100.0 * m.firefly_fraction);
    return 0;
}

}  // namespace
}  // namespace spangle

int main(int argc, char** argv) {
    using namespace spangle;
    CLI::App app{"Spangle: a physically based renderer for glittering surfaces"};
    app.set_version_flag("--version", std::string("spangle ") + SPANGLE_VERSION);
    app.require_subcommand(1);

    RenderArgs ra;
    CLI::App* render = app.add_subcommand("render", "render a scene file to a colour-managed EXR");
    render->add_option("scene", ra.scene, "scene file (TOML)")->required();
    render->add_option("-o,--output", ra.output, "output EXR (default: <scene name>.exr)");
    render->add_option("--preview", ra.preview, "PNG preview path (default: the output with .png)");
    render->add_flag("--no-preview", ra.no_preview, "write no PNG preview");
    render->add_option("--size", ra.size, "image size WIDTHxHEIGHT (overrides the scene)");
    render->add_option("--spp", ra.spp, "samples per pixel (overrides the scene)")
        ->check(CLI::Range(1u, 1u << 20));
    render->add_option("--threads", ra.threads, "worker threads (default: all cores)")
        ->check(CLI::Range(1, 1024));
    render->add_option("--plugin-path", ra.plugin_dirs,
                       "directory searched for plugins first (repeatable)");
    render->add_flag("--stats", ra.stats, "print which systems ran and render statistics");
    render->add_option("--frames", ra.frames,
                       "render frames A..B (or A) of the scene's keyframed animation, each to the "
                       "output with its number ('#' runs in -o are the number, else .####)");
    render->add_option("--spp-range", ra.spp_range,
                       "render samples A..B-1 of the frame's (A..B); spangle merge adds parts of "
                       "one frame into exactly the whole render (docs/crop_merge.md)");
    render->add_option("--crop", ra.crop,
                       "render only the window x0,y0,x1,y1 of the image (pixels [x0, x1) x [y0, "
                       "y1)); the EXR's data window places it in the full frame; spangle merge "
                       "assembles the parts bit for bit");
    render
        ->add_option("--band-rows", ra.band_rows,
                     "under mpirun: tile rows (16 pixels each) per unit of work handed to a rank "
                     "(default 1)")
        ->check(CLI::Range(1u, 4096u));
    render->add_flag("--layers", ra.layers,
                     "write render layers into the EXR beside the beauty: A (coverage), albedo, "
                     "N, Z, P, glints, and lightgroup_<name> per light group (docs/layers.md)");
    render->add_option("--view", ra.view,
                       "OCIO view of the PNG preview (default: the display's default view; the "
                       "shipped config's is \"Glint\", a hue-preserving tone map; \"Standard\" "
                       "clips at 1)");
    render->add_option("--display", ra.display,
                       "OCIO display of the PNG preview (default: the config's default display)");
    render->add_option("--texture-cache", ra.texture_cache,
                       "folder for textures converted to the working space (default: "
                       "$SPANGLE_TEXTURE_CACHE, else $XDG_CACHE_HOME/spangle/textures, else "
                       "~/.cache/spangle/textures)");
    render
        ->add_option("--texture-memory", ra.texture_memory_mb,
                     "MiB the texture tile cache may hold (default 1024)")
        ->check(CLI::Range(16u, 1u << 20));
    render->add_flag("--float", ra.full_float, "write 32-bit float EXR instead of half");
    render->add_option("--compression", ra.compression, "EXR compression (default zip)");
    render->add_option("--ocio", ra.ocio,
                       "OpenColorIO config (default: $OCIO, then the shipped one)");
    render->add_flag("-q,--quiet", ra.quiet, "no progress or info output");
    render
        ->add_option("--strategy", ra.strategy,
                     "light transport estimator: mis (default), nee or bsdf (for debugging)")
        ->check(CLI::IsMember({"mis", "nee", "bsdf"}));
    render->add_flag("--watch", ra.watch,
                     "keep running: re-render incrementally whenever the scene or a file it "
                     "uses is saved (stop with Ctrl-C)");
    render->add_flag("--pass-output", ra.pass_output,
                     "write the EXR and preview after every pass (on by default with --watch)");
    render->add_flag("--no-pass-output", ra.no_pass_output,
                     "with --watch: write only finished images");
    render
        ->add_option("--serve", ra.serve,
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

    std::vector<std::string> plugin_dirs;
    CLI::App* plugins =
        app.add_subcommand("plugins", "list the plugins found and their parameters");
    plugins->add_option("--plugin-path", plugin_dirs,
                        "directory searched for plugins first (repeatable)");

    std::string inspect_path;
    CLI::App* inspect =
        app.add_subcommand("inspect", "measure an image: mean, non-finite pixels, fireflies");
    inspect
        ->add_option("image", inspect_path,
                     "EXR (or any image OpenImageIO reads, through its module)")
        ->required();

    std::vector<std::string> merge_parts;
    std::string merge_out;
    CLI::App* merge = app.add_subcommand(
        "merge",
        "assemble crop windows (render --crop) or add sample ranges (render --spp-range) into "
        "the whole render, bit for bit");
    merge->add_option("parts", merge_parts, "the parts' EXR files")->required();
    merge->add_option("-o,--output", merge_out, "the full frame's EXR")->required();

    std::vector<std::string> flicker_frames;
    double flicker_threshold = 0.0;
    CLI::App* flicker = app.add_subcommand(
        "flicker", "measure how glints flicker in a sequence rendered with --frames --layers");
    flicker->add_option("frames", flicker_frames, "the frames' EXRs, in order")->required();
    flicker
        ->add_option("--threshold", flicker_threshold,
                     "glint-mask threshold (glints layer luminance; default 4 x its mean)")
        ->check(CLI::Range(0.0, 1e30));

    BenchArgs ba;
    std::string write_scene;
    CLI::App* bench = app.add_subcommand(
        "bench", "render fixed scenes and print samples and rays per second, phase times, memory");
    bench->add_option("scenes", ba.scenes,
                      "scene files, shipped scene names, or 'interior' (default: demo materials "
                      "beetle interior)");
    bench->add_option("--size", ba.size,
                      "image size of every scene (default 640x360; '' = the scene's)");
    bench->add_option("--spp", ba.spp, "samples per pixel (default 16)")
        ->check(CLI::Range(1u, 1u << 20));
    bench->add_option("--threads", ba.threads, "worker threads (default: all cores)")
        ->check(CLI::Range(1, 1024));
    bench->add_option("--repeat", ba.repeat, "renders per scene, the fastest counts (default 1)")
        ->check(CLI::Range(1, 100));
    bench->add_option("--plugin-path", ba.plugin_dirs, "directory searched for plugins first");
    bench->add_option("--work-dir", ba.work_dir,
                      "where the interior scene is written (default: a folder in the temp dir)");
    bench->add_option("--csv", ba.csv, "also write the results as CSV");
    bench->add_option("--export-obj", ba.export_obj,
                      "with one scene: also write the triangles it traces (world space) as an OBJ, "
                      "for Embree's viewer");
    bench->add_flag("--measure-one", ba.measure_one)->group("");  // internal: one child's render
    bench->add_option("--write-scene", write_scene,
                      "only write the procedural interior scene into this folder");

    // An unknown first word is a misspelt command, not a missing one.
    if (argc > 1 && argv[1][0] != '-') {
        const std::string word = argv[1];
        std::vector<std::string> commands;
        for (const CLI::App* sub : app.get_subcommands({})) commands.push_back(sub->get_name());
        if (std::find(commands.begin(), commands.end(), word) == commands.end()) {
            fmt::print(stderr,
                       "spangle: error: unknown command '{}'{} (the commands are {}; "
                       "spangle --help)\n",
                       word, did_you_mean(word, commands), fmt::join(commands, ", "));
            return 2;
        }
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    try {
        if (*render && !ra.spp_range.empty()) {
            if (ra.layers)
                usage_error(
                    "--spp-range parts carry the beauty's exact sums, not the layers': render "
                    "--layers without --spp-range");
            if (ra.watch) usage_error("--spp-range renders a part of a frame; --watch a whole one");
            if (launcher_info().size > 1)
                usage_error("--spp-range is for one process (under mpirun, ranks share the image)");
        }
        if (*render && launcher_info().size > 1) {
            // Started by mpirun (or srun) as one of several ranks.
            if (ra.watch || ra.pass_output || !ra.serve.empty())
                usage_error(
                    "--watch, --pass-output and --serve are for one process; under mpirun "
                    "spangle renders a still or --frames and rank 0 writes them");
#ifdef SPANGLE_HAVE_MPI
            MpiJob job(argc, argv);
            try {
                return run_render_mpi(ra, job);
            } catch (const RankExit& e) {
                return e.code;
            }
#else
            usage_error(
                "this spangle was built without MPI, so each of the {} ranks would render the "
                "whole image: run it as one process, or rebuild with libopenmpi-dev installed "
                "(SPANGLE_MPI=ON)",
                launcher_info().size);
#endif
        }
        if (*render) {
            if (!ra.frames.empty() && ra.watch)
                usage_error(
                    "--frames renders a sequence and ends; --watch keeps one frame live: "
                    "choose one");
            if (!ra.frames.empty()) return run_frames(ra);
            return ra.watch ? run_watch(ra) : run_render(ra);
        }
        if (*plugins) return run_plugins(plugin_dirs);
        if (*inspect) return run_inspect(inspect_path);
        if (*flicker) {
            const FlickerReport r = measure_flicker(flicker_frames, flicker_threshold);
            fmt::print(
                "frames: {} ({} pairs), pixels compared: {:.0f} (points carried by {})\n"
                "glint mask threshold: {:.4g}, mask coverage: {:.4f}\n"
                "mask flicker (mean |mask_k - mask_k+1| of reprojected pixels): {:.4f}\n"
                "glint persistence (glint pixels still glints in the next frame): {:.4f}\n"
                "relative glint difference (mean |g_k - g_k+1| / mean g): {:.4f}\n",
                flicker_frames.size(), r.pairs, r.pixels,
                r.by_objects ? "their objects" : "world position", r.threshold, r.mask_fraction,
                r.mask_flicker, r.mask_persistence, r.relative_difference);
            return 0;
        }
        if (*merge) {
            for (const std::string& p : merge_parts)
                if (same_file(p, merge_out))
                    usage_error("the output '{}' is one of the parts", merge_out);
            if (fs::path(merge_out).extension() != ".exr")
                usage_error("output '{}' must end in .exr", merge_out);
            check_writable(merge_out, "EXR");
            const MergeReport rep = merge_exr_parts(merge_parts, merge_out);
            if (rep.sample_ranges > 0) {
                fmt::print("added {} sample ranges into {} ({}x{} frame)\n", rep.sample_ranges,
                           merge_out, rep.width, rep.height);
                return 0;
            }
            fmt::print(
                "merged {} parts into {} ({}x{}{})\n", rep.parts, merge_out, rep.width, rep.height,
                rep.overlap_pixels
                    ? fmt::format(", {} pixels held by more than one part", rep.overlap_pixels)
                    : std::string());
            return 0;
        }
        if (*bench) {
            if (!write_scene.empty()) {
                fmt::print("wrote {}\n", write_interior_scene(write_scene));
                return 0;
            }
            if (!ba.size.empty()) parse_size(ba.size, ba.width, ba.height);
            return run_bench(ba);
        }
    } catch (const UsageError& e) {
        if (launcher_info().rank == 0) print_error(e.what());  // ranks > 0: rank 0 says it
        return 2;
    } catch (const SpangleError& e) {
        print_error(e.what());
        return 1;
    } catch (const std::logic_error& e) {
        fmt::print(stderr, "spangle: {}\n", e.what());
        return 3;
    } catch (const std::exception& e) {
        print_error(e.what());
        return 1;
    }
    return 0;
}
