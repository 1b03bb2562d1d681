#include "session.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include "core/error.h"
#include "core/files.h"
#include "scene/scene_loader.h"
#include "shading/plugin_loader.h"

namespace spangle::python {

namespace fs = std::filesystem;

void set_module_location(const std::string& package_dir) {
    // An installed package carries its plugins, OCIO config and OpenImageIO module beside
    // itself; a module in the build tree finds them in the build directory it was built in.
    if (fs::is_directory(fs::path(package_dir) / "plugins")) {
        set_executable_dir(package_dir);
        return;
    }
#ifdef SPANGLE_BUILD_DIR
    set_executable_dir(SPANGLE_BUILD_DIR);
#endif
}

PySession::PySession(std::vector<std::string> plugin_path, const std::string& ocio, int threads,
                     bool verbose) {
    // As the command line's --threads (TBB crashed on 70000; a negative count was taken).
    if (threads < 0 || threads > 1024)
        throw SpangleError(fmt::format("threads {} must be 0 (every core) to 1024", threads));
    log_.threshold = verbose ? LogLevel::Info : LogLevel::Warning;
    RenderOptions options;
    options.threads = threads;
    options.progressive = false;
    session_ = std::make_unique<Session>(std::move(plugin_path), ocio, options, log_);
}

void PySession::check_size(const std::pair<uint32_t, uint32_t>& size) {
    if (size.first < 1 || size.second < 1 || size.first > 16384 || size.second > 16384)
        throw SpangleError(
            fmt::format("size ({}, {}) must be 1 to 16384 pixels a side", size.first, size.second));
}

std::unique_lock<std::mutex> PySession::edit_lock() {
    // A render refuses the edit; another thread's edit or load is waited for (each was refused
    // as "rendering": 345 of 400 edits from two threads). Polled, not blocked on, so that a
    // render that takes the lock meanwhile still refuses it rather than making it wait.
    for (;;) {
        if (busy_.load())
            throw SpangleError(
                "this session is rendering: load or edit it after render() returns (stop() ends "
                "a render early)");
        std::unique_lock<std::mutex> lock(rendering_, std::try_to_lock);
        if (lock.owns_lock()) return lock;
        std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
}

void PySession::load(const std::string& path, double time,
                     const std::optional<std::pair<uint32_t, uint32_t>>& size) {
    const auto lock = edit_lock();
    if (path.empty()) throw SpangleError("load(): the scene's path is empty");
    if (size) check_size(*size);
    // By its absolute path: edits reload it, and the process may change folder in between (every
    // edit after os.chdir failed to find the scene's meshes).
    SceneDescription d =
        read_scene(std::filesystem::absolute(path).lexically_normal().string(), SceneReadOptions{});
    if (size) {
        d.render.width = size->first;
        d.render.height = size->second;
    }
    session_->load(d, time);
    const std::lock_guard<std::mutex> l(desc_mutex_);
    base_size_ = {d.render.width, d.render.height};
    desc_ = std::move(d);
    time_ = time;
    loaded_ = true;
}

SceneDescription PySession::description() const {
    if (!loaded_) throw SpangleError("no scene is loaded: call load(path) first");
    // A copy, under the lock an edit swaps the description under: a reader on another thread
    // (s.materials while s.set_camera runs) read it as it was freed and crashed.
    const std::lock_guard<std::mutex> l(desc_mutex_);
    return desc_;
}

void PySession::apply_locked(SceneDescription edited) {
    session_->load(edited, time_);
    const std::lock_guard<std::mutex> l(desc_mutex_);
    desc_ = std::move(edited);
}

std::vector<std::string> PySession::materials() const {
    std::vector<std::string> out;
    for (const MaterialDesc& m : description().materials) out.push_back(m.name);
    return out;
}

namespace {

/** Where an edit from Python is blamed in messages. */
FileLoc python_loc(const std::string& what) {
    return FileLoc{"python: " + what, 0, 0};
}

}  // namespace

void PySession::set_material(const std::string& name,
                             const std::vector<std::pair<std::string, ParamValue>>& params) {
    // The edit lock from the read to the reload: two threads' edits each made on its own copy
    // of the description, and the later reload dropped the other's edit.
    const auto lock = edit_lock();
    SceneDescription d = description();
    MaterialDesc* m = nullptr;
    for (MaterialDesc& x : d.materials)
        if (x.name == name) m = &x;
    if (!m) {
        std::string names;
        for (const MaterialDesc& x : d.materials) names += (names.empty() ? "" : ", ") + x.name;
        throw SpangleError(
            python_loc(fmt::format("set_material('{}')", name)),
            fmt::format("no material '{}' (materials: {})", name, names.empty() ? "none" : names));
    }
    for (const auto& [key, value] : params) {
        // The host's cut-out keys, beside the plugin's parameters: a number in [0, 1] each.
        if (key == "alpha" || key == "alpha_cutoff") {
            const FileLoc at = python_loc(fmt::format("set_material('{}', {}=...)", name, key));
            const double* x = std::get_if<double>(&value);
            const long long* i = std::get_if<long long>(&value);
            const double v = x ? *x : i ? static_cast<double>(*i) : -1.0;
            if (!(v >= 0.0 && v <= 1.0))
                throw SpangleError(
                    at, fmt::format("material '{}': '{}' must be a number in [0, 1]", name, key));
            if (key == "alpha_cutoff") {
                m->alpha_cutoff = v;
                m->alpha_cutoff_loc = at;
                continue;
            }
            ParamDesc a;
            a.name = "alpha";
            a.kind = ParamDesc::Kind::Number;
            a.number = v;
            a.loc = a.key_loc = at;
            m->alpha = a;
            continue;
        }
        ParamDesc* p = nullptr;
        for (ParamDesc& x : m->params)
            if (x.name == key) p = &x;
        if (!p) {
            m->params.emplace_back();
            p = &m->params.back();
            p->name = key;
        }
        p->loc = p->key_loc = python_loc(fmt::format("set_material('{}', {}=...)", name, key));
        p->is_integer = false;
        if (const bool* b = std::get_if<bool>(&value)) {
            p->kind = ParamDesc::Kind::Bool;
            p->number = *b ? 1.0 : 0.0;
        } else if (const long long* i = std::get_if<long long>(&value)) {
            p->kind = ParamDesc::Kind::Number;
            p->number = static_cast<double>(*i);
            p->is_integer = true;
        } else if (const double* x = std::get_if<double>(&value)) {
            if (!std::isfinite(*x))
                throw SpangleError(python_loc(fmt::format("set_material('{}', {}=...)", name, key)),
                                   fmt::format("material '{}': '{}' must be finite", name, key));
            p->kind = ParamDesc::Kind::Number;
            p->number = *x;
        } else if (const std::string* s = std::get_if<std::string>(&value)) {
            p->kind = ParamDesc::Kind::String;
            p->text = *s;
        } else {
            const auto& c = std::get<std::array<double, 3>>(value);
            for (double v : c)
                if (!std::isfinite(v))
                    throw SpangleError(
                        python_loc(fmt::format("set_material('{}', {}=...)", name, key)),
                        fmt::format("material '{}': the colour '{}' must be finite", name, key));
            p->kind = ParamDesc::Kind::Color;
            p->color = ColorDesc{};
            p->color.rgb =
                Vec3(static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]));
            p->color.loc = p->color.space_loc = p->loc;
        }
    }
    if (m->alpha_cutoff && !m->alpha)
        throw SpangleError(
            m->alpha_cutoff_loc,
            fmt::format("material '{}': alpha_cutoff needs an alpha to cut by", name));
    apply_locked(std::move(d));
}

