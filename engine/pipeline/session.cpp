#include "pipeline/session.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <set>
#include <typeindex>

#include "core/files.h"
#include "core/hash.h"
#include "pipeline/frame.h"
#include "pipeline/systems.h"
#include "render/adaptive.h"
#include "render/integrator.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "shading/plugin_loader.h"

namespace fs = std::filesystem;

namespace spangle {

namespace {

/** The finest angle between neighbouring pixels' rays that 32-bit directions resolve, with room
 *  for the sub-pixel positions of the samples (a direction's components are known to about
 *  6e-8). */
constexpr double kFinestPixelAngle = 2e-7;

/** The render, declared like the systems (the session runs the path tracer itself). */
const ecs::System<World>& render_system() {
    static const ecs::System<World> s =
        ecs::system<World>("render", nullptr).needs_all<Camera, Film>();
    return s;
}

/** Every component type some system writes: they are derived, not part of the scene's diff. */
std::vector<std::type_index> derived_components(const ecs::Schedule<World>& schedule) {
    std::vector<std::type_index> out;
    for (const auto& s : schedule.systems())
        for (const ecs::Resource& w : s.writes)
            if (!w.product) out.push_back(w.type);
    return out;
}

/** The files a system read for the live scene that have changed since, as reload report lines
 *  ("mesh file PATH"), in order of kind then path. A file saved again with the same bytes (a
 *  bad save put back, a touch, an editor's save without an edit) has not: its bytes are compared
 *  with those the live scene read, by their hash in `hashes` (path -> identity, hash; files of
 *  at most kContentHashedBytes, whose hash covers every byte). */
std::vector<std::string> edited_files(
    const std::map<std::string, FileRead>& files,
    const std::map<std::string, std::pair<std::string, uint64_t>>& hashes) {
    std::vector<std::pair<std::string, std::string>> edited;
    for (const auto& [path, read] : files) {
        if (file_identity(path) == read.identity) continue;
        const auto it = hashes.find(path);
        std::error_code ec;
        const uintmax_t size = std::filesystem::file_size(path, ec);
        if (it != hashes.end() && it->second.first == read.identity && !ec &&
            size <= kContentHashedBytes && file_content_hash(path) == it->second.second)
            continue;
        edited.emplace_back(read.kind, path);
    }
    std::sort(edited.begin(), edited.end());
    std::vector<std::string> out;
    for (const auto& [kind, path] : edited) out.push_back(fmt::format("{} file {}", kind, path));
    return out;
}

/** A skipped system's writes, handed over from the live scene: its products, the components it
 *  put on the entities of its needs, its cache entries and the files it read. */
void carry(const ecs::System<World>& s, const ecs::Registry& live_registry, const World& live,
           ecs::Registry& cand, World& next, BuildCache& cache) {
    for (const ecs::Resource& w : s.writes) {
        if (w.product) {
            next.products.take(w.type, live.products);
            continue;
        }
        for (const ecs::Resource& need : s.needs)
            for (ecs::Entity e : cand.entities_of(need.type))
                cand.copy_component(w.type, live_registry, e);
    }
    cache.keep(s.name);
    if (auto it = live.files.find(s.name); it != live.files.end()) next.files[s.name] = it->second;
}

}  // namespace

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
    ocio_identity_ = file_identity(color_->path());
    ocio_bytes_ = file_content_hash(color_->path());
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
    if (info_ && !info_->path.empty()) all.insert(info_->path);
    if (info_) all.insert(info_->files.begin(), info_->files.end());
    if (world_)
        for (const auto& [system, files] : world_->files)
            for (const auto& [path, read] : files) all.insert(path);
    if (color_) {
        all.insert(color_->path());
        for (const std::string& lut : color_->lut_files()) all.insert(lut);
    }
    return {all.begin(), all.end()};
}

void Session::check_memory(const ecs::Registry& cand, const SceneInfo& info) const {
    // The film of a whole frame, at least (no layers counted; a crop renders less): an edit
    // asking for more than the machine has is refused as a load, so that the last good scene
    // stays (refused when its render began, it stopped the render in progress and was taken as
    // the live scene).
    if (!options_.film_memory_at_load || cand.count<Film>() == 0 || !options_.crop.whole() ||
        info.crop)
        return;
    Film f = cand.find_pool<Film>()->columns().get(0);
    const bool sized = options_.width_override || options_.height_override;
    apply_overrides(f);
    try {
        check_film_memory(f.width, f.height, f.spp, options_, 0);
    } catch (const SpangleError& e) {
        if (sized || info.size_loc.file.empty()) throw;
        throw_error(info.size_loc, "{}", e.what());
    }
}

