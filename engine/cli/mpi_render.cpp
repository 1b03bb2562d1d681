// Distributed rendering over MPI: see mpi_render.h.
//
// The protocol, on MPI_COMM_WORLD:
//   rank r > 0 -> 0, kTagReport: int64[kReportSize] = the band it finished (-1 on its first
//       request) and that band's counters; when a band is named, then kTagPixels: its floats
//       (RGB rows, then the layer rows).
//   0 -> rank r, kTagUnit: int64 = the next band for r, or -1: none left (r's part is over).
// Rank 0 answers on a thread of its own that polls (MPI_Test and a short sleep: a blocking
// receive would spin a core the renderer needs), while its main thread renders bands from the
// same counter. Only that thread calls MPI during a render (MPI_THREAD_SERIALIZED).

#include "cli/mpi_render.h"

#include <mpi.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <thread>
#include <tuple>

#include "color/color_config.h"
#include "core/error.h"
#include "core/hash.h"
#include "pipeline/session.h"
#include "render/adaptive.h"
#include "render/integrator.h"
#include "render/layers/layer_sink.h"
#include "scene/components.h"
#include "scene/scene_builder.h"

namespace spangle {
namespace {

constexpr int kTagReport = 1, kTagPixels = 2, kTagUnit = 3;
constexpr int kReportSize = 10;

/** A band of the window: whole tile rows of the full frame's grid, clipped to the window. */
CropWindow band_window(const CropWindow& win, uint32_t band_px, uint32_t unit) {
    const uint32_t first = win.y0 / band_px;
    CropWindow b = win;
    b.y0 = std::max(win.y0, (first + unit) * band_px);
    b.y1 = std::min(win.y1, (first + unit + 1) * band_px);
    return b;
}

/** The counters of one band, as sent to rank 0. */
struct Report {
    int64_t v[kReportSize] = {};  ///< unit, busy ns, samples, rays x3, non-finite, first bad x/y/k

    /** The report of band `unit` (-1: a rank's first request), `busy` seconds, counters `s`. */
    static Report of(int64_t unit, double busy, const RenderStats& s) {
        Report r;
        r.v[0] = unit;
        r.v[1] = static_cast<int64_t>(busy * 1e9);
        r.v[2] = static_cast<int64_t>(s.samples);
        r.v[3] = static_cast<int64_t>(s.camera_rays);
        r.v[4] = static_cast<int64_t>(s.bounce_rays);
        r.v[5] = static_cast<int64_t>(s.shadow_rays);
        r.v[6] = static_cast<int64_t>(s.nonfinite);
        r.v[7] = s.first_bad_pixel_x;
        r.v[8] = s.first_bad_pixel_y;
        r.v[9] = s.first_bad_sample;
        return r;
    }
};

/** How the window is cut into bands: what every rank works out before any band is handed out. */
struct BandPlan {
    Film film;                             ///< the scene's, with the options' size and spp
    CropWindow win;                        ///< the window rendered (the image without --crop)
    std::vector<std::string> layer_names;  ///< the layers' channels; empty without --layers
    uint32_t band_px = 0;                  ///< pixel rows of a band (16 per tile row)
    uint32_t units = 0;                    ///< bands the window is cut into
    uint32_t cw = 0, ch = 0;               ///< the window's size
    std::size_t lc = 0;                    ///< layer channels per pixel

