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
#include <mutex>
#include <thread>
#include <tuple>

#include "core/error.h"
#include "pipeline/session.h"
#include "render/layers/layer_sink.h"

namespace spangle {
namespace {

constexpr int kTagReport = 1, kTagPixels = 2, kTagUnit = 3;
constexpr int kReportSize = 10;

int env_int(const char* name, int fallback) {
    const char* v = std::getenv(name);
    if (!v || !*v) return fallback;
    char* end = nullptr;
    const long n = std::strtol(v, &end, 10);
    return end && *end == '\0' && n >= 0 && n < (1L << 30) ? static_cast<int>(n) : fallback;
}

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
    int64_t v[kReportSize] = {};
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

}  // namespace

LauncherInfo launcher_info() {
    // Open MPI's names, then MPICH/Hydra's and Slurm's.
    LauncherInfo l;
    // (Not Slurm's SLURM_NTASKS: a batch script has it without being a rank.)
    l.size = env_int("OMPI_COMM_WORLD_SIZE", env_int("PMI_SIZE", 1));
    l.rank = env_int("OMPI_COMM_WORLD_RANK", env_int("PMI_RANK", 0));
    l.local_size = env_int("OMPI_COMM_WORLD_LOCAL_SIZE", env_int("MPI_LOCALNRANKS", 1));
    l.size = std::max(l.size, 1);
    l.local_size = std::max(l.local_size, 1);
    return l;
}

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
    Film film;
    CropWindow win;
    std::size_t lc = 0;
    std::vector<std::string> groups = session.info().light_groups;
    if (groups.empty()) groups.push_back("default");
    uint32_t band_px = 0, units = 0, cw = 0, ch = 0;
    std::string setup_error;
    try {
        if (!session.film(film)) throw_error("the scene has no camera to render from");
        win = crop_within(crop, film.width, film.height);
        band_px = 16 * std::max(band_rows, 1u);
        units = (win.y1 - 1) / band_px - win.y0 / band_px + 1;
        cw = win.x1 - win.x0;
        ch = win.y1 - win.y0;
        lc = session.options().layers ? layer_channel_names(groups).size() : 0;
        if (static_cast<double>(band_px) * cw * static_cast<double>(3 + lc) >= 2147483647.0)
            throw_error("bands of {} rows of {} pixels are too large to send: lower --band-rows",
                        band_px, cw);
        if (rank_ == 0) {
            out = DistributedImage{};
            out.image.assign(static_cast<std::size_t>(cw) * ch * 3, 0.0f);
            out.layers.assign(static_cast<std::size_t>(cw) * ch * lc, 0.0f);
        }
    } catch (const std::exception& e) {
        setup_error = e.what();
    }
    const std::vector<int> failed = failed_ranks(setup_error.empty());
    if (!failed.empty()) {
        if (!setup_error.empty() && failed.front() == rank_)
            fmt::print(stderr, "spangle: error: {}{}\n", rank_ ? who() + ": " : "", setup_error);
        return false;
    }
    const std::size_t per_pixel = 3 + lc;

    // Renders band `unit` on this rank; returns its pixels (RGB rows, then layer rows).
    const auto render_band = [&](uint32_t unit, std::vector<float>& pixels, Report& report) {
        const auto t0 = std::chrono::steady_clock::now();
        session.options().crop = band_window(win, band_px, unit);
        session.render();
        const RenderResult& w = session.result();
        pixels.assign(w.image.begin(), w.image.end());
        pixels.insert(pixels.end(), w.layers.begin(), w.layers.end());
        report = Report::of(
            unit, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
            w.stats);
    };

