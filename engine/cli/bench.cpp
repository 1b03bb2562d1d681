#include "cli/bench.h"

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

#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"
#include "core/log.h"
#include "core/math.h"
#include "pipeline/frame.h"
#include "shading/plugin_loader.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

// ---------------------------------------------------------------------------------------------
// The procedural interior.

/** A mesh being generated: positions, normals, uvs and triangles. */
struct GenMesh {
    std::vector<float> p, n, uv;
    std::vector<uint32_t> tri;

    uint32_t add(Vec3 pos, Vec3 nrm, float u, float v) {
        const auto i = static_cast<uint32_t>(p.size() / 3);
        p.insert(p.end(), {pos.x, pos.y, pos.z});
        n.insert(n.end(), {nrm.x, nrm.y, nrm.z});
        uv.insert(uv.end(), {u, v});
        return i;
    }
};

/** A (nu x nv)-cell grid of the parametric surface f(u, v), u and v in [0, 1]; normals from
 *  central differences, turned to face away from centre(u, v) (the shape's axis). */
template <class F, class C>
void add_grid(GenMesh& m, uint32_t nu, uint32_t nv, F f, C centre) {
    const auto first = static_cast<uint32_t>(m.p.size() / 3);
    constexpr float kEps = 1e-4f;
    for (uint32_t j = 0; j <= nv; ++j)
        for (uint32_t i = 0; i <= nu; ++i) {
            const float u = static_cast<float>(i) / static_cast<float>(nu);
            const float v = static_cast<float>(j) / static_cast<float>(nv);
            const Vec3 p = f(u, v);
            const Vec3 du = f(u + kEps, v) - f(u - kEps, v);
            const Vec3 dv = f(u, std::min(v + kEps, 1.0f)) - f(u, std::max(v - kEps, 0.0f));
            Vec3 n = cross(du, dv);
            const Vec3 out = p - centre(u, v);
            if (!(length(n) > 1e-12f)) n = out;  // a pole
            n = normalize(n);
            if (dot(n, out) < 0.0f) n = -n;
            m.add(p, n, u, v);
        }
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            const uint32_t a = first + j * (nu + 1) + i, b = a + 1, c = a + nu + 1, d = c + 1;
            m.tri.insert(m.tri.end(), {a, b, d, a, d, c});
        }
}

/** A flat rectangle corner + s a + t b, (s, t) in [0, 1]^2, in nu x nv cells, facing `facing`;
 *  cells for which skip(s, t) holds at their centre are left out (a window). */
template <class S>
void add_rect(GenMesh& m, Vec3 corner, Vec3 a, Vec3 b, uint32_t nu, uint32_t nv, Vec3 facing,
              S skip) {
    Vec3 n = normalize(cross(a, b));
    const bool flip = dot(n, facing) < 0.0f;
    if (flip) n = -n;
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            const float s0 = static_cast<float>(i) / static_cast<float>(nu),
                        s1 = static_cast<float>(i + 1) / static_cast<float>(nu);
            const float t0 = static_cast<float>(j) / static_cast<float>(nv),
                        t1 = static_cast<float>(j + 1) / static_cast<float>(nv);
            if (skip(0.5f * (s0 + s1), 0.5f * (t0 + t1))) continue;
            const float su = length(a), sv = length(b);  // uv in metres
            const uint32_t q0 = m.add(corner + a * s0 + b * t0, n, s0 * su, t0 * sv);
            const uint32_t q1 = m.add(corner + a * s1 + b * t0, n, s1 * su, t0 * sv);
            const uint32_t q2 = m.add(corner + a * s1 + b * t1, n, s1 * su, t1 * sv);
            const uint32_t q3 = m.add(corner + a * s0 + b * t1, n, s0 * su, t1 * sv);
            if (flip)
                m.tri.insert(m.tri.end(), {q0, q2, q1, q0, q3, q2});
            else
                m.tri.insert(m.tri.end(), {q0, q1, q2, q0, q2, q3});
        }
}

/** Writes m as a binary little-endian PLY with normals and uvs. */
void write_ply(const GenMesh& m, const std::string& path) {
    std::ofstream out(path, std::ios::binary);
    const std::size_t nv = m.p.size() / 3, nf = m.tri.size() / 3;
    out << "ply\nformat binary_little_endian 1.0\ncomment made by spangle bench\n"
        << "element vertex " << nv
        << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n"
           "property float ny\nproperty float nz\nproperty float u\nproperty float v\n"
        << "element face " << nf << "\nproperty list uchar uint vertex_indices\nend_header\n";
    std::vector<char> buf;
    buf.reserve(nv * 32 + nf * 13);
    const auto put = [&](const void* data, std::size_t bytes) {
        const auto* c = static_cast<const char*>(data);
        buf.insert(buf.end(), c, c + bytes);
    };
    for (std::size_t i = 0; i < nv; ++i) {
        put(&m.p[3 * i], 12);
        put(&m.n[3 * i], 12);
        put(&m.uv[2 * i], 8);
    }
    for (std::size_t f = 0; f < nf; ++f) {
        const uint8_t three = 3;
        put(&three, 1);
        put(&m.tri[3 * f], 12);
    }
    out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    if (!out) throw_error("cannot write '{}'", path);
}

