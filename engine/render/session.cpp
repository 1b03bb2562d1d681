#include "render/session.h"

#include <fmt/format.h>

#include <chrono>
#include <set>
#include <typeindex>

#include "core/files.h"
#include "render/frame.h"
#include "render/systems.h"
#include "scene/scene_loader.h"
#include "shading/plugin_loader.h"

namespace spangle {

std::string ReloadReport::summary() const {
    auto list = [](const std::vector<std::string>& v) {
        return v.empty() ? std::string("nothing") : fmt::format("{}", fmt::join(v, ", "));
    };
    std::vector<std::string> reuse;
    for (const auto& [kind, n] : reused) reuse.push_back(fmt::format("{} {}", n, kind));
    return fmt::format("changed: {}; ran: {}; rebuilt: {}; reused: {}", list(changed), list(ran),
                       list(built), list(reuse));
}

Session::Session(std::vector<std::string> plugin_dirs, const std::string& ocio,
                 RenderOptions options, const Logger& log)
    : log_(log), options_(std::move(options)), ocio_request_(ocio) {
    color_ = std::make_unique<ColorConfig>(ColorConfig::load(ocio, default_ocio_locations()));
    host_ = std::make_unique<HostServices>(
        *color_, log_, TextureSettings{options_.texture_cache, options_.texture_memory_mb});
    plugins_ = std::make_unique<PluginLoader>(plugin_search_path(plugin_dirs));
    plugins_->reopen_changed = true;
}

Session::~Session() {
    // Instances before the libraries and services they use.
    world_.reset();
    cache_ = BuildCache{};
}

std::vector<std::string> Session::watched_files() const {
    std::set<std::string> all;
    if (info_) all.insert(info_->path);
    for (const auto& [kind, files] : files_)
        for (const auto& [path, id] : files) all.insert(path);
    return {all.begin(), all.end()};
}

ReloadReport Session::load(const std::string& scene, double time) {
    const auto t0 = std::chrono::steady_clock::now();
    ReloadReport rep;
    rep.first = !world_;
    bool full = rep.first;

    // Parse into a candidate. The colour config is copied so that a failed parse cannot change
    // the live one's working space; an edited OCIO config is loaded afresh.
    std::unique_ptr<ColorConfig> color;
    if (world_ && file_identity(color_->path()) != files_["ocio"][color_->path()]) {
        color = std::make_unique<ColorConfig>(
            ColorConfig::load(ocio_request_, default_ocio_locations()));
        rep.changed.push_back("file " + color_->path());
        full = true;
    } else {
        color = std::make_unique<ColorConfig>(color_->clone());
    }
    auto cand = std::make_unique<ecs::Registry>();
    auto info = std::make_unique<SceneInfo>(load_scene(scene, *color, *cand, time));
    for (const std::string& note : info->notes) log_.warn("{}", note);
    if (world_ && color->working_space() != color_->working_space()) {
        rep.changed.push_back("working space");
        full = true;
    }

    std::set<std::string> changed;
    if (!full) {
        const std::vector<std::type_index> derived = {std::type_index(typeid(TriangleMeshRef)),
                                                      std::type_index(typeid(EmitterRef))};
        for (const auto& t : ecs::Registry::changed_types(*live_, *cand, derived)) {
            changed.insert(t);
            rep.changed.push_back(t);
        }
        for (const auto& [kind, files] : files_)
            for (const auto& [path, id] : files)
                if (kind != "ocio" && file_identity(path) != id) {
                    changed.insert("file:" + kind);
                    rep.changed.push_back(fmt::format("{} file {}", kind, path));
                }
    }
    auto has = [&](const char* what) { return full || changed.count(what) > 0; };

    bool auto_levels = false;
    if (auto* p = cand->find_pool<SubdivSurface>())
        for (const SubdivOptions& o : p->columns().options)
            auto_levels = auto_levels || o.level < 0;
    const bool emitters = cand->count<Emission>() > 0;
    const bool run_mesh = has("MeshFile") || has("file:mesh");
    const bool run_subdiv = has("SubdivSurface") || has("file:cage") ||
                            (auto_levels && (has("Transform") || has("Camera") || has("Film")));
    const bool geometry = run_mesh || run_subdiv;
    const bool run_materials =
        has("Material") || has("MaterialRef") || has("file:plugin") || has("file:texture");
    // Lights are sized by the scene's bounds, which take in a moving object's whole sweep.
    const bool run_lights = geometry || has("Transform") || has("Motion") || has("QuadLight") ||
                            has("SphereLight") || has("Emission") || has("LightGroup") ||
                            has("PointLight") || has("DistantLight") || has("Environment") ||
                            has("EnvironmentMapFile") || has("file:env");
    const bool run_accel = geometry || has("Transform") || has("Motion") || has("MaterialRef") ||
                           has("QuadLight") || has("SphereLight") || has("Emission") ||
                           (emitters && run_lights);

    std::unique_ptr<HostServices> host;
    ColorConfig* live_color = full ? color.get() : color_.get();
    if (full)
        host = std::make_unique<HostServices>(
            *live_color, log_, TextureSettings{options_.texture_cache, options_.texture_memory_mb});
    auto next = std::make_unique<World>();
    next->color = live_color;
    next->log = &log_;
    next->plugins = plugins_.get();
    next->host = full ? host.get() : host_.get();
    next->info = info.get();
    next->options = options_;
    next->cache = &cache_;
    if (full && !rep.first) cache_ = BuildCache{};  // colours were converted with the old config
    cache_.begin();

    World* live = world_.get();
    bool lights_carried = false;
    // A skipped system hands over what it made for the live scene, and keeps its cache entries.
    auto carry = [&](const std::string& name) {
        if (name == "mesh_load") {
            cache_.keep("mesh|");
            for (uint32_t i = 0; i < live->mesh_file_count; ++i)
                next->geometry.meshes.push_back(live->geometry.meshes[i]);
            next->mesh_file_count = live->mesh_file_count;
            for (ecs::Entity e : cand->pool<MeshFile>().entities())
                cand->put(e, live_->get<TriangleMeshRef>(e));
        } else if (name == "subdivide") {
            cache_.keep("cage|");
            cache_.keep("subdiv|");
            const auto base = static_cast<uint32_t>(next->geometry.meshes.size());
            for (std::size_t i = live->mesh_file_count; i < live->geometry.meshes.size(); ++i)
                next->geometry.meshes.push_back(live->geometry.meshes[i]);
            for (ecs::Entity e : cand->pool<SubdivSurface>().entities())
                cand->put(e, TriangleMeshRef{live_->get<TriangleMeshRef>(e).mesh -
                                             live->mesh_file_count + base});
            next->subdiv = live->subdiv;
        } else if (name == "materials") {
            cache_.keep("material|");
            next->materials = live->materials;
        } else if (name == "accelerate") {
            next->instances = live->instances;
            next->accel = live->accel;
        } else if (!lights_carried) {  // the light table: area, point, environment, selection
            lights_carried = true;
            cache_.keep("env|");
            next->lights = live->lights;
            next->quad_vertices = live->quad_vertices;
            next->sphere_lights = live->sphere_lights;
            next->quad_light_first = live->quad_light_first;
            next->environment = live->environment;
            next->environment_group = live->environment_group;
            if (auto* p = cand->find_pool<Emission>())
                for (ecs::Entity e : p->entities())
                    if (live_->has<EmitterRef>(e)) cand->put(e, live_->get<EmitterRef>(e));
        }
    };

    const ecs::Schedule<World> schedule = make_frame_schedule();
    for (const auto& s : schedule.systems()) {
        if (s.name == "render") continue;
        if (!ecs::Schedule<World>::should_run(s, *cand, nullptr)) continue;
        const bool dirty = s.name == "mesh_load"   ? run_mesh
                           : s.name == "subdivide" ? run_subdiv
                           : s.name == "materials" ? run_materials
                           : s.name == "accelerate"
                               ? run_accel
                               : run_lights;  // area_lights, point_lights, environment, selection
        if (dirty || !live) {
            if (s.name == "accelerate" && live) next->accel = live->accel;  // keeps its BLAS
            s.run(*cand, *next);
            rep.ran.push_back(s.name);
        } else {
            carry(s.name);
            rep.skipped.push_back(s.name);
        }
    }

    // Commit: from here on nothing throws.
    if (full && !rep.first) {
        old_colors_.push_back(std::move(color_));
        old_hosts_.push_back(std::move(host_));
    }
    if (full) {
        color_ = std::move(color);
        host_ = std::move(host);
    }
    live_ = std::move(cand);
    info_ = std::move(info);
    world_ = std::move(next);
    cache_.evict();
    files_.clear();
    auto record = [&](const char* kind, const std::vector<std::string>& paths) {
        for (const std::string& f : paths) files_[kind][f] = file_identity(f);
    };
    if (auto* p = live_->find_pool<MeshFile>()) record("mesh", p->columns().path);
    if (auto* p = live_->find_pool<SubdivSurface>()) record("cage", p->columns().path);
    if (auto* p = live_->find_pool<EnvironmentMapFile>()) record("env", p->columns().path);
    for (const auto& m : world_->materials) {
        if (!m) continue;
        files_["plugin"][m->plugin().path()] = file_identity(m->plugin().path());
        // Textures: an edited image makes its material anew (the material cache's key holds
        // the file's identity) and converts the image again.
        for (const TextureBinding& t : m->textures())
            files_["texture"][t.ref.path] = file_identity(t.ref.path);
        if (m->map_kind() != MapKind::None)
            files_["texture"][m->map().ref.path] = file_identity(m->map().ref.path);
    }
    files_["ocio"][color_->path()] = file_identity(color_->path());
    rep.built = cache_.built;
    rep.reused = cache_.reused;
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return rep;
}

void Session::render() {
    world_->options = options_;
    world_->stats = RenderStats{};
    const auto& cams = live_->pool<Camera>();
    if (cams.size() == 0 || live_->count<Film>() == 0) {
        world_->image.clear();
        return;
    }
    system_render(*live_, *world_);
}

bool Session::film(Film& out) const {
    const ecs::Registry* live = live_.get();
    if (!live || live->count<Camera>() == 0 || live->count<Film>() == 0) return false;
    out = live->find_pool<Film>()->columns().get(0);
    if (options_.width_override) out.width = options_.width_override;
    if (options_.height_override) out.height = options_.height_override;
    if (options_.spp_override) out.spp = options_.spp_override;
    return true;
}

}  // namespace spangle
