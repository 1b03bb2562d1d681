#include "render/frame.h"

#include <cstdio>
#include <filesystem>

#include "core/files.h"
#include "render/systems.h"
#include "scene/scene_loader.h"
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

namespace {

/** Writes every instance's triangles in world space as one OBJ. */
void export_world_obj(const World& world, const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (!f) throw_error("cannot write '{}'", path);
    std::size_t base = 1;
    for (const Instance& inst : world.instances) {
        const TriangleMesh& m = world.geometry.mesh(inst.mesh);
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

}  // namespace

FrameResult render_frame(const FrameRequest& req) {
    ColorConfig color = ColorConfig::load(req.ocio_config, default_ocio_locations());
    ecs::Registry registry;
    SceneInfo info = load_scene(req.scene, color, registry, req.time);
    for (const std::string& note : info.notes) req.log->warn("{}", note);
    if (req.on_loaded) req.on_loaded(color, info);

    PluginLoader plugins(plugin_search_path(req.plugin_dirs));
    HostServices host(color, *req.log, {req.options.texture_cache, req.options.texture_memory_mb});
    World world;
    world.color = &color;
    world.log = req.log;
    world.plugins = &plugins;
    world.host = &host;
    world.info = &info;
    world.options = req.options;

    const ecs::Schedule<World> schedule = make_frame_schedule();
    std::vector<ecs::SystemReport> reports = schedule.run(registry, world);
    if (!req.export_obj.empty()) export_world_obj(world, req.export_obj);

    FrameResult result{std::move(color),
                       world.width,
                       world.height,
                       world.window,
                       std::move(world.image),
                       std::move(world.layers),
                       std::move(world.layer_names),
                       std::move(world.sums),
                       std::move(reports),
                       plugins.opened(),
                       world.stats,
                       std::move(info),
                       world.subdiv,
                       0,
                       0,
                       0,
                       0,
                       {}};
    for (const Instance& inst : world.instances)
        result.triangles += world.geometry.mesh(inst.mesh).triangle_count();
    for (const auto& mesh : world.geometry.meshes)
        result.mesh_bytes += sizeof(float) * (mesh->positions.capacity() +
                                              mesh->normals.capacity() + mesh->uvs.capacity()) +
                             sizeof(uint32_t) * mesh->indices.capacity();
    if (world.accel) {
        result.accel_bytes = world.accel->bytes();
        result.accel_peak_bytes = world.accel->peak_bytes();
    }
    for (const auto& mat : world.materials) {
        if (!mat || !mat->model().stats) continue;
        SpangleStat_v3 buf[64];
        const uint32_t n = std::min<uint32_t>(mat->model().stats(mat->instance(), buf, 64), 64);
        std::vector<std::pair<std::string, double>> values;
        for (uint32_t i = 0; i < n; ++i)
            values.emplace_back(buf[i].name ? buf[i].name : "?", buf[i].value);
        result.material_stats.emplace_back(mat->name(), std::move(values));
    }
    // Materials go before the loader that holds their libraries (shared ownership keeps the
    // library open until the last instance is destroyed anyway).
    world.materials.clear();
    return result;
}

}  // namespace spangle
