// `spangle render --frames`: see frames_command.h.

#include "cli/frames_command.h"

#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include <unistd.h>

#include "cli/arguments.h"
#include "cli/outputs.h"
#include "cli/progress.h"
#include "cli/render_setup.h"
#include "cli/signals.h"
#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "render/render_scene.h"
#include "scene/frame_sequence.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"

namespace spangle {
namespace {

/** Whether frames first..last reach past both the scene's frame range and its keys (the
 *  frames past both hold the nearest key). */
bool beyond_range_and_keys(const SceneInfo& info, int64_t first, int64_t last) {
    const auto frame_of = [&](double t) {
        return static_cast<double>(info.frame_start) + t * info.fps;
    };
    const double from = std::min(static_cast<double>(info.frame_start), frame_of(info.keys_from));
    const double to = std::max(static_cast<double>(info.frame_end), frame_of(info.keys_to));
    return static_cast<double>(first) < from || static_cast<double>(last) > to;
}

/** The line of a written frame: its time, how long it took, the systems that ran. */
void print_frame_line(const Session& session, int64_t f, double seconds, const ReloadReport& rep,
                      const std::string& exr) {
    fmt::print(
        "frame {} ({:.3f} s): {:.2f} s, ran: {}; wrote {}\n", f, frame_time(session.info(), f),
        seconds,
        rep.ran.empty() ? std::string("nothing") : fmt::format("{}", fmt::join(rep.ran, ", ")),
        exr);
}

}  // namespace

int run_frames(const RenderArgs& a) {
    const auto [first, last] = parse_frames(a.frames);
    RenderSetup s = set_up_render(a, true);
    // A warning that holds for every frame (an emitter that moves while the shutter is open, a
    // material no object uses) is said for the first frame only, as --watch says it once.
    WarningsSaid said;
    Logger frame_log = s.log;
    frame_log.once = &said;
    Session session(a.plugin_dirs, a.ocio, render_options(a), frame_log);
    session.options().stop = stop_requested;
    // Every frame's mesh and cage files exist before the first frame renders (sequences are
    // written in TOML scenes; a missing frame 5 failed after frames 1 to 4 had rendered).
    if (std::filesystem::path(a.scene).extension() == ".toml")
        check_sequence_files(read_scene(a.scene), first, last);
    for (int64_t f = first; f <= last; ++f) {
        const auto t0 = std::chrono::steady_clock::now();
        const ReloadReport rep = session.load_frame(a.scene, f);
        // The images the scene asks for ([render] output, pbrt's Film "filename") when -o gives
        // none, numbered as -o's are ('#' runs, else .#### before the extension), as a still
        // render writes the one it asks for (frames went to the scene's name instead).
        if (f == first)
            if (auto asked = scene_outputs(a, session.info(), s.log, true, first, last))
                s.out = std::move(*asked);
        s.out.for_frame(f).check_not_inputs(session.watched_files());
        if (f == first) {
            // No frame's output over a file the scene reads, before anything renders (frame 1
            // was written before frame 2's output was found to be the scene's map). Each frame
            // checks again against its own inputs (a sequence's meshes) as it loads.
            for (int64_t g = first + 1; g <= last; ++g)
                s.out.for_frame(g).check_not_inputs(session.watched_files());
            check_request_fits_scene(session);
            s.out.check_view(session.color());
            const SceneInfo& info = session.info();
            if (!info.animated)
                s.log.warn("{}: nothing in the scene has keyframes: every frame is the same image",
                           a.scene);
            else if (beyond_range_and_keys(info, first, last))
                // Frames past the scene's range and its keys: said, not silent (frames past
                // frame_end but within the keys, as a turntable's, do move).
                s.log.warn(
                    "{}: frames {}..{} reach beyond the scene's frame range {}..{} "
                    "([render] frame_start, frame_end); past its keys a frame holds the "
                    "nearest key",
                    a.scene, first, last, info.frame_start, info.frame_end);
        }
        // Progress within the frame, as a still render shows it (a farm's log of a long frame
        // showed nothing until its line at the end).
        Progress progress(::isatty(STDERR_FILENO) != 0);
        std::atomic<uint64_t> traced{0};
        if (!a.quiet) {
            session.options().traced = &traced;
            session.options().progress = [&](uint64_t done, uint64_t total) {
                progress.update(done, total, traced.load(std::memory_order_relaxed));
            };
        }
        session.render();
        session.options().progress = nullptr;
        session.options().traced = nullptr;
        if (!a.quiet) progress.finish();
        RenderResult scratch;
        const RenderResult& w = for_output(session.result(), session.options(), s.log, scratch);
        // Frames a signal left unrendered: the sequence is not whole, whatever the signal (a
        // farm script must not take it for done).
        const auto left = [&](int64_t from) {
            return from > last ? std::string()
                               : fmt::format("; frames {}..{} not rendered", from, last);
        };
        if (w.stats.spp_reached == 0) {
            s.log.warn("stopped by a signal ({}) before frame {} had a pass: not written{}",
                       stop_signal_name(), f, left(f));
            return interrupted_status();
        }
        const Outputs out = s.out.for_frame(f);
        const ImageDescription image = final_image(w, session.color(), session.info());
        out.write_image(s.log, image);
        warn_nonfinite(s.log, w.stats);
        // A partial frame is not announced as a finished one: the warning below says what it is.
        if (!a.quiet && !image.partial)
            print_frame_line(
                session, f,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), rep,
                out.exr);
        std::fflush(stdout);
        if (w.stats.denoise_stopped) {
            s.log.warn(
                "stopped by a signal ({}) while denoising: wrote {} as rendered, not "
                "denoised{}",
                stop_signal_name(), out.exr, left(f + 1));
            return interrupted_status();
        }
        if (image.partial || (stop_requested() && f < last)) {
            if (image.partial)
                s.log.warn("stopped by a signal ({}): wrote {} with {} of {} samples per pixel{}",
                           stop_signal_name(), out.exr, w.stats.spp_reached, w.stats.spp_target,
                           left(f + 1));
            else
                s.log.warn("stopped by a signal ({}) after frame {}{}", stop_signal_name(), f,
                           left(f + 1));
            return interrupted_status();
        }
        // A signal after the last frame's last pass: every frame is whole (said, and the status
        // a one-shot render gives then: SIGTERM and SIGHUP end as such, SIGINT with 0).
        // (The flag read once: a signal between two reads exited without the line.)
        if (f == last && stop_requested()) {
            const int status = exit_status_for_signal();
            s.log.warn("{} arrived after the last pass of the last frame: wrote {} whole{}",
                       stop_signal_name(), out.exr, late_signal_status(status));
            return status;
        }
    }
    return 0;
}

}  // namespace spangle