constexpr float kPi = 3.14159265358979f;

/** Object k of the interior: one of four shapes, its proportions varied by k so that every
 *  mesh is distinct (no instancing: 30 separate BVHs' worth of triangles). About 10,800
 *  triangles each. */
GenMesh make_object(uint32_t k) {
    const float r1 = to_unit_float(hash2(k, 1)), r2 = to_unit_float(hash2(k, 2));
    GenMesh m;
    switch (k % 4) {
        case 0: {  // a ball
            const float rad = 0.38f + 0.12f * r1;
            add_grid(
                m, 120, 45,
                [=](float u, float v) {
                    const float th = v * kPi, ph = 2 * kPi * u;
                    return Vec3(rad * std::sin(th) * std::cos(ph), rad + rad * std::cos(th),
                                rad * std::sin(th) * std::sin(ph));
                },
                [=](float, float) { return Vec3(0, rad, 0); });
            break;
        }
        case 1: {  // a standing ring
            const float big = 0.35f + 0.1f * r1, small = 0.08f + 0.06f * r2;
            add_grid(
                m, 120, 45,
                [=](float u, float v) {
                    const float a = 2 * kPi * u, b = 2 * kPi * v;
                    const float rr = big + small * std::cos(b);
                    return Vec3(rr * std::cos(a), big + small + rr * std::sin(a),
                                small * std::sin(b));
                },
                [=](float u, float) {
                    const float a = 2 * kPi * u;
                    return Vec3(big * std::cos(a), big + small + big * std::sin(a), 0.0f);
                });
            break;
        }
        case 2: {  // a twisted rounded-square column
            const float h = 1.0f + 0.8f * r1, w = 0.22f + 0.06f * r2, twist = kPi * (0.5f + r1);
            add_grid(
                m, 90, 60,
                [=](float u, float v) {
                    const float a = 2 * kPi * u, c = std::cos(a), s = std::sin(a);
                    // A superellipse of exponent 4: |x|^4 + |z|^4 = w^4.
                    const float x = w * std::copysign(std::sqrt(std::fabs(c)), c);
                    const float z = w * std::copysign(std::sqrt(std::fabs(s)), s);
                    const float t = twist * v, ct = std::cos(t), st = std::sin(t);
                    const float taper = 1.0f - 0.3f * v;
                    return Vec3((x * ct - z * st) * taper, h * v, (x * st + z * ct) * taper);
                },
                [=](float, float v) { return Vec3(0, h * v, 0); });
            break;
        }
        default: {  // a lumpy blob
            const float rad = 0.42f, fa = 3.0f + std::floor(4.0f * r1),
                        fb = 2.0f + std::floor(3.0f * r2);
            add_grid(
                m, 120, 45,
                [=](float u, float v) {
                    const float th = v * kPi, ph = 2 * kPi * u;
                    const float r = rad * (1.0f + 0.12f * std::sin(fa * ph) * std::sin(fb * th));
                    return Vec3(r * std::sin(th) * std::cos(ph), rad * 1.15f + r * std::cos(th),
                                r * std::sin(th) * std::sin(ph));
                },
                [=](float, float) { return Vec3(0, rad * 1.15f, 0); });
            break;
        }
    }
    return m;
}

constexpr const char* kInteriorMaterials = R"(
[[material]]
name = "walls"
plugin = "smooth"
model = "diffuse"
params = { albedo = 0.72 }

[[material]]
name = "floor"
plugin = "smooth"
model = "plastic"
params = { albedo = [0.36, 0.2, 0.1], roughness = 0.25 }

[[material]]
name = "m0"
plugin = "smooth"
model = "diffuse"
params = { albedo = [0.7, 0.1, 0.08] }

[[material]]
name = "m1"
plugin = "smooth"
model = "conductor"
params = { preset = "gold", roughness = 0.2 }

[[material]]
name = "m2"
plugin = "smooth"
model = "plastic"
params = { albedo = [0.1, 0.45, 0.15], roughness = 0.05 }

[[material]]
name = "m3"
plugin = "flake"
params = { base_color = [0.02, 0.05, 0.3], flake_weight = 0.5, density = 2000000, gamma = 3, coat = true }

[[material]]
name = "m4"
plugin = "smooth"
model = "dielectric"
params = { ior = 1.5, roughness = 0.0 }