std::vector<std::string> PySession::objects() const {
    std::vector<std::string> out;
    const SceneDescription& d = description();
    for (std::size_t i = 0; i < d.objects.size(); ++i)
        out.push_back(!d.objects[i].name.empty() ? d.objects[i].name
                                                 : fmt::format("[[object]] #{}", i + 1));
    return out;
}

namespace {

/** The checks the TOML reader makes on the same keys, for the edits (they were taken as given: a
 *  negative radius lit the scene 860 times, a NaN fov rendered black). */
void check_vec(const std::string& call, const char* key, const std::optional<Vec3>& v) {
    if (v && !(std::isfinite(v->x) && std::isfinite(v->y) && std::isfinite(v->z) &&
               std::fabs(v->x) <= 1e30f && std::fabs(v->y) <= 1e30f && std::fabs(v->z) <= 1e30f))
        throw SpangleError(python_loc(call),
                           fmt::format("'{}' must be finite and at most 1e30 in size, got ({}, "
                                       "{}, {})",
                                       key, v->x, v->y, v->z));
}

void check_number(const std::string& call, const char* key, const std::optional<double>& v,
                  double lo, double hi, bool lo_open) {
    if (v && !((lo_open ? *v > lo : *v >= lo) && *v <= hi))
        throw SpangleError(python_loc(call), fmt::format("'{}' must be in {}{}, {}], got {}", key,
                                                         lo_open ? "(" : "[", lo, hi, *v));
}

}  // namespace

