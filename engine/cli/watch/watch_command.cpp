// Watch mode's loop: see watch_command.h.

#include "cli/watch/watch_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "cli/output_paths.h"
#include "cli/outputs.h"
#include "cli/preview_server.h"
#include "cli/render_setup.h"
#include "cli/signals.h"
#include "cli/usage.h"
#include "cli/watch/file_watcher.h"
#include "core/error.h"
#include "core/files.h"
#include "pipeline/session.h"
#include "scene/scene_builder.h"
#include "scene/scene_hash.h"
#include "scene/scene_loader.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** The render options of watch mode: a preview pass first when passes are shown or written. */
RenderOptions watch_options(const RenderArgs& a) {
    RenderOptions options = render_options(a);
    options.preview_pass = !a.no_pass_output || !a.serve.empty();
    options.film_memory_at_load = true;
    return options;
}

/** One watch session: the live scene, the render thread, and the reload line of the change
 *  being rendered (printed when its first full pass is written). */
class WatchLoop {
public:
    /** Loads the colour config and checks the preview's view; starts the page of --serve. */
    WatchLoop(const RenderArgs& a, const RenderSetup& s);

    /** Renders and re-renders until a stop signal; returns the exit status. */
    int run();

private:
    /** A reload line, to the terminal and the page. */
    void say(const std::string& line);
    /** An error, to the terminal and the page. */
    void report_error(const std::string& message);
    /** A pass was written: the pending reload line goes out at the first full pass (with the
     *  preview pass's time when there was one). */
    /** Says the reload line with the pass just done; `written`: whether its image reached the
     *  disk (a failed write was reported, and the line says "rendered" instead). */
    void announce(uint32_t spp, uint32_t block, bool written = true);
    /** A change (or a stop signal) interrupted the render before its first pass: the line goes
     *  out as it stands, ending with `why`. */
    void flush_unannounced(const char* why = "interrupted by the next change");
    /** Shows and writes the image of a pass that is not the last. */
    void on_pass(const PassImage& p);
    /** Starts the render thread (and says so on the page). */
    void start_render();
    /** The render thread's body: renders the live scene, then writes what it reached. */
    void render();
    /** Writes the render's image when it is complete or a signal stopped it after a pass. */
    void finish_render();
    /** Loads the scene (the first load, or a reload after saves of `what`); false when it
     *  failed, having said so. */
    bool load(const std::string& what);
    /** Watches the live scene's files until a save; empty when a stop signal came first. */
    std::vector<std::string> wait_for_change(FileWatcher& watcher);
    /** Stops the render, reloads, and renders again when there is something to show. */
    void apply_change(const std::vector<std::string>& touched);
    /** The line a stop signal ends the session with: what is on disk, at how many samples. */
    void say_stopped();
    /** The files a load reads (the scene's watched files and the scene file). */
    std::vector<std::string> files_to_watch() const;
    /** A save of scene description files only, while a render runs: false when it must reload;
     *  true when it was dealt with and the render goes on (the files hold what the live scene
     *  was built from: an editor's autosave, a touch; or they do not parse: said). */
    bool render_goes_on(const std::vector<std::string>& touched);
    /** The touched files' names for the reload line (those that exist or are watched). */
    std::string touched_names(const std::vector<std::string>& touched) const;

    const RenderArgs& a_;         ///< the command line
    WarningsSaid warnings_said_;  ///< each warning once per watch session
    Logger log_;                  ///< the render's logger, saying each warning once
    /** Where images go: -o, else the image the scene asks for ([render] output, pbrt's Film
     *  "filename"; taken at the first good load), else <scene name>.exr. */
    Outputs out_;
    bool output_chosen_ = false;       ///< out_ follows the scene (set by the first good load)
    const bool pass_output_;           ///< write every pass (not --no-pass-output)
    std::atomic<bool> reload_{false};  ///< stops the render for a reload
    Session session_;                  ///< the live scene
    std::unique_ptr<PreviewServer> server_;  ///< after the session: shows its colour config
    std::mutex mutex_;                       ///< the four below: the render thread's reports
    std::string pending_line_;               ///< the reload line not yet printed
    std::chrono::steady_clock::time_point changed_at_;  ///< when the pending change was seen
    bool finished_ = false;        ///< the last render completed (or has nothing)
    std::string preview_note_;     ///< when the preview pass of the change was written
    bool unchanged_ = false;       ///< the last good reload changed nothing of the live scene
    uint32_t written_spp_ = 0;     ///< samples per pixel of the last image written (0: none)
    uint32_t written_target_ = 0;  ///< and the samples it was going to
    uint32_t written_block_ = 0;   ///< >0: the file holds a preview of 1/block resolution
    std::thread worker_;           ///< the render thread
    /** Each watched file's identity as it was before the last load read it: a file that
     *  differs from it has been saved since, whether or not its events were seen (a save while
     *  the scene loaded). */
    std::map<std::string, std::string> baseline_;
    /** Files of baseline_ whose identity was taken after the load that found them read them. */
    std::set<std::string> unproven_;
    bool last_load_failed_ = false;       ///< retry when a new file appears (the one it lacked)
    std::atomic<bool> rendering_{false};  ///< the render thread is rendering
    std::string last_error_;              ///< why the last load failed (empty: it did not)
};

