// `spangle bench`: renders fixed scenes, each in its own process, and prints what any change to
// the engine should be compared by: samples and rays per second, time per phase, peak memory.
// The scenes: shipped ones by name, scene files, and the procedural interior (interior_scene.h),
// written on first use.

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <oneapi/tbb/task_arena.h>
#include <CLI/CLI.hpp>

#include "cli/arguments.h"
#include "cli/commands.h"
#include "cli/interior_scene.h"
#include "cli/usage.h"
#include "core/error.h"
#include "core/files.h"
#include "core/log.h"
#include "pipeline/frame.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** Options of `spangle bench`. */
struct BenchArgs {
    std::vector<std::string> scenes;  ///< scene files or shipped names; empty = the default set
    std::string size = "640x360";     ///< image size of every scene, as given ('scene': theirs)
    uint32_t width = 0, height = 0;   ///< size, parsed (0 = the scene's)
    uint32_t spp = 16;                ///< samples per pixel of every scene
    int threads = 0;                  ///< worker threads (0 = all cores)
    int repeat = 1;                   ///< renders per scene; the fastest is reported
    std::vector<std::string> plugin_dirs;  ///< --plugin-path entries, searched first
    std::string work_dir;      ///< where generated scenes go (default: a folder in the temp dir)
    std::string csv;           ///< also write the table as CSV here
    std::string export_obj;    ///< with one scene: also write its traced triangles as an OBJ
    bool measure_one = false;  ///< internal: measure scenes[0] in this process, print the result
    std::string write_scene;   ///< only write the interior scene into this folder
};

/** What one scene's render measured (in the child process). */
struct Measurement {
    std::string scene;                        ///< the scene file
    bool ok = false;                          ///< it rendered
    std::string error;                        ///< why not, on one line
    uint32_t width = 0, height = 0, spp = 0;  ///< what was rendered
    double triangles = 0;                     ///< of all instances
    double mesh_bytes = 0, accel_bytes = 0;   ///< meshes; Embree after the build
    double accel_peak = 0;                    ///< the most Embree held (bytes)
    double total = 0;                         ///< seconds from request to image
    double geometry = 0, accelerate = 0;      ///< seconds: meshes and subdivision; BVHs
    double other = 0, render = 0;             ///< seconds: the other systems; the render
    double samples = 0, camera_rays = 0;      ///< camera samples and rays traced
    double bounce_rays = 0, shadow_rays = 0;  ///< continuation and visibility rays traced
    double peak_rss = 0;                      ///< bytes (VmHWM)

    /** The measurement as the child prints it for its parent (parse reads it back). */
    std::string serialise() const {
        return fmt::format("{}\n{}\n{} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {}\n",
                           ok ? 1 : 0, error.empty() ? "-" : error, width, height, spp, triangles,
                           mesh_bytes, accel_bytes, accel_peak, total, geometry, accelerate, other,
                           render, samples, camera_rays, bounce_rays, shadow_rays, peak_rss);
    }
    /** Reads what serialise wrote. */
    void parse(const std::string& text) {
        std::istringstream in(text);
        std::string line;
        std::getline(in, line);
        ok = line == "1";
        std::getline(in, error);
        in >> width >> height >> spp >> triangles >> mesh_bytes >> accel_bytes >> accel_peak >>
            total >> geometry >> accelerate >> other >> render >> samples >> camera_rays >>
            bounce_rays >> shadow_rays >> peak_rss;
    }
    /** Every ray traced. */
    double rays() const { return camera_rays + bounce_rays + shadow_rays; }
};

/** A field of /proc/self/status in bytes (VmHWM, VmRSS, ...); 0 when unknown. */
double proc_status_bytes(const char* field) {
    std::ifstream in("/proc/self/status");
    std::string line;
    const std::string key = std::string(field) + ":";
    while (std::getline(in, line))
        if (line.rfind(key, 0) == 0) return std::atof(line.c_str() + key.size()) * 1024.0;
    return 0.0;
}

/** Renders one scene in this process (a fresh one, started by measure_in_child) and measures
 *  it; the peak memory is the whole process's, libraries included. */