    if (rank_ != 0) {
        // Ask, render, send back, ask again -- until rank 0 says there is nothing left.
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
                render_band(static_cast<uint32_t>(next), pixels, report);
            } catch (const std::exception& e) {
                fmt::print(stderr, "spangle: error: {}: band {} failed: {}\n", who(), next,
                           e.what());
                abort(1);
            }
        }
        return true;
    }

    // Rank 0: the image, filled by its own bands and the others'.
    out.width = cw;
    out.height = ch;
    out.window = ImageWindow{win.x0, win.y0, film.width, film.height};
    if (lc) out.layer_names = layer_channel_names(groups);
    out.loads.assign(static_cast<std::size_t>(size_), RankLoad{});
    out.units = units;
    std::atomic<uint32_t> next_unit{0};
    std::mutex mutex;  // the image, the counters, progress
    const uint64_t total = static_cast<uint64_t>(cw) * ch * film.spp;
    uint64_t done = 0;
    const auto t_start = std::chrono::steady_clock::now();
    const auto place = [&](int from, const Report& rep, const std::vector<float>& pixels) {
        const CropWindow b = band_window(win, band_px, static_cast<uint32_t>(rep.v[0]));
        const std::size_t row0 = b.y0 - win.y0, rows = b.y1 - b.y0;
        const std::size_t n = rows * cw;
        if (pixels.size() != n * per_pixel)
            throw_error("{}: band {} came back with {} values, not {}", who(), rep.v[0],
                        pixels.size(), n * per_pixel);
        std::lock_guard<std::mutex> lock(mutex);
        std::copy(pixels.begin(), pixels.begin() + static_cast<std::ptrdiff_t>(n * 3),
                  out.image.begin() + static_cast<std::ptrdiff_t>(row0 * cw * 3));
        if (lc)
            std::copy(pixels.begin() + static_cast<std::ptrdiff_t>(n * 3), pixels.end(),
                      out.layers.begin() + static_cast<std::ptrdiff_t>(row0 * cw * lc));
        RankLoad& l = out.loads[static_cast<std::size_t>(from)];
        ++l.units;
        l.busy += static_cast<double>(rep.v[1]) * 1e-9;
        l.samples += static_cast<uint64_t>(rep.v[2]);
        RenderStats& s = out.stats;
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
        done += static_cast<uint64_t>(rep.v[2]);
        if (progress) progress(done, total);
    };

    // The answering thread: serves every other rank until each has been told "none left".
    std::string answer_error;
    std::thread answerer([&] {
        try {
            int active = size_ - 1;
            std::vector<float> pixels;
            while (active > 0) {
                Report rep;
                MPI_Request req;
                MPI_Irecv(rep.v, kReportSize, MPI_INT64_T, MPI_ANY_SOURCE, kTagReport,
                          MPI_COMM_WORLD, &req);
                int arrived = 0;
                MPI_Status st;
                for (;;) {
                    MPI_Test(&req, &arrived, &st);
                    if (arrived) break;
                    std::this_thread::sleep_for(std::chrono::microseconds(200));
                }
                const int from = st.MPI_SOURCE;
                if (rep.v[0] >= 0) {
                    const CropWindow b = band_window(win, band_px, static_cast<uint32_t>(rep.v[0]));
                    // Its size first: a band of another size is an error, not a silent mix.
                    MPI_Status probe;
                    MPI_Probe(from, kTagPixels, MPI_COMM_WORLD, &probe);
                    int count = 0;
                    MPI_Get_count(&probe, MPI_FLOAT, &count);
                    const std::size_t want = static_cast<std::size_t>(b.y1 - b.y0) * cw * per_pixel;
                    pixels.resize(std::max<std::size_t>(static_cast<std::size_t>(count), 0));
                    MPI_Recv(pixels.data(), count, MPI_FLOAT, from, kTagPixels, MPI_COMM_WORLD,
                             MPI_STATUS_IGNORE);
                    if (pixels.size() != want)
                        throw_error(
                            "rank {} sent band {} with {} values, not {} (do all ranks read the "
                            "same scene?)",
                            from, rep.v[0], pixels.size(), want);
                    place(from, rep, pixels);
                }
                const uint32_t u = next_unit.fetch_add(1);
                const int64_t next = u < units ? static_cast<int64_t>(u) : -1;
                MPI_Send(&next, 1, MPI_INT64_T, from, kTagUnit, MPI_COMM_WORLD);
                if (next < 0) --active;
            }
        } catch (const std::exception& e) {
            answer_error = e.what();
        }
    });
    std::string own_error;
    try {
        std::vector<float> pixels;
        Report rep;
        for (uint32_t u; (u = next_unit.fetch_add(1)) < units;) {
            render_band(u, pixels, rep);
            place(0, rep, pixels);
        }
    } catch (const std::exception& e) {
        own_error = e.what();
    }
    if (!own_error.empty()) {
        // The answering thread may be inside an MPI call: no MPI call from here (the library
        // only allows one at a time); exiting makes the launcher end every rank.
        fmt::print(stderr, "spangle: error: {}: {}\n", who(), own_error);
        std::fflush(stderr);
        std::_Exit(1);
    }
    answerer.join();
    if (!answer_error.empty()) {
        fmt::print(stderr, "spangle: error: {}: {}\n", who(), answer_error);
        abort(1);
    }
    RenderStats& s = out.stats;
    s.spp_reached = s.spp_target = film.spp;
    s.passes = 1;
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    return true;
}

}  // namespace spangle