WatchLoop::WatchLoop(const RenderArgs& a, const RenderSetup& s)
    : a_(a),
      log_(s.log),
      out_(s.out),
      pass_output_(!a.no_pass_output),
      session_(a.plugin_dirs, a.ocio, watch_options(a), log_) {
    log_.once = &warnings_said_;
    out_.check_view(session_.color());  // a display or view the config lacks: an error now
    // And in every config an edit reloads: one that lacks them is a failed reload.
    session_.check_reloaded_config = [this](const ColorConfig& c) { out_.check_view(c); };
    session_.options().stop = [this] { return stop_requested() || reload_.load(); };
    session_.plugins().copy_on_first_open = true;  // a plugin rebuilt in place while watched
    server_ = start_preview_server(a.serve, log_);
    if (server_) {
        session_.options().progress = [this](uint64_t done, uint64_t total) {
            server_->progress(done, total);
        };
        // The page says what the load is doing (meshes, BVHs, materials) before any pass.
        session_.options().work_progress =
            work_progress_to(server_.get(), std::move(session_.options().work_progress));
    }
    session_.options().on_pass = [this](const PassImage& p) { on_pass(p); };
}

void WatchLoop::say(const std::string& line) {
    fmt::print("{}\n", line);
    std::fflush(stdout);
    if (server_) server_->log("info", line);
}

void WatchLoop::report_error(const std::string& message) {
    print_error(message);
    if (server_) server_->log("error", message);
}

void WatchLoop::announce(uint32_t spp, uint32_t block, bool written) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (pending_line_.empty()) return;
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - changed_at_).count();
    const char* done = written ? "written" : "rendered (not written: see the error)";
    if (spp == 0) {
        preview_note_ = fmt::format("preview (1/{} resolution) {} {:.3f} s, ", block, done, s);
        return;
    }
    // Without pass images the first image written is the finished one.
    say(fmt::format("{}; {}{} ({} spp) {} {:.3f} s after the change", pending_line_, preview_note_,
                    pass_output_ ? "first pass" : "image", spp, done, s));
    pending_line_.clear();
    preview_note_.clear();
}

void WatchLoop::flush_unannounced(const char* why) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (pending_line_.empty()) return;
    say(fmt::format("{}; {}{}", pending_line_, preview_note_, why));
    pending_line_.clear();
    preview_note_.clear();
}

void WatchLoop::on_pass(const PassImage& p) {
    if (server_)
        server_->publish_pass(p.image, p.width, p.height, p.spp, p.target, p.block,
                              session_.color());
    if (!pass_output_) return;
    bool written = false;
    try {
        out_.write_pass(p, session_.color(), &session_.info());
        std::lock_guard<std::mutex> lock(mutex_);
        written_spp_ = p.spp;
        written_target_ = p.target;
        written_block_ = p.spp == 0 ? p.block : 0;  // a preview replaced what was on disk
        written = true;
    } catch (const SpangleError& e) {
        report_error(e.what());
    }
    announce(p.spp, p.block, written);
}

void WatchLoop::start_render() {
    if (server_) server_->stage("rendering");
    worker_ = std::thread([this] { render(); });
}

