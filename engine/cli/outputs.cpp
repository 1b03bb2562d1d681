// The outputs module: see outputs.h.

#include "cli/outputs.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <future>
#include <optional>

#include "cli/arguments.h"
#include "cli/output_paths.h"
#include "cli/usage.h"
#include "color/color_config.h"
#include "color/temporary_files.h"
#include "core/check.h"
#include "core/cryptomatte.h"
#include "core/error.h"
#include "render/camera.h"
#include "render/denoise.h"
#include "render/layers/layer_sink.h"
#include "render/render_scene.h"
#include "scene/frame_sequence.h"
#include "scene/scene_loader.h"

#ifndef SPANGLE_VERSION
#define SPANGLE_VERSION "0.0.0"
#endif

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** The header attributes a scene's camera and objects give: the matrices pbrt-v4 writes and
 *  Nuke reads (OpenEXR's standard attributes), and with the layers where each object stands. */
void add_scene_attributes(ExrOptions& o, const ImageDescription& d, uint32_t frame_w,
                          uint32_t frame_h) {
    const Camera& c = d.info->camera;
    const CameraModel model = CameraModel::of(c, frame_w, frame_h);
    const CameraMatrices m = model.matrices();
    o.matrices = {{"worldToCamera", m.world_to_camera}};
    // A panorama projects onto no plane: it has no worldToNDC (spangle flicker says so).
    if (model.projects_to_ndc()) o.matrices.push_back({"worldToNDC", m.world_to_ndc});
    // Which scene (its files' bytes) and which moment: spangle merge refuses parts that differ.
    o.metadata.emplace_back("spangle:sceneHash", fmt::format("{:016x}", d.info->content_hash));
    o.metadata.emplace_back("spangle:time", fmt::format("{}", d.info->time));
    // A frame whose motion was blurred (spangle flicker warns: its glints are streaks).
    if (d.info->motion_blur)
        o.metadata.emplace_back("spangle:shutter",
                                fmt::format("{} {}", d.info->shutter_open, d.info->shutter_close));
    // With the layers: where each object stands (12 floats each, the rows of its 3x4
    // object-to-world matrix), so that Pobj carries a point into world space and a sequence's
    // frames can follow a turning object (spangle flicker).
    if (d.layers && !d.layers->empty()) {
        std::vector<float> xf;
        for (const Affine& a : d.info->object_to_world)
            for (int r = 0; r < 3; ++r)
                xf.insert(xf.end(), {a.m[r][0], a.m[r][1], a.m[r][2], a.t[r]});
        o.float_vectors.emplace_back("spangle:objectToWorld", std::move(xf));
        // Which objects deform: their Pobj is the rest pose's, the same at the same spot of the
        // surface in every frame.
        if (!d.info->rest_pose.empty()) {
            std::vector<float> rest(d.info->object_to_world.size(), 0.0f);
            for (std::size_t k = 0; k < d.info->rest_pose.size() && k < rest.size(); ++k)
                rest[k] = static_cast<float>(d.info->rest_pose[k]);
            o.float_vectors.emplace_back("spangle:restPose", std::move(rest));
        }
    }
}

/** The header attributes of the layers: which channels are data (written as 32-bit floats)
 *  and, for each Cryptomatte, its name, hash, conversion and manifest under the key the
 *  specification derives from its name. */
void add_layer_attributes(ExrOptions& o, const ImageDescription& d) {
    std::string data;
    o.layer_full_float.clear();
    bool crypto = false;
    for (const std::string& n : o.layer_names) {
        const bool is_data = layer_channel_is_data(n);
        o.layer_full_float.push_back(is_data ? 1 : 0);
        if (is_data) data += (data.empty() ? "" : ",") + n;
        crypto = crypto || n.rfind("Crypto", 0) == 0;
    }
    o.metadata.emplace_back("spangle:dataChannels", data);
    if (!crypto || !d.info) return;
    const std::pair<const char*, const std::vector<std::string>*> kinds[] = {
        {"CryptoObject", &d.info->object_names}, {"CryptoMaterial", &d.info->material_names}};
    for (const auto& [layer, names] : kinds) {
        const std::string at = "cryptomatte/" + cryptomatte_key(layer) + "/";
        o.metadata.emplace_back(at + "name", layer);
        o.metadata.emplace_back(at + "hash", "MurmurHash3_32");
        o.metadata.emplace_back(at + "conversion", "uint32_to_float32");
        o.metadata.emplace_back(at + "manifest", cryptomatte_manifest(*names));
    }
}

/** The EXR options of `d` written as `out` says: its place in the frame, layers, header. */
ExrOptions exr_options_for(const Outputs& out, const ImageDescription& d) {
    ExrOptions o = out.exr_options;
    // A crop: the image is a data window of the full frame; the camera is the frame's.
    uint32_t frame_w = d.width, frame_h = d.height;
    if (d.window.full_width > 0) {
        frame_w = d.window.full_width;
        frame_h = d.window.full_height;
        o.origin_x = static_cast<int>(d.window.x0);
        o.origin_y = static_cast<int>(d.window.y0);
        o.display_width = static_cast<int>(frame_w);
        o.display_height = static_cast<int>(frame_h);
    }
    if (d.layers && d.layer_names && !d.layers->empty()) {
        o.layers = d.layers;
        o.layer_names = *d.layer_names;
    }
    o.metadata = {{"spangle:scene", out.scene},
                  {"spangle:version", SPANGLE_VERSION},
                  {"spangle:spp", std::to_string(d.spp)},
                  {"spangle:partial", d.partial ? "1" : "0"}};
    // How the samples were taken and whether the image was denoised: spangle merge refuses
    // parts that differ (adaptive crops of other thresholds made a quilt) or were denoised.
    if (!d.sampling.empty()) o.metadata.emplace_back("spangle:sampling", d.sampling);
    if (!d.denoised.empty()) o.metadata.emplace_back("spangle:denoised", d.denoised);
    // A --spp-range part: its samples' exact sums, for spangle merge. One a signal stopped holds
    // the samples of its completed passes, first..first+spp: a part of that range (merge then
    // names the samples still missing; it was written as a plain image that merge called "not
    // crops of one render").
    if (out.spp_end > 0 && d.sums && d.spp > 0 && d.block <= 1) {
        o.sums = d.sums;
        o.metadata.emplace_back("spangle:spp_range",
                                fmt::format("{}..{}", out.spp_first, out.spp_first + d.spp));
        o.metadata.emplace_back("spangle:spp_frame", std::to_string(d.spp_frame));
        if (!d.spread.empty()) o.metadata.emplace_back("spangle:filter_spread", d.spread);
    } else if (out.spp_end > 0 && d.spp > 0 && d.block <= 1) {
        // A pass image of a --spp-range render (--pass-output): samples of the range, without
        // the sums; it was labelled a render of the frame's first samples, which merge took.
        o.metadata.emplace_back("spangle:spp_range",
                                fmt::format("{}..{}", out.spp_first, out.spp_first + d.spp));
    }
    if (!out.strategy.empty()) o.metadata.emplace_back("spangle:strategy", out.strategy);
    if (d.seconds >= 0.0) o.floats.emplace_back("renderTimeSeconds", static_cast<float>(d.seconds));
    if (d.info) add_scene_attributes(o, d, frame_w, frame_h);
    if (o.layers) add_layer_attributes(o, d);
    // A reduced-resolution preview pass (0 spp, blocks of `block` pixels).
    if (d.block > 1) o.metadata.emplace_back("spangle:preview_stride", std::to_string(d.block));
    return o;
}

/** An exclusive lock on an output's pair of files (the EXR and its PNG), held while both are
 *  written: two renders of one output (a farm job queued twice) leave both files of one render
 *  (15 of 20 such races left the EXR of one and the PNG of the other). The lock is a hidden file
 *  beside the EXR, removed by its holder; one that cannot be made (a folder we may not write
 *  in is refused elsewhere) leaves the write unlocked. */
/** The lock files held now, for remove_locks_in_progress() to unlink from a signal handler: a
 *  few fixed slots (images may be written concurrently), each claimed by one lock. */
struct HeldLock {
    std::atomic<bool> claimed{false};
    std::atomic<bool> set{false};
    char path[4096];
};
HeldLock held_locks[4];

class OutputLock {
public:
    explicit OutputLock(const std::string& exr) {
        const fs::path p(exr);
        path_ = (p.parent_path() / fmt::format(".{}.lock", p.filename().string())).string();
        // Known to the signal handler (when a slot is free and the path fits: otherwise the
        // next render removes a lock left behind).
        for (HeldLock& h : held_locks)
            if (path_.size() < sizeof h.path && !h.claimed.exchange(true)) {
                std::copy(path_.begin(), path_.end(), h.path);
                h.path[path_.size()] = '\0';
                h.set.store(true);
                held_ = &h;
                break;
            }
        for (int tries = 0; tries < 1000; ++tries) {
            fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
            if (fd_ < 0) return;
            if (::flock(fd_, LOCK_EX) != 0) {
                ::close(fd_);
                fd_ = -1;
                return;
            }
            // Still the file at the path? Its holder removes it before unlocking: a lock taken
            // on the removed file locks nothing, so take the new one.
            struct stat held {
            }, named{};
            if (::fstat(fd_, &held) == 0 && ::stat(path_.c_str(), &named) == 0 &&
                held.st_dev == named.st_dev && held.st_ino == named.st_ino)
                return;
            ::close(fd_);
            fd_ = -1;
        }
    }
    ~OutputLock() {
        if (held_) {
            held_->set.store(false);
            held_->claimed.store(false);
        }
        if (fd_ < 0) return;
        ::unlink(path_.c_str());
        ::close(fd_);
    }
    OutputLock(const OutputLock&) = delete;
    OutputLock& operator=(const OutputLock&) = delete;

private:
    std::string path_;
    int fd_ = -1;
    HeldLock* held_ = nullptr;
};

}  // namespace

