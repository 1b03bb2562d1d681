// The MPI render mode (one rank's part of `mpirun -np N spangle render`): see mpi_command.h.

#include "cli/mpi_command.h"

#include <fmt/format.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "cli/arguments.h"
#include "cli/launcher.h"
#include "cli/mpi_render.h"
#include "cli/outputs.h"
#include "cli/progress.h"
#include "cli/render_setup.h"
#include "cli/usage.h"
#include "pipeline/session.h"
#include "render/denoise.h"

namespace spangle {
namespace {

/** Ends a rank quietly with `code` after the rank that should speak has printed why. */
struct RankExit {
    int code;  ///< the exit status
};

/** A step every rank takes: when it fails on any, the first rank that failed says why (rank 0
 *  with the one-process message, another rank naming itself) and every rank ends (RankExit). */
void together(const MpiJob& job, const std::function<void()>& step) {
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
}

/** The worker threads of this rank: --threads, else this machine's cores shared among its
 *  ranks (unless the launcher bound each to its own: then those, with a warning when that
 *  leaves cores idle). */
int rank_threads(const RenderArgs& a, const MpiJob& job, const Logger& log) {
    if (a.threads != 0) return a.threads;
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    cpu_set_t set;
    const bool bound = sched_getaffinity(0, sizeof(set), &set) == 0 &&
                       static_cast<unsigned>(CPU_COUNT(&set)) < cores;
    const int local = launcher_info().local_size;
    const int threads = bound ? CPU_COUNT(&set) : std::max(1, static_cast<int>(cores) / local);
    if (bound && job.rank() == 0 && threads * local < static_cast<int>(cores))
        log.warn(
            "the launcher bound each rank to {} of this machine's {} cores ({} ranks here): "
            "run mpirun with --bind-to none (spangle then shares the cores among the ranks) "
            "or give each rank its cores (--map-by node:PE=N)",
            threads, cores, local);
    return threads;
}

/** The frames to render: (frame, whether it is a frame of --frames) -- one still without. */
std::vector<std::pair<int64_t, bool>> frames_of(const RenderArgs& a) {
    std::vector<std::pair<int64_t, bool>> frames;
    if (a.frames.empty()) {
        frames.emplace_back(0, false);
    } else {
        const auto [first, last] = parse_frames(a.frames);
        for (int64_t f = first; f <= last; ++f) frames.emplace_back(f, true);
    }
    return frames;
}

/** Rank 0: writes a frame's image and, unless quiet, the line of the ranks' loads. A failure
 *  ends the job (the other ranks wait for the next step). */
void write_on_rank0(const RenderArgs& a, const MpiJob& job, const Session& session,
                    const Logger& log, const Outputs& out, int64_t f, bool numbered,
                    const DistributedImage& img) {
    try {
        const Outputs o = numbered ? out.for_frame(f) : out;
        warn_nonfinite(log, img.stats);
        o.write_image(log, final_image(img, session.color(), session.info()));
        if (a.quiet) return;
        std::string ranks;
        for (std::size_t r = 0; r < img.loads.size(); ++r)
            ranks += fmt::format("{}{}: {} bands {:.2f} s", r ? "; " : "", r, img.loads[r].units,
                                 img.loads[r].busy);
        fmt::print(
            "{}{:.2f} s over {} ranks ({} bands of {} tile rows; {}); balance "
            "(busiest / mean) {:.3f}; wrote {}\n",
            numbered ? fmt::format("frame {}: ", f) : std::string(), img.stats.seconds,
            img.loads.size(), img.units, std::max(a.band_rows, 1u), ranks, img.balance(), o.exr);
        std::fflush(stdout);
    } catch (const std::exception& e) {
        print_error(e.what());
        job.abort(1);
    }
}

/** One rank's part of the job. */
int render_as_rank(const RenderArgs& a, const MpiJob& job) {
    Logger log = render_logger(a);
    // The other ranks would repeat rank 0's notes and warnings: they report errors only.
    if (job.rank() != 0) log.threshold = LogLevel::Error;
    Outputs out;
    RenderOptions options = render_options(a);
    options.progressive = false;  // one pass per band: the same sums, bit for bit
    options.preview_pass = false;
    options.threads = rank_threads(a, job, log);
    if (job.rank() != 0) options.work_progress = nullptr;  // rank 0 speaks for all
    std::unique_ptr<Session> session;
    together(job, [&] {
        if (job.rank() == 0) {
            // (Without -o, the default is checked once the scene says it is the one.)
            out = outputs_for(a, !a.output.empty());
            if (!a.output.empty()) out.remove_stale_temporaries(log);
        }
        session = std::make_unique<Session>(a.plugin_dirs, a.ocio, options, log);
    });
    const std::vector<std::pair<int64_t, bool>> frames = frames_of(a);
    Progress progress(::isatty(STDERR_FILENO) != 0);
    for (const auto& frame : frames) {
        // Plain names, not a structured binding: lambdas capture those only from C++20 on, and
        // clang 14 (the fuzz and sanitizer build) refuses them.
        const int64_t f = frame.first;
        const bool numbered = frame.second;
        together(job, [&] {
            if (numbered)
                session->load_frame(a.scene, f);
            else
                session->load(a.scene, 0.0);
            // The image the scene asks for where -o gives none, as a render in one process
            // writes it (an MPI render wrote the scene file's name).
            if (job.rank() == 0 && f == frames.front().first)
                if (auto asked =
                        scene_outputs(a, session->info(), log, numbered, f, frames.back().first))
                    out = std::move(*asked);
            if (job.rank() == 0)
                (numbered ? out.for_frame(f) : out).check_not_inputs(session->watched_files());
            if (job.rank() == 0 && f == frames.front().first) {
                out.check_view(session->color());
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
        // The denoiser reads neighbouring pixels: it runs on the assembled image.
        if (options.denoise) {
            denoise_and_record(
                DenoiseImage{&img.image, &img.layers, &img.layer_names, img.width, img.height},
                options.denoise_glints, options.threads, /*control: none, as mpirun signals*/ {},
                log, img.stats);
        }
        write_on_rank0(a, job, *session, log, out, f, numbered, img);
    }
    return 0;
}

}  // namespace

int run_render_mpi(const RenderArgs& a, int& argc, char**& argv) {
    MpiJob job(argc, argv);
    try {
        return render_as_rank(a, job);
    } catch (const RankExit& e) {
        return e.code;
    }
}

}  // namespace spangle
