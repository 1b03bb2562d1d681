#include "cli/progress.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>

namespace spangle {

namespace {

/** fmt::print without its throw when the write fails: a closed terminal (EIO after a hangup)
 *  threw out of a worker thread and the render ended in std::terminate, its image lost. */
template <class... Args>
void say_progress(std::FILE* out, fmt::format_string<Args...> format, Args&&... args) {
    const std::string line = fmt::format(format, std::forward<Args>(args)...);
    std::fwrite(line.data(), 1, line.size(), out);
}

std::string format_duration(double s) {
    if (!(s >= 0.0) || s > 1e7) return "?";
    const auto t = static_cast<long>(s + 0.5);
    if (t >= 3600) return fmt::format("{}h{:02}m", t / 3600, (t / 60) % 60);
    if (t >= 60) return fmt::format("{}m{:02}s", t / 60, t % 60);
    return fmt::format("{}s", t);
}

}  // namespace

Progress::Progress(bool interactive, std::FILE* out)
    : interactive_(interactive),
      out_(out),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

void Progress::update(uint64_t done, uint64_t total, uint64_t traced) {
    const auto now = std::chrono::steady_clock::now();
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    // (At most 1: work counted twice, as MPI bands that render rows around them for a shared
    // filter, must not overfill the bar.)
    const double frac =
        total ? std::min(1.0, static_cast<double>(done) / static_cast<double>(total)) : 1.0;
    const double work = static_cast<double>(traced > 0 ? traced : done);
    const double rate = elapsed > 0.0 ? work / elapsed : 0.0;
    const double left =
        rate > 0.0 ? static_cast<double>(total - std::min(done, total)) / rate : -1.0;
    if (interactive_) {
        if (done < total && std::chrono::duration<double>(now - last_draw_).count() < 0.2) return;
        last_draw_ = now;
        constexpr int kWidth = 30;
        const int filled = static_cast<int>(frac * kWidth);
        say_progress(out_, "\r[{}{}] {:5.1f}%  {:.2f} Msamples/s  {} left   ",
                     std::string(static_cast<std::size_t>(filled), '#'),
                     std::string(static_cast<std::size_t>(kWidth - filled), '.'), 100.0 * frac,
                     rate * 1e-6, format_duration(left));
        std::fflush(out_);
        drawn_ = true;
        return;
    }
    const int decile = static_cast<int>(frac * 10.0);
    // No line at 0%: the rate (and so the time left) means nothing before a tenth is done.
    if (decile == last_decile_ || decile == 0) return;
    last_decile_ = decile;
    say_progress(out_, "render: {:3d}%  {:.2f} Msamples/s  {} left\n", decile * 10, rate * 1e-6,
                 format_duration(left));
    std::fflush(out_);
}

void Progress::finish() {
    if (interactive_ && drawn_) say_progress(out_, "\n");
}

namespace {

/** What work_meter() keeps between calls. */
struct WorkMeter {
    bool interactive = false;
    std::FILE* out = stderr;
    std::string what;  ///< the piece now running ("" before the first)
    std::chrono::steady_clock::time_point start, last_draw;
    bool shown = false;    ///< a line of this piece was printed
    int last_decile = -1;  ///< the last 10% step printed (not interactive)

    /** Seconds a piece runs before it is shown. */
    static constexpr double kQuiet = 1.0;

    void update(const std::string& w, double fraction) {
        const auto now = std::chrono::steady_clock::now();
        // A new piece, or the same piece begun again (a reload after one that failed before
        // its end: its clock ran on from the failed one, "done in 7s" for a 1 ms build).
        if (w != what || fraction <= 0.0) {
            what = w;
            start = last_draw = now;
            shown = false;
            last_decile = -1;
        }
        const double elapsed = std::chrono::duration<double>(now - start).count();
        const bool done = fraction >= 1.0;
        if (!shown && (elapsed < kQuiet)) return;  // quick work stays quiet, its end too
        if (done) {
            say_progress(out, "{}{}: done in {}{}\n", interactive ? "\r" : "", what,
                         format_duration(elapsed), interactive ? "          " : "");
            std::fflush(out);
            what.clear();
            return;
        }
        if (interactive) {
            if (shown && std::chrono::duration<double>(now - last_draw).count() < 0.2) return;
            say_progress(out, "\r{}  {:5.1f}%  {}   ", what, 100.0 * fraction,
                         format_duration(elapsed));
        } else {
            const int decile = static_cast<int>(fraction * 10.0);
            if (decile == last_decile) return;
            last_decile = decile;
            say_progress(out, "{}: {:3d}%  {}\n", what, decile * 10, format_duration(elapsed));
        }
        std::fflush(out);
        last_draw = now;
        shown = true;
    }
};

}  // namespace

WorkProgress work_meter(bool interactive, std::FILE* out) {
    auto m = std::make_shared<WorkMeter>();
    m->interactive = interactive;
    m->out = out;
    return [m](const std::string& what, double fraction) { m->update(what, fraction); };
}

}  // namespace spangle