void remove_locks_in_progress() noexcept {
    for (const HeldLock& h : held_locks)
        if (h.set.load()) ::unlink(h.path);
}

ImageDescription pass_image(const PassImage& p, const ColorConfig& color, const SceneInfo* info) {
    ImageDescription d;
    d.image = &p.image;
    d.width = p.width;
    d.height = p.height;
    d.color = &color;
    d.spp = p.spp;
    d.partial = true;
    d.block = p.block;
    d.info = info;
    d.seconds = p.seconds;
    d.window = p.window;
    d.layers = p.layers;
    d.layer_names = p.layer_names;
    return d;
}

std::size_t Outputs::write(const ImageDescription& d) const {
    SPANGLE_CHECK(d.image && d.color, "an image to write needs its pixels and colour config");
    const ExrOptions o = exr_options_for(*this, d);
    const int width = static_cast<int>(d.width), height = static_cast<int>(d.height);
    // The PNG is written beside the EXR, on another thread. It shows the picture whole: the
    // premultiplied beauty over the environment kept apart in the layer `background`.
    const OutputLock lock(exr);
    std::future<void> png_done;
    std::vector<float> composite;
    const std::vector<float>* shown = d.image;
    if (!preview.empty() && o.layers) {
        const auto& names = o.layer_names;
        const auto at = std::find(names.begin(), names.end(), "background.R");
        if (at != names.end()) {
            const std::size_t lc = names.size(), b = static_cast<std::size_t>(at - names.begin());
            composite = *d.image;
            for (std::size_t p = 0; p < composite.size() / 3; ++p)
                for (std::size_t c = 0; c < 3; ++c)
                    composite[3 * p + c] += (*o.layers)[p * lc + b + c];
            shown = &composite;
        }
    }
    // The PNG goes to a temporary name of its own and takes its place only once the EXR is
    // written: an EXR that cannot be written (a full disk) leaves the old pair as it was, not a
    // new preview beside an old image.
    const std::string png_target = preview.empty() ? std::string() : output_target(preview);
    const std::string png_tmp = preview.empty() ? std::string() : temporary_path_for(png_target);
    // A second Ctrl-C while the EXR is written removes it too.
    std::optional<TemporaryInProgress> png_in_progress;
    if (!png_tmp.empty()) png_in_progress.emplace(png_tmp);
    const auto drop_png = [&] {
        std::error_code ec;
        if (!png_tmp.empty()) fs::remove(png_tmp, ec);
    };
    if (!preview.empty()) {
        PngOptions png;
        if (d.partial) png.compression_level = 1;  // passes come often: speed over size
        png.block = d.block;
        png.display = display;
        png.view = view;
        png_done = std::async(std::launch::async, [&, png] {
            write_png_preview(png_tmp, *shown, width, height, *d.color, png);
        });
    }
    std::size_t overflow = 0;
    try {
        overflow = write_exr(exr, *d.image, width, height, *d.color, o);
    } catch (...) {
        if (png_done.valid()) png_done.wait();
        drop_png();
        throw;
    }
    if (png_done.valid()) {
        try {
            png_done.get();  // rethrows its error
        } catch (const std::exception& e) {
            // The EXR is this render's: an older preview beside it would show another render.
            drop_png();
            std::error_code ec;
            const bool removed = fs::remove(png_target, ec);
            throw_error("cannot write the preview '{}'{}: {}", preview,
                        removed ? " (the older one was removed: the EXR is this render's)" : "",
                        e.what());
        }
        std::error_code ec;
        fs::rename(png_tmp, png_target, ec);
        if (ec) {
            drop_png();
            throw_error("cannot write the preview '{}': {}", preview, ec.message());
        }
    }
    return overflow;
}