void WatchLoop::render() {
    rendering_ = true;
    const struct Done {
        std::atomic<bool>& flag;
        ~Done() { flag = false; }
    } done{rendering_};
    try {
        // An edit may have made an output one of the scene's own files: refused, not rendered.
        out_.check_not_inputs(session_.watched_files());
        session_.render();
    } catch (const std::exception& e) {
        // A render that fails (a texture whose cached tiles vanished, memory) is reported; the
        // session waits for the next save.
        report_error(e.what());
        return;
    }
    if (session_.result().image.empty()) return;
    warn_if_no_chromaticities(log_, session_.color());
    finish_render();
}

void WatchLoop::finish_render() {
    // --denoise: the image written (finished, or stopped by a signal) is denoised; one a
    // reload cut short is not written.
    const RenderResult& done = session_.result();
    const bool written = done.stats.spp_reached >= done.stats.spp_target ||
                         (stop_requested() && done.stats.spp_reached > 0);
    RenderResult scratch;
    const RenderResult& w = written ? for_output(done, session_.options(), log_, scratch) : done;
    const RenderStats& st = w.stats;
    const ImageDescription image = final_image(w, session_.color(), session_.info());
    bool wrote = false;
    if (!image.partial || (stop_requested() && st.spp_reached > 0)) {
        if (server_)
            server_->publish_pass(w.image, w.width, w.height, st.spp_reached, st.spp_target, 1,
                                  session_.color());
        try {
            out_.write_image(log_, image);
            std::lock_guard<std::mutex> lock(mutex_);
            written_spp_ = st.spp_reached;
            written_target_ = st.spp_target;
            written_block_ = 0;
            wrote = true;
        } catch (const SpangleError& e) {
            report_error(e.what());
            // What an earlier pass wrote may be gone with its folder: not claimed at the stop.
            std::lock_guard<std::mutex> lock(mutex_);
            std::error_code ec;
            if (!fs::exists(out_.exr, ec)) written_spp_ = written_block_ = 0;
        }
        announce(st.spp_reached, 1, wrote);
    }
    if (image.partial) return;
    warn_nonfinite(log_, st);
    const std::string line =
        wrote ? fmt::format("wrote {} ({} spp); watching for changes", out_.exr, st.spp_reached)
              : fmt::format(
                    "rendered {} spp but could not write {} (see the error above); watching for "
                    "changes (a save renders it again)",
                    st.spp_reached, out_.exr);
    if (wrote)
        log_.info("{}", line);
    else
        log_.warn("{}", line);
    if (server_) server_->log(wrote ? "info" : "error", line);
    // Unwritten, it is not finished: a save (even of the same bytes) renders it again.
    std::lock_guard<std::mutex> lock(mutex_);
    finished_ = wrote;
}

std::vector<std::string> WatchLoop::files_to_watch() const {
    std::vector<std::string> files = session_.watched_files();
    files.push_back(a_.scene);
    // Each once, absolute (the scene as typed and as the session knows it are one file).
    for (std::string& f : files) f = absolute_path(f);
    std::sort(files.begin(), files.end());
    files.erase(std::unique(files.begin(), files.end()), files.end());
    return files;
}

bool WatchLoop::load(const std::string& what) {
    if (server_)
        server_->stage(session_.has_scene() ? fmt::format("reloading {} ({})", a_.scene, what)
                                            : fmt::format("loading {}", a_.scene));
    // The files as they are before the load reads them: one saved from now on differs.
    std::map<std::string, std::string> before;
    for (const std::string& f : files_to_watch()) before[f] = file_identity(f);
    const auto keep_baseline = [&](bool failed) {
        baseline_ = before;
        // Files the load found that were not known before it: as they are now (taken after the
        // load read them: a save in between is not proven absent, so a save seen for them is
        // never taken for one already dealt with).
        unproven_.clear();
        for (const std::string& f : files_to_watch())
            if (!baseline_.count(f)) {
                baseline_[f] = file_identity(f);
                unproven_.insert(f);
            }
        last_load_failed_ = failed;
    };
    try {
        const ReloadReport rep = session_.load(a_.scene);
        if (!output_chosen_) {
            // No render runs yet (none starts before a good load).
            // (Its display and view are the command line's: the constructor checked them.)
            if (auto asked = scene_outputs(a_, session_.info(), log_, false, 0, 0))
                out_ = std::move(*asked);
            output_chosen_ = true;
        }
        keep_baseline(false);
        last_error_.clear();
        std::lock_guard<std::mutex> lock(mutex_);
        // Compared with the live scene: the last good one, whatever failed in between.
        unchanged_ = !rep.first && rep.changed.empty();
        pending_line_ = rep.first ? fmt::format("loaded {} in {:.3f} s", a_.scene, rep.seconds)
                                  : fmt::format("reload ({}): {}; applied in {:.3f} s", what,
                                                rep.summary(), rep.seconds);
        return true;
    } catch (const SpangleError& e) {
        keep_baseline(true);
        last_error_ = e.what();
        report_error(e.what());
        const std::string line =
            session_.has_scene() ? std::string("reload failed; still showing the last good scene")
                                 : fmt::format("{} failed; waiting for a good save",
                                               what == "first load" ? "loading" : "reload");
        say(line);
        if (server_) server_->stage(line);
        return false;
    }
}