    /** Values of a pixel as sent: RGB, then the layers. */
    std::size_t per_pixel() const { return 3 + lc; }
};

/** The plan of `crop` for the session's live scene; throws SpangleError when the scene has no
 *  camera or a band would be too large for one message. */
BandPlan plan_bands(Session& session, const CropWindow& crop, uint32_t band_rows) {
    BandPlan p;
    if (!session.film(p.film)) throw_error("the scene has no camera to render from");
    p.win = crop_within(crop, p.film.width, p.film.height);
    p.band_px = 16 * std::max(band_rows, 1u);
    p.units = (p.win.y1 - 1) / p.band_px - p.win.y0 / p.band_px + 1;
    p.cw = p.win.x1 - p.win.x0;
    p.ch = p.win.y1 - p.win.y0;
    if (session.options().layers) {
        const SceneInfo& info = session.info();
        const bool catcher = std::any_of(info.shadow_catchers.begin(), info.shadow_catchers.end(),
                                         [](uint8_t c) { return c != 0; });
        p.layer_names =
            layer_channel_names(layer_plan(session.options(), &info.light_groups,
                                           &info.object_names, &info.material_names, catcher));
    }
    // Adaptive sampling: the samples of each pixel come back as the last channel (render/
    // adaptive.h: a band's pixels take the samples the whole render gives them).
    if (adaptive_on(p.film, session.options())) p.layer_names.emplace_back("spp");
    p.lc = p.layer_names.size();
    if (static_cast<double>(p.band_px) * p.cw * static_cast<double>(p.per_pixel()) >= 2147483647.0)
        throw_error("bands of {} rows of {} pixels are too large to send: lower --band-rows",
                    p.band_px, p.cw);
    return p;
}

/** What decides a rank's pixels, as hashes that rank 0 compares with every other rank's before a
 *  band is handed out: the bands of a rank that read other files (a stale copy of the scene on
 *  one node), other settings (another --spp in an MPMD launch) or another build of a plugin
 *  were placed into the image without a word. */
struct RankIdentity {
    static constexpr int kParts = 5;
    uint64_t v[kParts] = {};  ///< scene files, time, film settings, render options, plugins

