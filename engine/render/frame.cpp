#include "render/frame.h"

#include <filesystem>

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

FrameResult render_frame(const FrameRequest& req) {
    ColorConfig color = ColorConfig::load(req.ocio_config, default_ocio_locations());
    ecs::Registry registry;
    SceneInfo info = load_scene(req.scene, color, registry);
    for (const std::string& note : info.color_notes) req.log->warn("{}", note);
    if (req.on_loaded) req.on_loaded(color);

    PluginLoader plugins(plugin_search_path(req.plugin_dirs));
    HostServices host(color, *req.log);
    World world;
    world.color = &color;
    world.log = req.log;
    world.plugins = &plugins;
    world.host = &host;
    world.info = &info;
    world.options = req.options;

    const ecs::Schedule<World> schedule = make_frame_schedule();
    std::vector<ecs::SystemReport> reports = schedule.run(registry, world);

    FrameResult result{
        std::move(color), world.width, world.height,    std::move(world.image), std::move(reports),
        plugins.opened(), world.stats, std::move(info), world.subdiv,           {}};
    for (const auto& mat : world.materials) {
        if (!mat || !mat->model().stats) continue;
        SpangleStat_v2 buf[64];
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