std::vector<std::string> WatchLoop::wait_for_change(FileWatcher& watcher) {
    const std::vector<std::string> ignored = {out_.exr, out_.preview};
    while (!stop_requested()) {
        const std::vector<std::string> files = files_to_watch();
        watcher.watch(files, last_load_failed_, ignored);
        // Saves whose events were not seen (made while the scene loaded, or in a folder that
        // was away): the files differ from what the load read. Once they stop changing.
        std::vector<std::string> saved;
        for (int settle = 0; settle < 40; ++settle) {
            std::vector<std::string> now;
            for (const std::string& f : files) {
                const auto it = baseline_.find(f);
                if (it != baseline_.end() && file_identity(f) != it->second) now.push_back(f);
            }
            if (now.empty() || now == saved) {
                saved = now;
                break;
            }
            saved = now;
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        if (!saved.empty()) return saved;
        std::vector<std::string> touched = watcher.wait(250);
        if (!touched.empty() && !stop_requested()) return touched;
    }
    return {};
}

std::string WatchLoop::touched_names(const std::vector<std::string>& touched) const {
    // An editor's temporary file (sed -i, vim's 4913), seen in a watched folder and renamed or
    // removed since, is not named: the line said "reload (scene.toml, sedSIiHUg)".
    const std::vector<std::string> watched = files_to_watch();
    std::string what;
    for (const auto& f : touched) {
        std::error_code ec;
        if (!fs::exists(f, ec) &&
            !std::binary_search(watched.begin(), watched.end(), absolute_path(f)))
            continue;
        what += (what.empty() ? "" : ", ") + fs::path(f).filename().string();
    }
    return what.empty() ? std::string("a file removed") : what;
}

bool WatchLoop::render_goes_on(const std::vector<std::string>& touched) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!rendering_) return false;  // nothing in progress to keep
    }
    const SceneInfo& info = session_.info();
    std::vector<std::string> described = info.files;
    described.push_back(info.path);
    described.push_back(a_.scene);
    bool scene_files = false;
    for (const std::string& t : touched) {
        bool scene_file = false;
        for (const std::string& d : described) scene_file = scene_file || same_file(t, d);
        scene_files = scene_files || scene_file;
        // A mesh, a texture, a map or a plugin saved with other bytes: reload. With the same
        // bytes (a touch, a bad save put back) it restarted the render all the same.
        if (!scene_file && !session_.holds_what_was_read(t)) return false;
    }
    const std::string what = touched_names(touched);
    std::map<std::string, std::string> before;
    for (const std::string& f : files_to_watch()) before[f] = file_identity(f);
    if (!scene_files) {
        say(fmt::format("reload ({}): the same bytes as the render read them: its render goes on",
                        what));
    } else {
        try {
            const SceneDescription d =
                read_scene(a_.scene, SceneReadOptions{a_.camera, a_.environment, false,
                                                      !a_.size.empty(), a_.texture_cache});
            if (scene_content_hash(d.path, d.files) != info.scene_files_hash) return false;
            say(fmt::format("reload ({}): the same as the scene being rendered: its render goes on",
                            what));
        } catch (const SpangleError& e) {
            report_error(e.what());
            say("reload failed; the last good scene's render goes on");
            last_load_failed_ = true;  // retried when a file it lacks appears
            last_error_ = e.what();
        }
    }
    for (const auto& [f, id] : before) {
        baseline_[f] = id;
        unproven_.erase(f);
    }
    return true;
}