ObjectDesc& PySession::object_named(SceneDescription& d, const std::string& name) const {
    const std::vector<std::string> names = objects();
    for (std::size_t i = 0; i < names.size(); ++i)
        if (names[i] == name) return d.objects[i];
    std::string all;
    for (const std::string& n : names) all += (all.empty() ? "" : ", ") + n;
    throw SpangleError(
        python_loc(fmt::format("set_transform('{}')", name)),
        fmt::format("no object '{}' (objects: {})", name, all.empty() ? "none" : all));
}

void PySession::set_transform(const std::string& name, const std::optional<Vec3>& translate,
                              const std::optional<Vec3>& rotate, const std::optional<Vec3>& scale,
                              const std::optional<Affine>& matrix) {
    // The edit lock from the read to the reload: two threads' edits each made on its own copy
    // of the description, and the later reload dropped the other's edit.
    const auto lock = edit_lock();
    SceneDescription d = description();
    ObjectDesc& o = object_named(d, name);
    const std::string call = fmt::format("set_transform('{}')", name);
    const FileLoc edit = python_loc(call);
    check_vec(call, "translate", translate);
    check_vec(call, "rotate", rotate);
    check_vec(call, "scale", scale);
    // The scene file's range (1e-8 to 1e8 in size on every axis): a scale of 1e-20 was taken
    // and the render aborted in Embree.
    if (scale)
        for (const float v : {scale->x, scale->y, scale->z})
            if (!(std::fabs(v) >= 1e-8f && std::fabs(v) <= 1e8f))
                throw SpangleError(
                    edit, fmt::format("'scale' must be between 1e-8 and 1e8 in size on every "
                                      "axis, got ({}, {}, {})",
                                      scale->x, scale->y, scale->z));
    if (matrix) {
        bool finite =
            std::isfinite(matrix->t.x) && std::isfinite(matrix->t.y) && std::isfinite(matrix->t.z);
        for (const auto& row : matrix->m)
            for (const float x : row) finite = finite && std::isfinite(x);
        const float det = matrix->determinant();
        if (!finite || !(std::fabs(det) > 1e-24f && std::isfinite(det)))
            throw SpangleError(edit, "the matrix must be finite and invertible");
    }
    if (matrix && (translate || rotate || scale))
        throw SpangleError(edit, fmt::format("object '{}': give either matrix or "
                                             "translate/rotate/scale, not both",
                                             name));
    // What the object's keys set, they decide at every time: an edit of it would be reported by
    // transform() and ignored by the render (it was, silently), as for a keyframed camera.
    const auto keyed = [&](auto part) {
        return std::any_of(o.keys.keys.begin(), o.keys.keys.end(),
                           [&](const ObjectKey& k) { return (k.*part).has_value(); });
    };
    std::string decided;
    if (!o.matrix_keys.keys.empty() && (matrix || translate || rotate || scale))
        decided = "its placement (keyed as whole matrices)";
    else if (matrix && !o.keys.keys.empty())
        decided = "its placement";
    else if (translate && keyed(&ObjectKey::translate))
        decided = "translate";
    else if (rotate && keyed(&ObjectKey::rotate))
        decided = "rotate";
    else if (scale && keyed(&ObjectKey::scale))
        decided = "scale";
    if (!decided.empty())
        throw SpangleError(edit, fmt::format("the object is keyframed ([[object.keys]]): its "
                                             "keys decide {}; edit them in the scene file",
                                             decided));
    if (matrix) {
        o.placement.matrix = *matrix;
    } else {
        // Parts replace a matrix (the object's keys, if any, move the parts).
        if (o.placement.matrix && !(translate && rotate && scale))
            throw SpangleError(edit, fmt::format("object '{}' is placed by a matrix: give "
                                                 "translate, rotate and scale together, or a "
                                                 "matrix",
                                                 name));
        o.placement.matrix.reset();
        if (translate) o.placement.parts.translate = *translate;
        if (rotate) o.placement.parts.rotate = *rotate;
        if (scale) o.placement.parts.scale = *scale;
    }
    o.loc = edit;
    apply_locked(std::move(d));
}