[[material]]
name = "m5"
plugin = "smooth"
model = "conductor"
params = { preset = "copper", roughness = 0.35 }

[[material]]
name = "m6"
plugin = "smooth"
model = "diffuse"
params = { albedo = [0.15, 0.25, 0.6] }

[[material]]
name = "m7"
plugin = "flake"
params = { base_color = [0.3, 0.3, 0.32], flake_weight = 0.7, density = 500000, gamma = 5, color_table = true }

[[material]]
name = "m8"
plugin = "smooth"
model = "conductor"
params = { preset = "silver", roughness = 0.04 }

[[material]]
name = "m9"
plugin = "smooth"
model = "dielectric"
params = { ior = 1.45, roughness = 0.15 }

[[material]]
name = "m10"
plugin = "smooth"
model = "plastic"
params = { albedo = [0.8, 0.6, 0.1], roughness = 0.4 }

[[material]]
name = "m11"
plugin = "smooth"
model = "plastic"
params = { albedo = 0.02, roughness = 0.1 }
)";

constexpr uint32_t kInteriorObjects = 30, kInteriorMaterialCount = 12;

}  // namespace

std::string write_interior_scene(const std::string& dir) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw_error("cannot create '{}': {}", dir, ec.message());
    // The room: 12 x 4 x 10 m, a window in the left wall, the camera inside looking at -z.
    GenMesh floor, walls;
    const auto none = [](float, float) { return false; };
    add_rect(floor, {-6, 0, -5}, {12, 0, 0}, {0, 0, 10}, 24, 20, {0, 1, 0}, none);
    add_rect(walls, {-6, 4, -5}, {12, 0, 0}, {0, 0, 10}, 24, 20, {0, -1, 0}, none);  // ceiling
    add_rect(walls, {-6, 0, -5}, {12, 0, 0}, {0, 4, 0}, 24, 8, {0, 0, 1}, none);     // back
    add_rect(walls, {-6, 0, 5}, {12, 0, 0}, {0, 4, 0}, 24, 8, {0, 0, -1}, none);     // front
    add_rect(walls, {6, 0, -5}, {0, 0, 10}, {0, 4, 0}, 20, 8, {-1, 0, 0}, none);     // right
    add_rect(walls, {-6, 0, -5}, {0, 0, 10}, {0, 4, 0}, 20, 8, {1, 0, 0},            // left
             [](float s, float t) { return s > 0.2f && s < 0.6f && t > 0.25f && t < 0.8f; });
    write_ply(floor, (fs::path(dir) / "floor.ply").string());
    write_ply(walls, (fs::path(dir) / "walls.ply").string());

    std::string objects;
    for (uint32_t k = 0; k < kInteriorObjects; ++k) {
        const std::string name = fmt::format("object_{:02}.ply", k);
        write_ply(make_object(k), (fs::path(dir) / name).string());
        const uint32_t col = k % 6, row = k / 6;
        const float x = -4.5f + 1.8f * static_cast<float>(col) + 0.3f * static_cast<float>(row % 2);
        const float z = -3.8f + 1.5f * static_cast<float>(row);
        const float turn = 360.0f * to_unit_float(hash2(k, 3));
        objects += fmt::format(
            "\n[[object]]\nmesh = \"{}\"\nmaterial = \"m{}\"\ntranslate = [{:.3f}, 0, {:.3f}]\n"
            "rotate = [0, {:.1f}, 0]\n",
            name, (k * 7) % kInteriorMaterialCount, x, z, turn);
    }
    const std::string scene = fmt::format(
        R"(# A procedural interior for `spangle bench`: a closed room lit by a ceiling panel and by the
# sun through a window, with 30 distinct meshes (about 330,000 triangles) in 14 materials of
# both plugins. Paths bounce many times before they leave. Written by spangle bench; rewritten
# when missing.

[render]
width = 640
height = 360
spp = 16
max_depth = 12
rr_depth = 4
filter = "gaussian"
working_space = "ACEScg"
color_space = "srgb_texture"

[camera]
position = [0.5, 1.7, 4.6]
look_at = [-0.3, 0.6, -1.0]
fov = 62

[environment]
color = {{ rgb = [0.5, 0.65, 1.0], space = "lin_rec709" }}

[[light]]
type = "quad"
corner = [-1.0, 3.98, -1.0]
edge1 = [2.0, 0.0, 0.0]
edge2 = [0.0, 0.0, 1.0]
intensity = 12

[[light]]
type = "distant"
direction = [-1.0, 0.8, 0.35]
intensity = 4
angular_radius = 0.3
{}
[[object]]
mesh = "floor.ply"
material = "floor"

[[object]]
mesh = "walls.ply"
material = "walls"
{})",
        kInteriorMaterials, objects);
    const std::string path = (fs::path(dir) / "interior.toml").string();
    std::ofstream out(path, std::ios::binary);
    out << scene;
    if (!out) throw_error("cannot write '{}'", path);
    return path;
}