void WatchLoop::apply_change(const std::vector<std::string>& touched) {
    // A save whose events come in two batches (or are seen by an event and by the identity
    // poll) is dealt with once: files just as they were when the last load (or the check that
    // let the render go on) read them hold nothing new. It said "its render goes on" a second
    // time, or "reload failed" twice for one bad save.
    bool all_seen = true;
    for (const std::string& t : touched) {
        const std::string f = absolute_path(t);
        const auto it = baseline_.find(f);
        all_seen = all_seen && it != baseline_.end() && !unproven_.count(f) &&
                   file_identity(it->first) == it->second;
    }
    if (all_seen) return;
    // After a failed load, a file that appeared in a watched folder may be the one the scene
    // lacked: the scene is read again, and when it fails as before, nothing is said or stopped.
    const std::vector<std::string> watched = files_to_watch();
    bool arrivals_only = true;
    for (const std::string& t : touched)
        arrivals_only =
            arrivals_only && !std::binary_search(watched.begin(), watched.end(), absolute_path(t));
    if (arrivals_only && !last_error_.empty()) {
        try {
            read_scene(a_.scene, SceneReadOptions{a_.camera, a_.environment, false,
                                                  !a_.size.empty(), a_.texture_cache});
        } catch (const SpangleError& e) {
            if (e.what() == last_error_) return;
        }
    }
    // A save that changes nothing the render reads, or that does not parse, leaves the render
    // in progress alone (it restarted from its first sample: an autosave every few seconds
    // kept it from ever finishing).
    if (render_goes_on(touched)) return;
    {
        std::lock_guard<std::mutex> lock(mutex_);  // the render thread reads it in announce
        changed_at_ = std::chrono::steady_clock::now();
    }
    reload_ = true;
    if (worker_.joinable()) worker_.join();
    reload_ = false;
    flush_unannounced();
    const std::string what = touched_names(touched);
    bool interrupted = false;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        interrupted = !finished_;
        finished_ = false;
    }
    const bool ok = load(what);
    // A good save that changed nothing of the last good scene (a failed save fixed back, a
    // file touched) keeps the finished image: there is nothing to render again.
    if (ok && unchanged_ && !interrupted) {
        std::lock_guard<std::mutex> lock(mutex_);
        say(fmt::format("{}; the same as the last good scene: its image is kept", pending_line_));
        pending_line_.clear();
        finished_ = true;
        return;
    }
    // A failed reload keeps the last good scene: its image stays on disk, and a render of it
    // that the change interrupted goes on.
    if (session_.has_scene() && (ok || interrupted)) {
        start_render();
    } else {
        std::lock_guard<std::mutex> lock(mutex_);
        finished_ = true;
    }
}

int WatchLoop::run() {
    FileWatcher watcher;
    changed_at_ = std::chrono::steady_clock::now();
    load("first load");
    if (session_.has_scene()) start_render();
    for (;;) {
        const std::vector<std::string> touched = wait_for_change(watcher);
        if (touched.empty()) break;  // a stop signal
        apply_change(touched);
    }
    if (worker_.joinable()) worker_.join();
    flush_unannounced("stopped before its first pass");
    say_stopped();
    return exit_status_for_signal();
}

void WatchLoop::say_stopped() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (written_block_ > 0)
        say(
            fmt::format("stopped by {}: {} holds only the preview (1/{} resolution) of the last "
                        "change, before its first pass",
                        stop_signal_name(), out_.exr, written_block_));
    else if (written_spp_ == 0)
        say(fmt::format("stopped by {}: no image written", stop_signal_name()));
    else if (written_spp_ < written_target_)
        say(fmt::format("stopped by {}: wrote {} at {} of {} samples per pixel", stop_signal_name(),
                        out_.exr, written_spp_, written_target_));
    else
        say(fmt::format("stopped by {}: {} holds the finished image at {} samples per pixel",
                        stop_signal_name(), out_.exr, written_spp_));
}

}  // namespace

int run_watch(const RenderArgs& a) {
    // A name no save can make a scene (a mesh, another program's scene) ends the command, as it
    // does without --watch (it waited for a good save that could never come).
    check_scene_format(a.scene);
    // (Without -o the scene may name the image: its default is checked once it is read.)
    const RenderSetup s = set_up_render(a, true);
    WatchLoop loop(a, s);
    return loop.run();
}

}  // namespace spangle