    /** What differs in `other` (rank `r`'s) from this (rank 0's), in words; empty when nothing. */
    std::string differences(const RankIdentity& other) const {
        static constexpr const char* kWhat[kParts] = {
            "the scene's files (the scene, its imports, meshes, textures or maps)",
            "the scene's time (another frame)",
            "the image settings (size, spp, seed, depth, filter, clamp or adaptive sampling)",
            "the render options (--strategy, --layers, --crop, --camera, --env, --spp-range, "
            "--noise-threshold, --min-spp, --max-spp)",
            "the material plugins' files (another build of a plugin)"};
        std::string out;
        for (int i = 0; i < kParts; ++i)
            if (v[i] != other.v[i]) out += (out.empty() ? "" : "; ") + std::string(kWhat[i]);
        return out;
    }
};

/** Mixes the bytes of a value of at most 8 bytes into h. */
template <class T>
uint64_t mix_value(uint64_t h, const T& x) {
    static_assert(sizeof(T) <= sizeof(uint64_t));
    uint64_t bits = 0;
    std::memcpy(&bits, &x, sizeof(T));
    return hash2(h, bits);
}

RankIdentity identity_of(Session& session, const BandPlan& plan) {
    RankIdentity id;
    const SceneInfo& info = session.info();
    // The files' bytes, not their paths (nodes may mount them elsewhere), without the plugins'
    // (their own part below, named apart in the message).
    const std::vector<std::string> plugin_files = session.plugins().opened_files();
    uint64_t files = hash2(info.scene_files_hash, session.color().content_hash());
    for (const uint64_t h : session.read_content_hashes(plugin_files)) files = hash2(files, h);
    id.v[0] = files;
    id.v[1] = mix_value(0, info.time);
    uint64_t film = 0;
#define SPANGLE_MIX_FIELD(type, name, doc) film = mix_value(film, plan.film.name);
    SPANGLE_FILM_FIELDS(SPANGLE_MIX_FIELD)
#undef SPANGLE_MIX_FIELD
    id.v[2] = film;
    const RenderOptions& o = session.options();
    uint64_t opt = 0;
    for (const uint64_t x :
         {static_cast<uint64_t>(o.strategy), static_cast<uint64_t>(o.layers),
          static_cast<uint64_t>(o.background_apart), static_cast<uint64_t>(plan.win.x0),
          static_cast<uint64_t>(plan.win.y0), static_cast<uint64_t>(plan.win.x1),
          static_cast<uint64_t>(plan.win.y1), static_cast<uint64_t>(plan.band_px),
          static_cast<uint64_t>(o.spp_first), static_cast<uint64_t>(o.spp_end),
          static_cast<uint64_t>(o.min_spp_override), static_cast<uint64_t>(o.max_spp_override),
          static_cast<uint64_t>(o.footprints_always), static_cast<uint64_t>(plan.lc)})
        opt = hash2(opt, x);
    opt = mix_value(opt, o.noise_threshold_override);
    opt = hash2(opt, hash_text(o.camera));
    opt = hash2(opt, hash_text(o.environment));
    for (const std::string& n : plan.layer_names) opt = hash2(opt, hash_text(n));
    id.v[3] = opt;
    uint64_t plugins = 0;
    for (const std::string& f : plugin_files) plugins = hash2(plugins, file_content_hash(f));
    id.v[4] = plugins;
    return id;
}

/** Renders band `unit` on this rank: its pixels (RGB rows, then layer rows) and its report. */
void render_band(Session& session, const BandPlan& plan, uint32_t unit, std::vector<float>& pixels,
                 Report& report) {
    const auto t0 = std::chrono::steady_clock::now();
    session.options().crop = band_window(plan.win, plan.band_px, unit);
    session.render();
    const RenderResult& w = session.result();
    pixels.assign(w.image.begin(), w.image.end());
    pixels.insert(pixels.end(), w.layers.begin(), w.layers.end());
    report = Report::of(
        unit, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
        w.stats);
}

/** A rank other than 0: ask, render, send back, ask again -- until rank 0 says there is nothing
 *  left. A band that fails ends the job. */
void work_for_rank0(const MpiJob& job, Session& session, const BandPlan& plan) {
    Report report = Report::of(-1, 0.0, RenderStats{});
    std::vector<float> pixels;
    for (;;) {
        MPI_Send(report.v, kReportSize, MPI_INT64_T, 0, kTagReport, MPI_COMM_WORLD);
        if (report.v[0] >= 0)
            MPI_Send(pixels.data(), static_cast<int>(pixels.size()), MPI_FLOAT, 0, kTagPixels,
                     MPI_COMM_WORLD);
        int64_t next = -1;
        MPI_Recv(&next, 1, MPI_INT64_T, 0, kTagUnit, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (next < 0) break;
        try {
            render_band(session, plan, static_cast<uint32_t>(next), pixels, report);
        } catch (const std::exception& e) {
            fmt::print(stderr, "spangle: error: {}: band {} failed: {}\n", job.who(), next,
                       e.what());
            job.abort(1);
        }
    }
}

/** Rank 0's image, filled by its own bands and the others' as they arrive (from its main
 *  thread and its answering thread: placing is serialised). */
class Assembly {
public:
    /** Sizes `out` for `plan`; `progress` (may be empty) gets samples done and the total. */
    Assembly(const MpiJob& job, const BandPlan& plan,
             const std::function<void(uint64_t, uint64_t)>& progress, DistributedImage& out)
        : job_(job),
          plan_(plan),
          progress_(progress),
          out_(out),
          total_(static_cast<uint64_t>(plan.cw) * plan.ch * plan.film.spp) {
        out.width = plan.cw;
        out.height = plan.ch;
        out.window = ImageWindow{plan.win.x0, plan.win.y0, plan.film.width, plan.film.height};
        if (plan.lc) out.layer_names = plan.layer_names;
        out.loads.assign(static_cast<std::size_t>(job.size()), RankLoad{});
        out.units = plan.units;
    }

    /** Places the band `rep` names, rendered by rank `from`: its pixels and its counters.
     *  Throws SpangleError when `pixels` is not the band's size. */
    void place(int from, const Report& rep, const std::vector<float>& pixels) {
        const CropWindow b = band_window(plan_.win, plan_.band_px, static_cast<uint32_t>(rep.v[0]));
        const std::size_t row0 = b.y0 - plan_.win.y0, rows = b.y1 - b.y0;
        const std::size_t n = rows * plan_.cw, cw = plan_.cw, lc = plan_.lc;
        if (pixels.size() != n * plan_.per_pixel())
            throw_error("{}: band {} came back with {} values, not {}", job_.who(), rep.v[0],
                        pixels.size(), n * plan_.per_pixel());
        std::lock_guard<std::mutex> lock(mutex_);
        std::copy(pixels.begin(), pixels.begin() + static_cast<std::ptrdiff_t>(n * 3),
                  out_.image.begin() + static_cast<std::ptrdiff_t>(row0 * cw * 3));
        if (lc)
            std::copy(pixels.begin() + static_cast<std::ptrdiff_t>(n * 3), pixels.end(),
                      out_.layers.begin() + static_cast<std::ptrdiff_t>(row0 * cw * lc));
        add_counters(from, rep);
        done_ += static_cast<uint64_t>(rep.v[2]);
        if (progress_) progress_(done_, total_);
    }

private:
    /** Adds a band's counters to its rank's load and the image's stats; mutex_ held. */
    void add_counters(int from, const Report& rep) {
        RankLoad& l = out_.loads[static_cast<std::size_t>(from)];
        ++l.units;
        l.busy += static_cast<double>(rep.v[1]) * 1e-9;
        l.samples += static_cast<uint64_t>(rep.v[2]);
        RenderStats& s = out_.stats;
        s.samples += static_cast<uint64_t>(rep.v[2]);
        s.camera_rays += static_cast<uint64_t>(rep.v[3]);
        s.bounce_rays += static_cast<uint64_t>(rep.v[4]);
        s.shadow_rays += static_cast<uint64_t>(rep.v[5]);
        // The first bad pixel in image order, as one process reports it.
        const auto key = [](int64_t y, int64_t x, int64_t k) { return std::tuple(y, x, k); };
        if (rep.v[6] > 0 && (s.nonfinite == 0 || key(rep.v[8], rep.v[7], rep.v[9]) <
                                                     key(s.first_bad_pixel_y, s.first_bad_pixel_x,
                                                         s.first_bad_sample))) {
            s.first_bad_pixel_x = static_cast<uint32_t>(rep.v[7]);
            s.first_bad_pixel_y = static_cast<uint32_t>(rep.v[8]);
            s.first_bad_sample = static_cast<uint32_t>(rep.v[9]);
        }
        s.nonfinite += static_cast<uint64_t>(rep.v[6]);
    }

    const MpiJob& job_;                                        ///< for messages
    const BandPlan& plan_;                                     ///< the bands
    const std::function<void(uint64_t, uint64_t)>& progress_;  ///< may be empty
    DistributedImage& out_;                                    ///< the image being filled
    std::mutex mutex_;                                         ///< the image, counters, progress
    uint64_t done_ = 0;                                        ///< samples placed so far
    const uint64_t total_;                                     ///< samples of the whole window
};

/** Waits for the next report from any rank (polling: a blocking receive would spin a core the
 *  renderer needs); returns the rank it came from. */
int wait_for_report(Report& rep) {
    MPI_Request req;
    MPI_Irecv(rep.v, kReportSize, MPI_INT64_T, MPI_ANY_SOURCE, kTagReport, MPI_COMM_WORLD, &req);
    int arrived = 0;
    MPI_Status st;
    for (;;) {
        MPI_Test(&req, &arrived, &st);
        if (arrived) break;
        std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    return st.MPI_SOURCE;
}

/** Receives the pixels of the band `rep` names from rank `from`, its size probed first: a band
 *  of another size is an error (SpangleError), not a silent mix. */
void receive_band(int from, const Report& rep, const BandPlan& plan, std::vector<float>& pixels) {
    const CropWindow b = band_window(plan.win, plan.band_px, static_cast<uint32_t>(rep.v[0]));
    MPI_Status probe;
    MPI_Probe(from, kTagPixels, MPI_COMM_WORLD, &probe);
    int count = 0;
    MPI_Get_count(&probe, MPI_FLOAT, &count);
    const std::size_t want = static_cast<std::size_t>(b.y1 - b.y0) * plan.cw * plan.per_pixel();
    pixels.resize(std::max<std::size_t>(static_cast<std::size_t>(count), 0));
    MPI_Recv(pixels.data(), count, MPI_FLOAT, from, kTagPixels, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    if (pixels.size() != want)
        throw_error(
            "rank {} sent band {} with {} values, not {} (do all ranks read the same scene?)", from,
            rep.v[0], pixels.size(), want);
}

/** Rank 0's answering thread: serves every other rank (places what it sends, hands it the next
 *  band from the counter rank 0 renders from too) until each has been told "none left". */
void answer_ranks(const MpiJob& job, const BandPlan& plan, Assembly& assembly,
                  std::atomic<uint32_t>& next_unit) {
    int active = job.size() - 1;
    std::vector<float> pixels;
    while (active > 0) {
        Report rep;
        const int from = wait_for_report(rep);
        if (rep.v[0] >= 0) {
            receive_band(from, rep, plan, pixels);
            assembly.place(from, rep, pixels);
        }
        const uint32_t u = next_unit.fetch_add(1);
        const int64_t next = u < plan.units ? static_cast<int64_t>(u) : -1;
        MPI_Send(&next, 1, MPI_INT64_T, from, kTagUnit, MPI_COMM_WORLD);
        if (next < 0) --active;
    }
}

/** Rank 0: renders bands from the shared counter while a second thread answers the others,
 *  then completes the image's counters. A failure on either thread ends the job. */
void render_on_rank0(const MpiJob& job, Session& session, const BandPlan& plan,
                     const std::function<void(uint64_t, uint64_t)>& progress,
                     DistributedImage& out) {
    Assembly assembly(job, plan, progress, out);
    std::atomic<uint32_t> next_unit{0};
    const auto t_start = std::chrono::steady_clock::now();
    std::string answer_error;
    std::thread answerer([&] {
        try {
            answer_ranks(job, plan, assembly, next_unit);
        } catch (const std::exception& e) {
            answer_error = e.what();
        }
    });
    std::string own_error;
    try {
        std::vector<float> pixels;
        Report rep;
        for (uint32_t u; (u = next_unit.fetch_add(1)) < plan.units;) {
            render_band(session, plan, u, pixels, rep);
            assembly.place(0, rep, pixels);
        }
    } catch (const std::exception& e) {
        own_error = e.what();
    }
    if (!own_error.empty()) {
        // The answering thread may be inside an MPI call: no MPI call from here (the library
        // only allows one at a time); exiting makes the launcher end every rank.
        fmt::print(stderr, "spangle: error: {}: {}\n", job.who(), own_error);
        std::fflush(stderr);
        std::_Exit(1);
    }
    answerer.join();
    if (!answer_error.empty()) {
        fmt::print(stderr, "spangle: error: {}: {}\n", job.who(), answer_error);
        job.abort(1);
    }
    RenderStats& s = out.stats;
    const AdaptivePlan adaptive = adaptive_plan(plan.film, session.options());
    s.spp_reached = s.spp_target = adaptive.on() ? adaptive.max_spp : plan.film.spp;
    if (adaptive.on() && plan.lc > 0 && !out.layers.empty()) {
        s.noise_threshold = adaptive.threshold;
        s.adaptive_min_spp = adaptive.min_spp;
        s.pixel_spp_min = ~0u;
        double sum = 0.0;
        std::size_t pixels = 0;
        for (std::size_t i = plan.lc - 1; i < out.layers.size(); i += plan.lc) {
            const auto n = static_cast<uint32_t>(out.layers[i]);
            s.pixel_spp_min = std::min(s.pixel_spp_min, n);
            s.pixel_spp_max = std::max(s.pixel_spp_max, n);
            sum += n;
            ++pixels;
        }
        s.pixel_spp_mean = pixels ? sum / static_cast<double>(pixels) : 0.0;
    }
    s.passes = 1;
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
}

}  // namespace

double DistributedImage::balance() const {
    double most = 0.0, sum = 0.0;
    for (const RankLoad& l : loads) {
        most = std::max(most, l.busy);
        sum += l.busy;
    }
    return sum > 0.0 ? most * static_cast<double>(loads.size()) / sum : 1.0;
}

MpiJob::MpiJob(int& argc, char**& argv) {
    int provided = 0;
    if (MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS)
        throw_error("MPI could not be started");
    if (provided < MPI_THREAD_SERIALIZED) {
        MPI_Finalize();
        throw_error(
            "this MPI library cannot be called from a second thread "
            "(MPI_THREAD_SERIALIZED), which rank 0 needs to answer the others");
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    char name[MPI_MAX_PROCESSOR_NAME] = {};
    int len = 0;
    MPI_Get_processor_name(name, &len);
    host_.assign(name, static_cast<std::size_t>(std::max(len, 0)));
}

MpiJob::~MpiJob() {
    MPI_Finalize();
}

std::string MpiJob::who() const {
    return fmt::format("rank {} of {} on {}", rank_, size_, host_);
}

std::vector<int> MpiJob::failed_ranks(bool ok) const {
    std::vector<int> all(static_cast<std::size_t>(size_), 0);
    int mine = ok ? 1 : 0;
    MPI_Allgather(&mine, 1, MPI_INT, all.data(), 1, MPI_INT, MPI_COMM_WORLD);
    std::vector<int> failed;
    for (int r = 0; r < size_; ++r)
        if (!all[static_cast<std::size_t>(r)]) failed.push_back(r);
    return failed;
}

void MpiJob::abort(int code) const {
    std::fflush(stdout);
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, code);
    std::_Exit(code);  // MPI_Abort does not return; this is for the compiler
}

bool MpiJob::render(Session& session, const CropWindow& crop, uint32_t band_rows,
                    const std::function<void(uint64_t, uint64_t)>& progress,
                    DistributedImage& out) const {
    // What every rank checks (and rank 0 allocates) before any band is handed out; a failure on
    // any rank ends the render on all of them.
    BandPlan plan;
    std::string setup_error;
    try {
        plan = plan_bands(session, crop, band_rows);
        if (rank_ == 0) {
            out = DistributedImage{};
            out.image.assign(static_cast<std::size_t>(plan.cw) * plan.ch * 3, 0.0f);
            out.layers.assign(static_cast<std::size_t>(plan.cw) * plan.ch * plan.lc, 0.0f);
        }
    } catch (const std::exception& e) {
        setup_error = e.what();
    }
    // Every rank's identity against rank 0's (collective: every rank takes part, a failed
    // plan's identity is never compared).
    RankIdentity mine;
    if (setup_error.empty()) {
        try {
            mine = identity_of(session, plan);
        } catch (const std::exception& e) {
            setup_error = e.what();
        }
    }
    RankIdentity first = mine;
    MPI_Bcast(first.v, RankIdentity::kParts, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    if (setup_error.empty() && rank_ != 0) {
        const std::string differs = first.differences(mine);
        if (!differs.empty())
            setup_error = fmt::format(
                "it differs from rank 0 in {}: every rank must render the same scene with the "
                "same files, options and plugins (a node with a stale copy, or other options in "
                "an MPMD launch, would put its own bands into the image)",
                differs);
    }
    const std::vector<int> failed = failed_ranks(setup_error.empty());
    if (!failed.empty()) {
        if (!setup_error.empty() && failed.front() == rank_)
            fmt::print(stderr, "spangle: error: {}{}\n", rank_ ? who() + ": " : "", setup_error);
        return false;
    }
    if (rank_ != 0)
        work_for_rank0(*this, session, plan);
    else
        render_on_rank0(*this, session, plan, progress, out);
    return true;
}

}  // namespace spangle