void PySession::set_camera(const std::optional<Vec3>& position, const std::optional<Vec3>& look_at,
                           const std::optional<Vec3>& up, const std::optional<double>& fov,
                           const std::optional<double>& aperture,
                           const std::optional<double>& focus_distance,
                           const std::optional<double>& ortho_height,
                           const std::optional<std::string>& projection) {
    // The edit lock from the read to the reload: two threads' edits each made on its own copy
    // of the description, and the later reload dropped the other's edit.
    const auto lock = edit_lock();
    SceneDescription d = description();
    CameraDesc& c = d.camera;
    check_vec("set_camera()", "position", position);
    check_vec("set_camera()", "look_at", look_at);
    check_vec("set_camera()", "up", up);
    check_number("set_camera()", "fov", fov, 0.0, 179.999, true);
    check_number("set_camera()", "aperture", aperture, 0.0, 1e3, false);
    check_number("set_camera()", "focus_distance", focus_distance, 0.0, 1e30, true);
    check_number("set_camera()", "ortho_height", ortho_height, 0.0, 1e30, false);
    // A keyframed camera goes where its keys say: an edit of its placement or lens would be
    // reported by `camera` and ignored by the render (it was, silently).
    if (!c.keys.keys.empty() && (position || look_at || up || fov || aperture || focus_distance))
        throw SpangleError(python_loc("set_camera()"),
                           "the camera is keyframed ([[camera.keys]]): its keys decide "
                           "where it stands and its lens; edit them in the scene file");
    // A projection switches the camera as [camera] projection does: perspective (with its fov),
    // orthographic (with a view height) or equirectangular (no fov, view height or lens).
    if (projection) {
        if (*projection == "perspective") {
            if (ortho_height.value_or(0.0) > 0.0)
                throw SpangleError(python_loc("set_camera()"),
                                   "projection \"perspective\" takes no ortho_height (it "
                                   "makes the camera orthographic)");
            c.equirect = false;
            c.ortho_height = 0.0;
        } else if (*projection == "orthographic") {
            c.equirect = false;
            if (!(ortho_height.value_or(c.ortho_height) > 0.0))
                throw SpangleError(python_loc("set_camera()"),
                                   "projection \"orthographic\" needs ortho_height > 0 "
                                   "(the view's height in scene units)");
        } else if (*projection == "equirectangular") {
            if (ortho_height || fov || focus_distance)
                throw SpangleError(python_loc("set_camera()"),
                                   "an equirectangular camera has no fov, view height or "
                                   "focus distance");
            // Its lens goes with the switch: aperture=0 or none is accepted, a lens is not.
            if (aperture.value_or(0.0) > 0.0 || (!aperture && c.aperture > 0.0))
                throw SpangleError(python_loc("set_camera()"),
                                   "an equirectangular camera is a pinhole: give "
                                   "aperture=0 with it (the camera's aperture is " +
                                       fmt::format("{}", aperture.value_or(c.aperture)) + ")");
            c.equirect = true;
            c.ortho_height = 0.0;
        } else {
            throw SpangleError(python_loc("set_camera()"),
                               "projection must be \"perspective\", \"orthographic\" or "
                               "\"equirectangular\", got \"" +
                                   *projection + "\"");
        }
    } else if ((fov || ortho_height || aperture || focus_distance) && c.equirect) {
        throw SpangleError(python_loc("set_camera()"),
                           "an equirectangular camera has no fov, view height or lens "
                           "(projection=\"perspective\" or \"orthographic\" switches it back)");
    }
    // ortho_height > 0 makes the camera orthographic, 0 perspective again (with its fov).
    if (ortho_height) c.ortho_height = *ortho_height;
    if (position) c.position = *position;
    if (look_at) c.look_at = *look_at;
    if (up) c.up = *up;
    if (fov && c.ortho_height > 0.0)
        throw SpangleError(python_loc("set_camera()"),
                           "'fov': the camera is orthographic (ortho_height), it has no "
                           "field of view (ortho_height=0 makes it perspective)");
    if (fov) c.fov_deg = *fov;
    if (aperture) c.aperture = *aperture;
    if (focus_distance) c.focus_distance = *focus_distance;
    c.loc = c.look_at_loc = c.up_loc = python_loc("set_camera()");
    apply_locked(std::move(d));
}