Measurement measure(const std::string& scene, const BenchArgs& a, uint32_t width, uint32_t height) {
    Measurement m;
    m.scene = scene;
    Logger log;
    log.threshold = LogLevel::Warning;
    FrameRequest req;
    req.scene = scene;
    req.plugin_dirs = a.plugin_dirs;
    req.log = &log;
    req.options.threads = a.threads;
    req.options.spp_override = a.spp;
    req.options.width_override = width;
    req.options.height_override = height;
    req.options.progressive = false;
    req.export_obj = a.export_obj;
    const auto t0 = std::chrono::steady_clock::now();
    try {
        const FrameResult r = render_frame(req);
        m.total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        m.ok = true;
        m.width = r.width;
        m.height = r.height;
        m.spp = r.stats.spp_reached;
        m.triangles = static_cast<double>(r.triangles);
        m.mesh_bytes = static_cast<double>(r.mesh_bytes);
        m.accel_bytes = static_cast<double>(r.accel_bytes);
        m.accel_peak = static_cast<double>(r.accel_peak_bytes);
        double systems = 0;
        for (const auto& s : r.systems) {
            if (!s.ran) continue;
            systems += s.seconds;
            if (s.name == "mesh_load" || s.name == "subdivide")
                m.geometry += s.seconds;
            else if (s.name == "accelerate")
                m.accelerate += s.seconds;
            else if (s.name == "render")
                m.render += s.seconds;
            else
                m.other += s.seconds;
        }
        m.other += std::max(0.0, m.total - systems);  // config, parsing, plugins
        m.samples = static_cast<double>(r.stats.samples);
        m.camera_rays = static_cast<double>(r.stats.camera_rays);
        m.bounce_rays = static_cast<double>(r.stats.bounce_rays);
        m.shadow_rays = static_cast<double>(r.stats.shadow_rays);
    } catch (const std::exception& e) {
        m.error = e.what();
        std::replace(m.error.begin(), m.error.end(), '\n', ' ');
    }
    m.peak_rss = proc_status_bytes("VmHWM");
    return m;
}

/** Runs one scene's measurement in a fresh process (this binary, `bench --measure-one`), so
 *  that its peak memory is what a `spangle render` of it would take. */