std::vector<uint64_t> Session::read_content_hashes(const std::vector<std::string>& except) const {
    std::vector<uint64_t> out;
    for (const auto& [path, read] : file_hashes_) {
        bool skip = false;
        for (const std::string& e : except) {
            std::error_code ec;
            skip = skip || path == e || fs::equivalent(path, e, ec);
        }
        if (!skip) out.push_back(read.second);
    }
    std::sort(out.begin(), out.end());
    return out;
}

bool Session::holds_what_was_read(const std::string& path) const {
    for (const auto& [p, read] : file_hashes_) {
        std::error_code ec;
        if (p != path && !fs::equivalent(p, path, ec)) continue;
        // An identity cleared at the load: the file changed while it was read. A file beyond
        // what the hash reads whole (its size alone) may have changed within its size.
        if (read.first.empty() || fs::file_size(p, ec) > kContentHashedBytes || ec) return false;
        return file_content_hash(p) == read.second;
    }
    return false;
}

ReloadReport Session::load(const std::string& scene, double time) {
    const auto t0 = std::chrono::steady_clock::now();
    ReloadReport rep = load(read_scene(scene, read_options()), time);
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return rep;
}

ReloadReport Session::load_frame(const std::string& scene, int64_t frame) {
    const auto t0 = std::chrono::steady_clock::now();
    const SceneDescription d = read_scene(scene, read_options());
    ReloadReport rep = load(d, static_cast<double>(frame - d.render.frame_start) / d.render.fps);
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return rep;
}

