#include "pipeline/frame.h"

#include <fmt/ranges.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/files.h"
#include "pipeline/session.h"
#include "render/adaptive.h"
#include "render/denoise.h"
#include "shading/plugin_loader.h"

namespace fs = std::filesystem;

namespace spangle {

std::vector<std::string> default_ocio_locations() {
    std::vector<std::string> out;
    const std::string exe = executable_dir();
    if (!exe.empty()) {
        out.push_back((fs::path(exe) / "ocio" / "config.ocio").string());
        out.push_back((fs::path(exe) / ".." / "share" / "spangle" / "ocio" / "config.ocio")
                          .lexically_normal()
                          .string());
    }
#ifdef SPANGLE_SOURCE_DIR
    out.push_back(SPANGLE_SOURCE_DIR "/assets/ocio/config.ocio");
#endif
    return out;
}

void export_world_obj(const Session& session, const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (!f) throw_error("cannot write '{}'", path);
    std::size_t base = 1;
    if (const auto* g = session.world().products.find<SceneGeometry>())
        for (const Instance& inst : g->instances) {
            const TriangleMesh& m = g->geometry.mesh(inst.mesh);
            for (std::size_t v = 0; v < m.vertex_count(); ++v) {
                const Vec3 p = inst.to_world.apply_point(m.position(static_cast<uint32_t>(v)));
                fmt::print(f, "v {} {} {}\n", p.x, p.y, p.z);
            }
            for (std::size_t t = 0; t < m.triangle_count(); ++t)
                fmt::print(f, "f {} {} {}\n", base + m.indices[3 * t], base + m.indices[3 * t + 1],
                           base + m.indices[3 * t + 2]);
            base += m.vertex_count();
        }
    if (std::fclose(f) != 0) throw_error("cannot write '{}'", path);
}

namespace {

/** What the live scene's systems built: triangles, memory, subdivision, the plugins' counters
 *  (after a render). */
void add_scene_facts(const Session& session, FrameResult& r) {
    const ecs::Products& p = session.world().products;
    if (const auto* s = p.find<SubdividedMeshes>()) r.subdiv = s->reports;
    if (const auto* g = p.find<SceneGeometry>()) {
        for (const Instance& inst : g->instances)
            r.triangles += g->geometry.mesh(inst.mesh).triangle_count();
        for (const auto& mesh : g->geometry.meshes)
            r.mesh_bytes +=
                sizeof(float) * (mesh->positions.capacity() + mesh->normals.capacity() +
                                 mesh->uvs.capacity() + mesh->rest_positions.capacity()) +
                sizeof(uint32_t) * mesh->indices.capacity();
        r.accel_bytes = g->accel->bytes();
        r.accel_peak_bytes = g->accel->peak_bytes();
    }
    if (const auto* m = p.find<MaterialSet>())
        for (const auto& mat : m->instances) {
            if (!mat || !mat->model().stats) continue;
            SpangleStat_v3 buf[64];
            uint32_t n = 0;
            call_plugin(mat->label(), "stats", [&] {
                n = std::min<uint32_t>(mat->model().stats(mat->instance(), buf, 64), 64);
            });
            std::vector<std::pair<std::string, double>> values;
            for (uint32_t i = 0; i < n; ++i)
                values.emplace_back(buf[i].name ? buf[i].name : "?", buf[i].value);
            r.material_stats.emplace_back(mat->name(), std::move(values));
        }
}

/** The scene's own crop window (pbrt's cropwindow) when the request gives none, in pixels of
 *  the film as rendered, each edge rounded up as pbrt rounds it. A window that holds no pixel
 *  leaves the whole image. */
void apply_scene_crop(Session& session) {
    RenderOptions& o = session.options();
    const SceneInfo& info = session.info();
    const auto* films = session.registry().find_pool<Film>();
    if (!o.crop.whole() || !info.crop || !films || films->size() == 0) return;
    const Film film = films->columns().get(0);
    const double w = o.width_override ? o.width_override : film.width;
    const double h = o.height_override ? o.height_override : film.height;
    const auto px = [](double f, double n) { return static_cast<uint32_t>(std::ceil(f * n)); };
    const std::array<double, 4>& c = *info.crop;  // x0, x1, y0, y1
    const CropWindow win{px(c[0], w), px(c[2], h), px(c[1], w), px(c[3], h)};
    // A window narrower than a pixel is an error, as in pbrt (it rendered the whole image).
    if (!(win.x0 < win.x1 && win.y0 < win.y1))
        throw_error(info.crop_loc,
                    "the crop window [{}] covers no pixel of the {}x{} image (pixels [{}, {}) x "
                    "[{}, {}), from ceil(fraction x size))",
                    fmt::join(c, ", "), w, h, win.x0, win.x1, win.y0, win.y1);
    o.crop = win;
}

}  // namespace

void check_request_fits_scene(Session& session) {
    const RenderOptions& o = session.options();
    const SceneInfo& info = session.info();
    Film film;
    if (!session.film(film)) return;
    const CropWindow& c = o.crop;
    if (!c.whole() && !(c.x0 < c.x1 && c.x1 <= film.width && c.y0 < c.y1 && c.y1 <= film.height)) {
        // A size the request gave (--size, Python's size=) is not the scene's to blame.
        if (o.width_override || o.height_override)
            throw_error(
                "--crop {},{},{},{} is not inside the {}x{} image (it needs x1 <= width "
                "and y1 <= height)",
                c.x0, c.y0, c.x1, c.y1, film.width, film.height);
        throw_error(info.size_loc,
                    "--crop {},{},{},{} is not inside the scene's {}x{} image (it needs x1 <= "
                    "width and y1 <= height; --size sets another)",
                    c.x0, c.y0, c.x1, c.y1, film.width, film.height);
    }
    if (o.spp_end == 0) return;
    if (o.noise_threshold_override < 0.0f && adaptive_on(film, o))
        throw_error(info.noise_threshold_loc, "{}, or give --noise-threshold 0",
                    spp_range_refusal("this scene's adaptive render (noise_threshold)"));
    if (!o.spp_override && o.spp_end > film.spp)
        throw_error(info.spp_loc,
                    "--spp-range {}..{} is not inside the scene's {} samples per pixel (it needs B "
                    "<= spp; --spp sets another)",
                    o.spp_first, o.spp_end, film.spp);
}

FrameResult render_frame(const FrameRequest& req) {
    Session session(req.plugin_dirs, req.ocio_config, req.options, *req.log);
    const ReloadReport loaded = session.load(req.scene, req.time);
    apply_scene_crop(session);
    check_request_fits_scene(session);
    if (req.on_loaded) req.on_loaded(session.color(), session.info(), session.watched_files());
    if (!req.export_obj.empty()) export_world_obj(session, req.export_obj);
    FrameResult r{session.color().clone(),
                  0,
                  0,
                  {},
                  {},
                  {},
                  {},
                  {},
                  loaded.systems,
                  {},
                  {},
                  {},
                  {},
                  0,
                  0,
                  0,
                  0,
                  {}};
    r.systems.push_back(session.render());
    RenderResult out = session.take_result();
    r.width = out.width;
    r.height = out.height;
    r.window = out.window;
    r.image = std::move(out.image);
    r.layers = std::move(out.layers);
    r.layer_names = std::move(out.layer_names);
    r.sums = std::move(out.sums);
    r.stats = out.stats;
    if (req.options.denoise && r.stats.spp_reached > 0)
        denoise_and_record(DenoiseImage{&r.image, &r.layers, &r.layer_names, r.width, r.height},
                           req.options.denoise_glints, req.options.threads,
                           denoise_control(req.options), *req.log, r.stats);
    r.info = session.info();
    r.plugins_opened = session.plugins().opened();
    add_scene_facts(session, r);
    return r;
}

}  // namespace spangle