void PySession::set_light(std::size_t index, const std::optional<double>& intensity,
                          const std::optional<Vec3>& color, const std::optional<Vec3>& position,
                          const std::optional<double>& radius) {
    // The edit lock from the read to the reload: two threads' edits each made on its own copy
    // of the description, and the later reload dropped the other's edit.
    const auto lock = edit_lock();
    SceneDescription d = description();
    const std::string call = fmt::format("set_light({})", index);
    const FileLoc loc = python_loc(call);
    if (index >= d.lights.size())
        throw SpangleError(loc, fmt::format("no light {} (the scene has {} light{}, from 0)", index,
                                            d.lights.size(), d.lights.size() == 1 ? "" : "s"));
    LightDesc& l = d.lights[index];
    check_number(call, "intensity", intensity, 0.0, 1e30, false);
    check_number(call, "radius", radius, 0.0, 1e30, true);
    check_vec(call, "position", position);
    check_vec(call, "color", color);
    if (color && (color->x < 0.0f || color->y < 0.0f || color->z < 0.0f))
        throw SpangleError(loc, fmt::format("'color' must not be negative, got ({}, {}, {})",
                                            color->x, color->y, color->z));
    if (intensity) l.intensity = *intensity;
    if (color) {
        ColorDesc c;
        c.rgb = *color;
        c.loc = c.space_loc = loc;
        l.color = c;
    }
    if (position || radius) {
        bool placed = false;
        std::visit(
            [&](auto& s) {
                using S = std::decay_t<decltype(s)>;
                if constexpr (std::is_same_v<S, SphereLightDesc>) {
                    if (position) s.center = *position;
                    if (radius) s.radius = *radius;
                    placed = true;
                } else if constexpr (std::is_same_v<S, PointLightDesc> ||
                                     std::is_same_v<S, SpotLightDesc>) {
                    if (position) s.position = *position;
                    placed = !radius;
                } else if constexpr (std::is_same_v<S, QuadLightDesc>) {
                    if (position) s.corner = *position;
                    placed = !radius;
                }
            },
            l.shape);
        if (!placed)
            throw SpangleError(loc, fmt::format("light {}: its kind has no {}", index,
                                                radius ? "radius" : "position"));
    }
    l.loc = loc;
    apply_locked(std::move(d));
}

std::vector<SpangleParamDesc_v3> PySession::parameters(const std::string& plugin,
                                                       const std::string& model) {
    const std::shared_ptr<LoadedPlugin> p =
        session_->plugins().open(plugin, FileLoc{"python: parameters('" + plugin + "')", 0, 0});
    const std::vector<std::string> names = p->model_names();
    const std::string& want = model.empty() && names.size() == 1 ? names[0] : model;
    const SpangleMaterialModel_v3* m = p->model(want);
    if (!m) {
        std::string all;
        for (const std::string& n : names) all += (all.empty() ? "" : ", ") + n;
        if (want.empty())
            throw SpangleError(
                fmt::format("plugin '{}' has several models: name one ({})", plugin, all));
        throw SpangleError(
            fmt::format("plugin '{}' has no model '{}' (models: {})", plugin, want, all));
    }
    return std::vector<SpangleParamDesc_v3>(m->params, m->params + m->param_count);
}