void Outputs::write_image(const Logger& log, const ImageDescription& d) const {
    warn_half_overflow(log, write(d), exr);
}

void Outputs::write_pass(const PassImage& p, const ColorConfig& color,
                         const SceneInfo* info) const {
    write(pass_image(p, color, info));
}

Outputs Outputs::for_frame(int64_t f) const {
    Outputs o = *this;
    o.exr = frame_path(exr, f);
    if (!o.preview.empty()) o.preview = frame_path(preview, f);
    return o;
}

void Outputs::check_view(const ColorConfig& color) const {
    std::string d = display, v = view;
    color.resolve_view(d, v);
    // The preview's transform built once now (on one pixel): a LUT file the config names but
    // lacks was found after the whole render, with the EXR written and no PNG.
    if (!preview.empty()) {
        float rgb[3] = {0.18f, 0.18f, 0.18f};
        color.to_display(d, v, rgb, 1);
    }
}

void Outputs::check_not_inputs(const std::vector<std::string>& inputs, const char* exr_option,
                               const char* preview_option) const {
    for (const std::string& in : inputs)
        for (const auto& [path, what] : {std::pair{exr, "EXR"}, std::pair{preview, "PNG preview"}})
            if (!path.empty() && same_file(path, in))
                throw_error(
                    "the {} '{}' is {}a file the scene reads: the render would overwrite it; "
                    "give {} another path",
                    what, path, path == in ? "" : fmt::format("'{}', ", in),
                    path == exr ? exr_option : preview_option);
}