namespace {

// ---------------------------------------------------------------------------------------------
// Measuring.

/** What one scene's render measured (in the child process). */
struct Measurement {
    std::string scene;
    bool ok = false;
    std::string error;
    uint32_t width = 0, height = 0, spp = 0;
    double triangles = 0, mesh_bytes = 0, accel_bytes = 0, accel_peak = 0;
    double total = 0, geometry = 0, accelerate = 0, other = 0, render = 0;
    double samples = 0, camera_rays = 0, bounce_rays = 0, shadow_rays = 0;
    double peak_rss = 0;  ///< bytes (VmHWM)

    std::string serialise() const {
        return fmt::format("{}\n{}\n{} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {}\n",
                           ok ? 1 : 0, error.empty() ? "-" : error, width, height, spp, triangles,
                           mesh_bytes, accel_bytes, accel_peak, total, geometry, accelerate, other,
                           render, samples, camera_rays, bounce_rays, shadow_rays, peak_rss);
    }
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
    if (width == 0) args[4] = "";
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

double mib(double bytes) {
    return bytes / (1024.0 * 1024.0);
}

}  // namespace

int run_bench(const BenchArgs& a) {
    const uint32_t width = a.width, height = a.height;
    if (a.measure_one) {
        if (a.scenes.size() != 1) return 2;
        fmt::print("{}", measure(a.scenes[0], a, width, height).serialise());
        return 0;
    }
    std::vector<std::string> names = a.scenes;
    if (names.empty()) names = {"demo", "materials", "beetle", "interior"};
    const std::string work =
        a.work_dir.empty()
            ? (fs::temp_directory_path() / fmt::format("spangle-bench-{}", getuid())).string()
            : a.work_dir;
    std::vector<std::pair<std::string, std::string>> scenes;  // (label, file)
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
            return 2;
        }
        scenes.emplace_back(n, f);
    }

    fmt::print("machine: {}\n", machine_description());
    fmt::print("spangle bench: {} spp, {}, {} thread(s), best of {}\n", a.spp,
               a.size.empty() ? std::string("scene sizes") : a.size,
               a.threads > 0 ? fmt::to_string(a.threads) : std::string("all"), a.repeat);
    fmt::print("{:<10} {:>9} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>7} {:>8} {:>8}\n",
               "scene", "triangles", "geom s", "bvh s", "other s", "render s", "Msamp/s", "Mrays/s",
               "rays/samp", "peak MiB", "geom MiB", "rest MiB");
    std::string csv =
        "scene,width,height,spp,threads,triangles,geometry_s,bvh_s,other_s,render_s,"
        "msamples_per_s,mrays_per_s,camera_rays,bounce_rays,shadow_rays,peak_mib,mesh_mib,"
        "bvh_mib,rest_mib\n";
    int failures = 0;
    for (const auto& [label, file] : scenes) {
        Measurement best;
        for (int r = 0; r < std::max(1, a.repeat); ++r) {
            Measurement m = measure_in_child(file, a, width, height);
            if (!m.ok) {
                best = m;
                break;
            }
            if (!best.ok || m.render < best.render) best = m;
        }
        if (!best.ok) {
            fmt::print("{:<10} failed: {}\n", label, best.error);
            ++failures;
            continue;
        }
        const double geom = best.mesh_bytes + best.accel_bytes;
        const double rest = best.peak_rss - geom;
        const double msps = best.samples / best.render * 1e-6;
        const double mrps = best.rays() / best.render * 1e-6;
        fmt::print(
            "{:<10} {:>9.0f} {:>8.2f} {:>8.2f} {:>8.2f} {:>8.2f} {:>8.3f} {:>8.3f} {:>9.2f} "
            "{:>8.1f} "
            "{:>8.1f} {:>8.1f}\n",
            label, best.triangles, best.geometry, best.accelerate, best.other, best.render, msps,
            mrps, best.rays() / best.samples, mib(best.peak_rss), mib(geom), mib(rest));
        csv += fmt::format(
            "{},{},{},{},{},{:.0f},{:.3f},{:.3f},{:.3f},{:.3f},{:.4f},{:.4f},{:.0f},"
            "{:.0f},{:.0f},{:.2f},{:.2f},{:.2f},{:.2f}\n",
            label, best.width, best.height, best.spp, a.threads, best.triangles, best.geometry,
            best.accelerate, best.other, best.render, msps, mrps, best.camera_rays,
            best.bounce_rays, best.shadow_rays, mib(best.peak_rss), mib(best.mesh_bytes),
            mib(best.accel_bytes), mib(rest));
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

}  // namespace spangle