RenderedImage PySession::render(std::optional<uint32_t> spp,
                                std::optional<std::pair<uint32_t, uint32_t>> size, bool layers,
                                const RenderCallbacks& callbacks, bool background_apart,
                                const AdaptiveArgs& adaptive, const DenoiseArgs& denoise_args) {
    if (!loaded_) throw SpangleError("no scene is loaded: call load(path) first");
    // The denoiser's guides are layers: as `--denoise`, which implies `--layers`.
    std::optional<GlintDenoise> denoise_glints;
    if (const auto& g = denoise_args.glints) {
        denoise_glints = glint_denoise_named(*g);
        if (!denoise_glints)
            throw SpangleError(fmt::format(
                "render(): denoise_glints must be \"keep\", \"apart\" or \"filter\", got \"{}\"",
                *g));
        if (!layers)
            throw SpangleError(
                "render(): denoise needs the layers (its albedo and normal guides and the glints): "
                "leave layers=True");
        std::string why;
        if (!denoiser_available(&why)) throw SpangleError("render(): cannot denoise: " + why);
    }
    if (busy_.load()) throw SpangleError("this session is already rendering");
    std::unique_lock<std::mutex> lock(rendering_, std::try_to_lock);
    if (!lock.owns_lock()) throw SpangleError("this session is already rendering");
    busy_.store(true);
    // A stop() is cleared when the render ends, not when it starts: one that came before
    // (from a thread that started this render and stopped it at once) is not lost.
    struct Idle {
        std::atomic<bool>& busy;
        std::atomic<bool>& stop;
        ~Idle() {
            stop.store(false);
            busy.store(false);
        }
    } idle{busy_, stop_};
    // A stop that came before the render: its first pass (one sample) only, reported stopped.
    const bool stop_pending = stop_.exchange(false);
    // (spp, min_spp and max_spp come checked from the binding, which takes Python ints.)
    if (const auto& t = adaptive.noise_threshold)
        if (const std::string why = noise_threshold_problem(*t); !why.empty())
            throw SpangleError("render(): noise_threshold " + why);
    // A size is the scene's film size: set in the description and reloaded (only what reads
    // the film is rebuilt, e.g. subdivision levels chosen from the camera's pixels), so that the
    // scene is built as `spangle render --size` builds it. A size that fails (a film beyond
    // memory) leaves the session at the size it had.
    // Without a size, the size the scene was loaded at (an earlier render's size stuck to every
    // render after it).
    std::optional<SceneDescription> before;
    const std::pair<uint32_t, uint32_t> want = size.value_or(base_size_);
    if (want.first != desc_.render.width || want.second != desc_.render.height) {
        check_size(want);
        SceneDescription d = desc_;
        d.render.width = want.first;
        d.render.height = want.second;
        before = desc_;
        apply_locked(std::move(d));
    }
    RenderOptions& o = session_->options();
    o.spp_override = stop_pending ? 1u : spp.value_or(0);
    o.layers = layers;
    // As `spangle render --layers`: the environment seen directly goes to its own layer and the
    // beauty is premultiplied (without it the layers did not match the command line's).
    o.background_apart = layers && background_apart;
    o.progressive = true;  // passes of 1, 1, 2, 4, ... samples: a stop keeps those completed
    o.noise_threshold_override =
        adaptive.noise_threshold ? static_cast<float>(*adaptive.noise_threshold) : -1.0f;
    o.min_spp_override = adaptive.min_spp.value_or(0);
    o.max_spp_override = adaptive.max_spp.value_or(0);
    o.progress = callbacks.progress;
    o.on_pass = callbacks.on_pass;
    o.stop = [this] { return stop_.load(); };
    ecs::SystemReport report;
    try {
        // The callbacks are this call's: gone when it ends, however it ends (before a failed
        // render's size is restored below).
        const struct Detach {
            RenderOptions& o;
            ~Detach() {
                o.progress = nullptr;
                o.on_pass = nullptr;
                o.stop = nullptr;
                o.noise_threshold_override = -1.0f;
                o.min_spp_override = o.max_spp_override = 0;
            }
        } detach{o};
        report = session_->render();
    } catch (...) {
        if (before) {
            try {
                apply_locked(std::move(*before));
            } catch (...) {
            }
        }
        throw;
    }
    RenderedImage out;
    out.result = session_->take_result();
    if (stop_pending)
        out.result.stats.spp_target =
            std::max(out.result.stats.spp_target, spp.value_or(desc_.render.spp));
    if (out.result.image.empty())
        throw SpangleError(fmt::format("nothing was rendered: {}", report.reason));
    if (denoise_glints) {
        RenderResult& r = out.result;
        if (denoise(DenoiseImage{&r.image, &r.layers, &r.layer_names, r.width, r.height},
                    *denoise_glints, o.threads))
            mark_denoised(r.stats, *denoise_glints);
        else
            log_.warn("{}", not_denoised_warning(r.width, r.height));
    }
    out.scene = desc_.path;
    out.inputs = session_->watched_files();
    out.info = std::make_shared<const SceneInfo>(session_->info());
    out.color = std::make_shared<const ColorConfig>(session_->color().clone());
    return out;
}

}  // namespace spangle::python