Measurement measure_in_child(const std::string& scene, const BenchArgs& a, uint32_t width,
                             uint32_t height) {
    std::vector<std::string> args = {"spangle",
                                     "bench",
                                     "--measure-one",
                                     "--size",
                                     fmt::format("{}x{}", width, height),
                                     "--spp",
                                     fmt::to_string(a.spp)};
    if (width == 0) args[4] = "scene";  // the scene's own size
    if (a.threads > 0) args.insert(args.end(), {"--threads", fmt::to_string(a.threads)});
    for (const auto& d : a.plugin_dirs) args.insert(args.end(), {"--plugin-path", d});
    if (!a.export_obj.empty()) args.insert(args.end(), {"--export-obj", a.export_obj});
    args.push_back("--");
    args.push_back(scene);
    std::vector<char*> argv;
    for (auto& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    int fds[2];
    if (pipe(fds) != 0) throw_error("cannot create a pipe: {}", std::strerror(errno));
    std::fflush(stdout);
    const pid_t pid = fork();
    if (pid < 0) throw_error("cannot fork: {}", std::strerror(errno));
    if (pid == 0) {
        close(fds[0]);
        dup2(fds[1], 1);
        close(fds[1]);
        execv("/proc/self/exe", argv.data());
        _exit(127);
    }
    close(fds[1]);
    std::string text;
    char buf[4096];
    for (;;) {
        const ssize_t got = read(fds[0], buf, sizeof(buf));
        if (got <= 0) break;
        text.append(buf, static_cast<std::size_t>(got));
    }
    close(fds[0]);
    int status = 0;
    waitpid(pid, &status, 0);
    Measurement m;
    m.scene = scene;
    if (text.empty()) {
        m.error = WIFSIGNALED(status) ? fmt::format("the render died (signal {})", WTERMSIG(status))
                                      : std::string("the render process reported nothing");
        return m;
    }
    m.parse(text);
    return m;
}

/** Where the shipped scenes are: beside the binary's source tree or an installed share/. */
std::string shipped_scene(const std::string& name) {
    std::vector<fs::path> places;
    const std::string exe = executable_dir();
    if (!exe.empty()) {
        places.push_back(fs::path(exe) / ".." / "assets" / "scenes");
        places.push_back(fs::path(exe) / ".." / "share" / "spangle" / "scenes");
    }
#ifdef SPANGLE_SOURCE_DIR
    places.emplace_back(SPANGLE_SOURCE_DIR "/assets/scenes");
#endif
    for (const auto& p : places) {
        const fs::path f = p / (name + ".toml");
        std::error_code ec;
        if (fs::is_regular_file(f, ec)) return f.lexically_normal().string();
    }
    return {};
}

/** The worker threads a render with --threads n runs (0: all TBB may run), as the integrator
 *  takes them: the CSV said 0 for the default. */
int threads_used(int n) {
    const int most = tbb::this_task_arena::max_concurrency();
    return n > 0 ? std::min(n, most) : most;
}

/** "CPU model, N hardware threads" from /proc/cpuinfo, for the header of the table. */
std::string machine_description() {
    std::ifstream in("/proc/cpuinfo");
    std::string line, model = "unknown CPU";
    int threads = 0;
    while (std::getline(in, line)) {
        if (line.rfind("processor", 0) == 0) ++threads;
        if (line.rfind("model name", 0) == 0 && model == "unknown CPU") {
            const auto colon = line.find(':');
            if (colon != std::string::npos) model = line.substr(colon + 2);
        }
    }
    return fmt::format("{}, {} hardware thread{}", model, threads, threads == 1 ? "" : "s");
}

/** Bytes in MiB. */
double mib(double bytes) {
    return bytes / (1024.0 * 1024.0);
}

/** The scenes to measure as (label, file): shipped names, files and 'interior' (written into
 *  the work folder when missing). False, having said why, for a name that is none of these. */
bool bench_scenes(const BenchArgs& a, std::vector<std::pair<std::string, std::string>>& scenes) {
    std::vector<std::string> names = a.scenes;
    if (names.empty()) names = {"demo", "materials", "beetle", "interior"};
    const std::string work =
        a.work_dir.empty()
            ? (fs::temp_directory_path() / fmt::format("spangle-bench-{}", getuid())).string()
            : a.work_dir;
    for (const std::string& n : names) {
        if (n == "interior") {
            const fs::path dir = fs::path(work) / "interior";
            std::error_code ec;
            std::string file = (dir / "interior.toml").string();
            if (!fs::is_regular_file(file, ec)) {
                fmt::print("writing the interior scene to {}\n", dir.string());
                file = write_interior_scene(dir.string());
            }
            scenes.emplace_back(n, file);
            continue;
        }
        std::error_code ec;
        if (fs::is_regular_file(n, ec)) {
            scenes.emplace_back(fs::path(n).stem().string(), n);
            continue;
        }
        const std::string f = shipped_scene(n);
        if (f.empty()) {
            fmt::print(stderr,
                       "spangle: error: '{}' is neither a scene file nor a shipped scene (demo, "
                       "materials, beetle, snowman, spheres) nor 'interior'\n",
                       n);
            return false;
        }
        scenes.emplace_back(n, f);
    }
    return true;
}

/** The machine and settings, and the table's column names. */
void print_bench_header(const BenchArgs& a) {
    fmt::print("machine: {}\n", machine_description());
    fmt::print("spangle bench: {} spp, {}, {} thread(s), best of {}\n", a.spp,
               a.size.empty() ? std::string("scene sizes") : a.size,
               a.threads > 0 ? fmt::to_string(a.threads) : std::string("all"), a.repeat);
    fmt::print("{:<10} {:>9} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>7} {:>8} {:>8}\n",
               "scene", "triangles", "geom s", "bvh s", "other s", "render s", "Msamp/s", "Mrays/s",
               "rays/samp", "peak MiB", "geom MiB", "rest MiB");
}

/** The fastest of --repeat renders of `file` (the first failure, when one fails). */
Measurement best_of_repeats(const std::string& file, const BenchArgs& a) {
    Measurement best;
    for (int r = 0; r < std::max(1, a.repeat); ++r) {
        Measurement m = measure_in_child(file, a, a.width, a.height);
        if (!m.ok) return m;
        if (!best.ok || m.render < best.render) best = m;
    }
    return best;
}

/** Prints a measured scene's row of the table and appends it to the CSV text. */
void report_row(const std::string& label, const Measurement& best, const BenchArgs& a,
                std::string& csv) {
    const double geom = best.mesh_bytes + best.accel_bytes;
    const double rest = best.peak_rss - geom;
    const double msps = best.samples / best.render * 1e-6;
    const double mrps = best.rays() / best.render * 1e-6;
    fmt::print(
        "{:<10} {:>9.0f} {:>8.2f} {:>8.2f} {:>8.2f} {:>8.2f} {:>8.3f} {:>8.3f} {:>9.2f} "
        "{:>8.1f} "
        "{:>8.1f} {:>8.1f}\n",
        label, best.triangles, best.geometry, best.accelerate, best.other, best.render, msps, mrps,
        best.rays() / best.samples, mib(best.peak_rss), mib(geom), mib(rest));
    csv += fmt::format(
        "{},{},{},{},{},{:.0f},{:.3f},{:.3f},{:.3f},{:.3f},{:.4f},{:.4f},{:.0f},"
        "{:.0f},{:.0f},{:.2f},{:.2f},{:.2f},{:.2f}\n",
        label, best.width, best.height, best.spp, threads_used(a.threads), best.triangles,
        best.geometry, best.accelerate, best.other, best.render, msps, mrps, best.camera_rays,
        best.bounce_rays, best.shadow_rays, mib(best.peak_rss), mib(best.mesh_bytes),
        mib(best.accel_bytes), mib(rest));
}

/** Runs the benchmark (or, with --measure-one, one child's measurement); returns the exit
 *  status: 1 when a scene failed, 2 for a scene that does not exist. */
int run_bench(const BenchArgs& a) {
    if (a.measure_one) {
        if (a.scenes.size() != 1) return 2;
        fmt::print("{}", measure(a.scenes[0], a, a.width, a.height).serialise());
        return 0;
    }
    std::vector<std::pair<std::string, std::string>> scenes;  // (label, file)
    if (!bench_scenes(a, scenes)) return 2;
    print_bench_header(a);
    std::string csv =
        "scene,width,height,spp,threads,triangles,geometry_s,bvh_s,other_s,render_s,"
        "msamples_per_s,mrays_per_s,camera_rays,bounce_rays,shadow_rays,peak_mib,mesh_mib,"
        "bvh_mib,rest_mib\n";
    int failures = 0;
    for (const auto& [label, file] : scenes) {
        const Measurement best = best_of_repeats(file, a);
        if (!best.ok) {
            fmt::print("{:<10} failed: {}\n", label, best.error);
            ++failures;
            continue;
        }
        report_row(label, best, a, csv);
    }
    fmt::print(
        "geom MiB: meshes and Embree's BVHs after the build; rest MiB: peak minus geom "
        "(libraries, "
        "film, plugins, the BVH build's temporary memory)\n");
    if (!a.csv.empty()) {
        std::ofstream out(a.csv, std::ios::binary);
        out << csv;
        if (!out) throw_error("cannot write '{}'", a.csv);
    }
    return failures > 0 ? 1 : 0;
}

/** Registers bench's options on `sub`, bound to `a`. */
void add_bench_options(CLI::App* sub, BenchArgs& a) {
    sub->add_option("scenes", a.scenes,
                    "scene files, shipped scene names, or 'interior' (default: demo materials "
                    "beetle interior)");
    sub->add_option("--size", a.size,
                    "image size of every scene (default 640x360; 'scene' = each scene's own)");
    sub->add_option("--spp", a.spp, "samples per pixel (default 16)")
        ->check(CLI::Range(1u, 1u << 20));
    sub->add_option("--threads", a.threads, "worker threads (default: all cores)")
        ->check(CLI::Range(1, 1024));
    sub->add_option("--repeat", a.repeat, "renders per scene, the fastest counts (default 1)")
        ->check(CLI::Range(1, 100));
    sub->add_option("--plugin-path", a.plugin_dirs, "directory searched for plugins first")
        ->allow_extra_args(false);  // one folder each: the scene after it is not a folder
    sub->add_option("--work-dir", a.work_dir,
                    "where the interior scene is written (default: a folder in the temp dir)");
    sub->add_option("--csv", a.csv, "also write the results as CSV");
    sub->add_option("--export-obj", a.export_obj,
                    "with one scene: also write the triangles it traces (world space) as an OBJ, "
                    "for Embree's viewer");
    sub->add_flag("--measure-one", a.measure_one)->group("");  // internal: one child's render
    sub->add_option("--write-scene", a.write_scene,
                    "only write the procedural interior scene into this folder");
}

}  // namespace

Command add_bench_command(CLI::App& app) {
    auto a = std::make_shared<BenchArgs>();
    CLI::App* sub = app.add_subcommand(
        "bench", "render fixed scenes and print samples and rays per second, phase times, memory");
    add_bench_options(sub, *a);
    return {sub, [a] {
                if (!a->write_scene.empty()) {
                    fmt::print("wrote {}\n", write_interior_scene(a->write_scene));
                    return 0;
                }
                // 'scene': each scene's own size (an empty value, the help's word before, is
                // refused as every option's is).
                if (a->size == "scene") a->size.clear();
                if (!a->size.empty()) parse_size(a->size, a->width, a->height);
                check_plugin_dirs(a->plugin_dirs);
                return run_bench(*a);
            }};
}

}  // namespace spangle