void Outputs::remove_stale_temporaries(const Logger& log) const {
    std::vector<fs::path> folders;
    for (const std::string& path : {exr, preview}) {
        if (path.empty()) continue;
        const fs::path dir = fs::path(path).parent_path();
        if (std::find(folders.begin(), folders.end(), dir) == folders.end()) folders.push_back(dir);
    }
    for (const fs::path& dir : folders) {
        const StaleTemporaries found = spangle::remove_stale_temporaries(dir.string());
        for (const std::string& p : found.removed)
            log.info("removed '{}', left by a render that was killed while writing it", p);
        for (const std::string& why : found.failed)
            log.warn("cannot remove the temporary image a killed render left: {}", why);
    }
}

namespace {

/** --frames: no frame's EXR or preview path is a folder (found after the frames before it had
 *  rendered, "...: Success"). The paths are otherwise checked once, as a pattern: a frame's
 *  EXR and preview keep their endings, .exr and .png, so they are never one file. */
void check_frame_paths(const Outputs& out, int64_t first, int64_t last) {
    for (int64_t f = first; f <= last; ++f) {
        const Outputs o = out.for_frame(f);
        for (const auto& [path, what] :
             {std::pair{o.exr, "EXR"}, std::pair{o.preview, "PNG preview"}}) {
            std::error_code ec;
            if (!path.empty() && fs::is_directory(path, ec))
                throw_error("cannot write frame {}'s {} '{}': it is a folder", f, what, path);
        }
    }
}

}  // namespace