ReloadReport Session::load(const SceneDescription& scene, double time) {
    // Keyframes are evaluated at `time`: NaN crashed their evaluation, and beyond 1e9 s a frame
    // number overflowed.
    if (!(std::fabs(time) <= 1e9))
        throw_error("the scene's time {} s must be a number within +-1e9 s", time);
    const auto t0 = std::chrono::steady_clock::now();
    ReloadReport rep;
    rep.first = !world_;
    bool full = rep.first;

    // Read into a candidate. The colour config is copied so that a failed read cannot change
    // the live one's working space; an edited OCIO config is loaded afresh.
    std::unique_ptr<ColorConfig> color;
    const bool luts_edited = world_ && color_->lut_files_changed();
    // The config's identity and bytes before it is read (a save landing while it loads is
    // seen by the next reload).
    const std::string loaded_identity = world_ ? file_identity(color_->path()) : std::string();
    const uint64_t loaded_bytes = world_ ? file_content_hash(color_->path()) : 0;
    bool config_edited = world_ && loaded_identity != ocio_identity_;
    if (config_edited && loaded_bytes == ocio_bytes_) {
        // Saved again with the same bytes (a touch, a save without an edit, a bad edit put
        // back): not an edit. It rebuilt the whole scene (every mesh subdivided again) and
        // threw the finished image away.
        ocio_identity_ = loaded_identity;
        config_edited = false;
    }
    if (config_edited || luts_edited) {
        // OpenColorIO keeps the LUTs it read for the process: an edited one must be read again
        // (the reloaded config rendered with the old LUT, unlike a fresh render).
        ColorConfig::forget_read_files();
        color = std::make_unique<ColorConfig>(
            ColorConfig::load(ocio_request_, default_ocio_locations()));
        if (!luts_edited && color->content_hash() == color_->content_hash()) {
            // Other bytes, the same config (a comment edited; where no conversion has read a
            // LUT, whose bytes the live config's hash holds too): not an edit either.
            ocio_identity_ = loaded_identity;
            ocio_bytes_ = loaded_bytes;
            color = std::make_unique<ColorConfig>(color_->clone());
        } else {
            if (config_edited) rep.changed.push_back("file " + color_->path());
            if (luts_edited) rep.changed.push_back("the OCIO config's LUT files");
            full = true;
        }
    } else {
        color = std::make_unique<ColorConfig>(color_->clone());
    }
    auto cand = std::make_unique<ecs::Registry>();
    auto info = std::make_unique<SceneInfo>(build_scene(scene, *color, *cand, time));
    if (full && !rep.first && check_reloaded_config) check_reloaded_config(*color);
    for (const std::string& note : info->notes) log_.warn("{}", note);
    if (world_ && color->working_space() != color_->working_space()) {
        rep.changed.push_back("working space");
        full = true;
    }

    const ecs::Schedule<World> schedule = build_schedule();
    std::set<std::type_index> changed;
    std::map<std::string, bool> edited;  // system -> a file it read was edited
    if (!full) {
        for (const auto& [type, name] :
             ecs::Registry::changed_pools(*live_, *cand, derived_components(schedule))) {
            changed.insert(type);
            rep.changed.push_back(name);
        }
        std::vector<std::string> files;
        for (const auto& [system, reads] : world_->files) {
            const std::vector<std::string> lines = edited_files(reads, file_hashes_);
            edited[system] = !lines.empty();
            files.insert(files.end(), lines.begin(), lines.end());
        }
        std::sort(files.begin(), files.end());
        files.erase(std::unique(files.begin(), files.end()), files.end());
        rep.changed.insert(rep.changed.end(), files.begin(), files.end());
    }

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
    next->previous = world_.get();
    if (full && !rep.first) cache_ = BuildCache{};  // colours were converted with the old config
    cache_.begin();

    for (const auto& s : schedule.systems()) {
        ecs::SystemReport sr{s.name, false, {}, 0.0};
        if (!ecs::Schedule<World>::should_run(s, *cand, &sr.reason)) {
            rep.systems.push_back(std::move(sr));
            continue;
        }
        if (full || s.affected_by(changed, *cand) || edited[s.name]) {
            const auto ts = std::chrono::steady_clock::now();
            next->system = s.name;
            cache_.owner = s.name;
            s.run(*cand, *next);
            sr.ran = true;
            sr.seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - ts).count();
            rep.ran.push_back(s.name);
            // What it wrote changed for the systems after it: products always, components
            // where they differ from the live scene's.
            for (const ecs::Resource& w : s.writes)
                if (w.product || !live_ || !cand->same_pool(w.type, *live_)) changed.insert(w.type);
        } else {
            carry(s, *live_, *world_, *cand, *next, cache_);
            sr.reason = "nothing it reads changed";
            rep.skipped.push_back(s.name);
        }
        rep.systems.push_back(std::move(sr));
    }
    next->system.clear();
    next->previous = nullptr;
    // The scene's hash covers the files the systems read too (a mesh or texture edited between
    // crop parts made parts that merged into a seam): each file's bytes hashed once per
    // identity (path, size, modification time), combined in the order of the hashes. (Bytes only,
    // not paths: farm nodes may mount the same files elsewhere.)
    std::map<std::string, std::pair<std::string, uint64_t>> hashes;
    {
        std::map<std::string, std::string> read;  // path -> identity
        for (const auto& [system, reads] : next->files)
            for (const auto& [path, fr] : reads)
                if (fr.kind != kAbsentPluginKind) read[path] = fr.identity;
        uint64_t h = info->content_hash;
        std::vector<uint64_t> bytes;  // the files' hashes, in an order of their own
        for (const auto& [path, identity] : read) {
            auto it = file_hashes_.find(path);
            const bool known = it != file_hashes_.end() && it->second.first == identity;
            const uint64_t fh = known ? it->second.second : file_content_hash(path);
            // The bytes hashed now are the bytes the load read only if the file has not changed
            // since: a mesh saved while its edit loaded, then put back, was taken for unchanged
            // (its hash, of the bytes put back, matched them) and the edit stayed on screen. A
            // file changed since it was read keeps no hash: the next reload reads it again.
            const bool same = known || file_identity(path) == identity;
            hashes[path] = {same ? identity : std::string(), fh};
            bytes.push_back(fh);
        }
        // Combined in the order of the hashes, not of the paths: nodes that mount the same
        // files elsewhere (or name them in another order) give one hash, and their crop parts
        // merge.
        std::sort(bytes.begin(), bytes.end());
        for (const uint64_t fh : bytes) h = hash2(h, fh);
        // And the colour config's text: parts of a crop render made before and after an edit
        // of the config in place (the same space names) merged into a seam.
        h = hash2(h, live_color->content_hash());
        // And whether --env replaced the environment (its map's bytes are hashed above, but the
        // scene's own intensity, rotation and colour space it drops are not, when it names the
        // scene's own map). (The camera looked through is in the builder's hash, by what it is:
        // --camera naming the camera the file looks through anyway is the same render.)
        info->content_hash = hash2(h, options_.environment.empty() ? 0x0u : 0xe1u);
    }

    // The film, once the systems' own needs (subdivision, maps, BVHs) are met and said.
    check_memory(*cand, *info);

    // Commit: from here on nothing throws.
    if (full && !rep.first) {
        old_colors_.push_back(std::move(color_));
        old_hosts_.push_back(std::move(host_));
    }
    if (full) {
        color_ = std::move(color);
        host_ = std::move(host);
        ocio_identity_ = loaded_identity.empty() ? file_identity(color_->path()) : loaded_identity;
        ocio_bytes_ = loaded_identity.empty() ? file_content_hash(color_->path()) : loaded_bytes;
    }
    live_ = std::move(cand);
    info_ = std::move(info);
    file_hashes_ = std::move(hashes);
    world_ = std::move(next);
    cache_.evict();
    rep.built = cache_.built;
    rep.reused = cache_.reused;
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return rep;
}