Outputs outputs_for(const RenderArgs& a, bool check_paths) {
    Outputs out;
    out.exr = a.output.empty() ? fs::path(a.scene).stem().string() + ".exr" : a.output;
    if (!has_extension(out.exr, ".exr")) usage_error("output '{}' must end in .exr", out.exr);
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
    // Lossy for 32-bit floats: the ids, depth and positions of the layers would be corrupt.
    if ((a.layers || a.denoise) && lossy_for_floats(a.compression))
        usage_error(
            "--compression {} is lossy for 32-bit floats and would corrupt the data layers of "
            "{} (object and material ids, depth, positions): use zip, zips, piz, rle, b44, "
            "b44a or none, or render without {}",
            a.compression, a.layers ? "--layers" : "--denoise (which writes the layers)",
            a.layers ? "--layers" : "--denoise");
    if (check_paths) {
        check_writable(out.exr, "EXR");
        if (!out.preview.empty()) check_writable(out.preview, "PNG preview");
    }
    // A frame number goes into one run of '#': a second would stay in every frame's name.
    for (const std::string& path : {out.exr, out.preview}) {
        if (find_frame_run(path).several)
            usage_error("'{}' has more than one run of '#'; the frame number goes into one", path);
        // Without --frames nothing numbers it: the file was written as 'still.####.exr'.
        if (a.frames.empty() && find_frame_run(path).count > 0)
            usage_error(
                "'{}' holds a frame number pattern ('#'), but only --frames numbers files: render "
                "the sequence with --frames FIRST..LAST, or name one file",
                path);
    }
    // The preview is a PNG whatever its name: another ending would mislabel it (p.jpg held PNG).
    if (!out.preview.empty() && !has_extension(out.preview, ".png"))
        usage_error("--preview '{}' must end in .png (the preview is a PNG)", out.preview);
    if (!a.frames.empty() && check_paths) {
        const auto [first, last] = parse_frames(a.frames);
        check_frame_paths(out, first, last);
    }
    out.exr_options.half = !a.full_float;
    out.exr_options.compression = a.compression;
    out.scene = a.scene;
    out.display = a.display;
    out.view = a.view;
    if (!a.spp_range.empty()) parse_spp_range(a.spp_range, out.spp_first, out.spp_end);
    if (a.strategy != "mis") out.strategy = a.strategy;
    return out;
}

std::optional<Outputs> scene_outputs(const RenderArgs& a, const SceneInfo& info, const Logger& log,
                                     bool numbered, int64_t first, int64_t last) {
    if (!a.output.empty()) return std::nullopt;
    const std::string& asked = info.output;
    if (asked.empty()) {
        Outputs out = outputs_for(a);
        out.remove_stale_temporaries(log);
        return out;
    }
    if (!numbered && find_frame_run(asked).count > 0)
        throw_error(info.output_loc,
                    "the scene asks for '{}', a name with a frame number ('#'), but only --frames "
                    "numbers images: render the sequence with --frames FIRST..LAST, or give -o",
                    asked);
    RenderArgs named = a;
    named.output = fs::path(asked).replace_extension(".exr").string();
    // What is wrong with it, at the scene's line (the path is the working folder's, as pbrt's).
    Outputs out;
    try {
        out = outputs_for(named);
    } catch (const SpangleError& e) {
        throw_error(info.output_loc, "the scene asks for '{}' (a path from the working folder): {}",
                    asked, e.what());
    }
    out.remove_stale_temporaries(log);
    if (!a.quiet) {
        if (!numbered)
            log.info("the scene asks for '{}': writing {}", asked, out.exr);
        else
            log.info("the scene asks for '{}': writing {}{}", asked, out.for_frame(first).exr,
                     last > first ? fmt::format(" to {}", out.for_frame(last).exr) : std::string());
    }
    return out;
}

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

void warn_half_overflow(const Logger& log, std::size_t values, const std::string& exr) {
    if (values > 0)
        log.warn(
            "{} values in {} are brighter than a half float holds (65504) and were stored as "
            "infinity; write 32-bit floats with --float",
            values, exr);
}

std::string sampling_note(const RenderStats& st) {
    if (!(st.noise_threshold > 0.0f)) return {};
    return fmt::format("adaptive {} min_spp {} max_spp {}", st.noise_threshold, st.adaptive_min_spp,
                       st.spp_target);
}

std::string spread_note(const RenderStats& st) {
    std::string out;
    for (const double w : st.filter_spread) out += fmt::format("{}{:a}", out.empty() ? "" : " ", w);
    return out;
}

std::string denoise_note(const RenderStats& st) {
    if (!st.denoised) return {};
    switch (st.denoise_glints) {
        case GlintDenoise::Apart:
            return "apart";
        case GlintDenoise::Filter:
            return "filter";
        case GlintDenoise::Keep:
            break;
    }
    return "keep";
}

const RenderResult& for_output(const RenderResult& r, const RenderOptions& o, const Logger& log,
                               RenderResult& scratch) {
    if (!o.denoise || r.stats.spp_reached == 0) return r;
    scratch = r;
    denoise_and_record(DenoiseImage{&scratch.image, &scratch.layers, &scratch.layer_names,
                                    scratch.width, scratch.height},
                       o.denoise_glints, o.threads, denoise_control(o), log, scratch.stats);
    return scratch;
}

}  // namespace spangle