RenderScene Session::render_scene() const {
    static const GeometryStore no_geometry;
    static const std::vector<Instance> no_instances;
    static const std::vector<std::shared_ptr<MaterialInstance>> no_materials;
    static const LightTable no_lights;
    const ecs::Products& p = world_->products;
    RenderScene s;
    const SceneGeometry* g = p.find<SceneGeometry>();
    s.geometry = g ? &g->geometry : &no_geometry;
    s.instances = g ? &g->instances : &no_instances;
    s.accel = g ? g->accel.get() : nullptr;
    if (const CutOutSet* c = p.find<CutOutSet>()) {
        s.cut_outs = &c->per_instance;
        s.emitter_cuts = &c->emitters;
    }
    const MaterialSet* m = p.find<MaterialSet>();
    s.materials = m ? &m->instances : &no_materials;
    const SceneLights* l = p.find<SceneLights>();
    s.lights = l ? &l->table : &no_lights;
    if (const AreaLightSet* a = p.find<AreaLightSet>()) s.quad_light_first = a->quad_first;
    if (const EnvironmentLight* e = p.find<EnvironmentLight>()) {
        s.environment = e->constant;
        s.environment_group = e->constant_group;
    }
    s.host = host_.get();
    s.light_groups = &info_->light_groups;
    s.object_names = &info_->object_names;
    s.material_names = &info_->material_names;
    return s;
}

ecs::SystemReport Session::render() {
    ecs::SystemReport rep{"render", false, {}, 0.0};
    result_.stats = RenderStats{};
    if (!ecs::Schedule<World>::should_run(render_system(), *live_, &rep.reason)) {
        result_.image.clear();
        return rep;
    }
    Film film;
    this->film(film);
    const ecs::Entity camera = live_->pool<Camera>().entities()[0];
    const std::vector<Camera> steps = live_->has<CameraMotion>(camera)
                                          ? live_->get<CameraMotion>(camera).steps
                                          : std::vector<Camera>{};
    // --min-spp / --max-spp bound adaptive sampling only: said once, not ignored silently.
    if ((options_.min_spp_override || options_.max_spp_override) && !adaptive_warned_ &&
        !adaptive_on(film, options_)) {
        log_.warn(
            "--min-spp and --max-spp bound adaptive sampling, which is off (no --noise-threshold "
            "and no [render] noise_threshold): every pixel takes the scene's spp");
        adaptive_warned_ = true;
    }
    if ((film.min_spp || film.max_spp) && !adaptive_warned_ && !adaptive_on(film, options_)) {
        log_.warn(
            "{}: [render] min_spp and max_spp bound adaptive sampling, which is off (no "
            "noise_threshold): every pixel takes spp",
            info_ ? info_->path : std::string("the scene"));
        adaptive_warned_ = true;
    }
    // min_spp (rounded up to a multiple of 4, at least 8) reaching max_spp leaves nothing to
    // adapt: said once, not a header that says adaptive over an image that is not.
    if (!adaptive_warned_ && adaptive_on(film, options_)) {
        const AdaptivePlan plan = adaptive_plan(film, options_);
        if (plan.min_spp >= plan.max_spp) {
            log_.warn(
                "adaptive sampling has nothing to adapt: min_spp, rounded up to a multiple of 4 "
                "and at least 8, reaches the {} samples a pixel may take, so every pixel takes "
                "them",
                plan.max_spp);
            adaptive_warned_ = true;
        }
    }
    // --spp raises no adaptive pixel above the scene's max_spp: said once.
    if (options_.spp_override && !options_.max_spp_override && film.max_spp &&
        film.max_spp < options_.spp_override && !adaptive_warned_ && adaptive_on(film, options_)) {
        log_.warn(
            "--spp {}: with adaptive sampling the scene's max_spp {} is the most samples a pixel "
            "takes (give --max-spp to change it)",
            options_.spp_override, film.max_spp);
        adaptive_warned_ = true;
    }
    // A panorama maps 360 x 180 degrees onto the image: anything but 2:1 stretches it. Said once.
    const Camera& cam = live_->get<Camera>(camera);
    if (cam.equirect && !panorama_warned_ &&
        std::abs(static_cast<double>(film.width) - 2.0 * film.height) > 0.01 * film.width + 1.0) {
        log_.warn(
            "the equirectangular camera maps 360 x 180 degrees onto a {}x{} image, which is not "
            "2:1: a pixel spans {:.3g} degrees across and {:.3g} up, so the panorama is stretched "
            "(give --size {}x{}, or a 2:1 width and height in the scene)",
            film.width, film.height, 360.0 / film.width, 180.0 / film.height, 2 * film.height,
            film.height);
        panorama_warned_ = true;
    }
    // A perspective camera whose pixels are closer together than a float direction can tell
    // (a telephoto of something 1e6 units away): neighbouring pixels' rays coincide, in streaks
    // and blocks. Said (once per session: the logger drops repeats where it keeps them).
    if (!cam.equirect && !(cam.ortho_height > 0.0f)) {
        // The image's height on the plane at distance 1: 2 tan(fov / 2), or a screen window's
        // (pbrt's, in units of tan(fov / 2): a narrow one zooms in as a small fov does).
        const double unit = std::tan(static_cast<double>(cam.fov_deg) * std::numbers::pi / 360.0);
        const bool window = cam.screen[0] != 0.0f || cam.screen[1] != 0.0f ||
                            cam.screen[2] != 0.0f || cam.screen[3] != 0.0f;
        const uint32_t across =
            cam.fov_shorter && !window ? std::min(film.width, film.height) : film.height;
        const double span = window ? std::fabs(static_cast<double>(cam.screen[3]) -
                                               static_cast<double>(cam.screen[2])) *
                                         unit
                                   : 2.0 * unit;
        const double pixel = span / static_cast<double>(across);
        if (pixel < kFinestPixelAngle)
            log_.warn(
                "the camera's pixels are {:.2g} radians apart ({}{:.3g} degrees over {} "
                "pixels), finer than 32-bit ray directions resolve ({:.0g}): neighbouring "
                "pixels see the same rays, in streaks and blocks; widen the view and move the "
                "camera closer",
                pixel, window ? "a screen window in an fov of " : "fov ", cam.fov_deg, across,
                kFinestPixelAngle);
    }
    render_image(render_scene(), options_, cam, film, steps, result_);
    rep.ran = true;
    rep.seconds = result_.stats.seconds;
    return rep;
}

bool Session::film(Film& out) const {
    const ecs::Registry* live = live_.get();
    if (!live || live->count<Camera>() == 0 || live->count<Film>() == 0) return false;
    out = live->find_pool<Film>()->columns().get(0);
    apply_overrides(out);
    return true;
}

void Session::apply_overrides(Film& f) const {
    if (options_.width_override) f.width = options_.width_override;
    if (options_.height_override) f.height = options_.height_override;
    if (options_.spp_override) f.spp = options_.spp_override;
}

}  // namespace spangle
