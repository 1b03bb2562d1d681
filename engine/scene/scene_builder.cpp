#include "scene/scene_builder.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <unordered_map>
#include <utility>

#include "color/image_io.h"
#include "core/files.h"
#include "core/hash.h"
#include "scene/components.h"
#include "scene/frame_sequence.h"
#include "scene/keyed_motion.h"
#include "scene/object_placement.h"
#include "scene/scene_hash.h"

namespace spangle {

namespace {

/** What building one scene needs besides the element at hand. */
struct BuildContext {
    ColorConfig* color;       ///< for resolving spaces and converting to the working space
    ecs::Registry* registry;  ///< filled
    SceneInfo* info;          ///< filled
    std::string bare_space;   ///< canonical space of bare colours
    Shutter shutter;          ///< the frame's exposure
    /** Content hashes of the inline meshes seen so far (instances share one mesh). */
    std::map<const TriangleMesh*, uint64_t> mesh_hashes;
};

/** Adds `note` to the scene's notes unless it is there already (a colour used twice). */
void note_once(BuildContext& ctx, std::string note) {
    auto& notes = ctx.info->notes;
    if (std::find(notes.begin(), notes.end(), note) == notes.end())
        notes.push_back(std::move(note));
}

/** Resolves a colour space name or throws at `at` listing the known ones; notes a stand-in
 *  (once per place and name). `implicit` words a default the scene did not write. */
std::string resolve_space(BuildContext& ctx, const std::string& name, const FileLoc& at,
                          const char* implicit = nullptr) {
    auto resolved = ctx.color->resolve(name);
    if (!resolved && ctx.color->is_named_transform(name))
        throw_error(at,
                    "'{}' is a named transform of the OCIO config, not a colour space (known "
                    "spaces: {})",
                    name, fmt::join(ctx.color->space_names(), ", "));
    if (!resolved)
        throw_error(at, "unknown {}colour space '{}' (known: {}); {}", implicit ? implicit : "",
                    name, fmt::join(ctx.color->space_names(), ", "), ctx.color->how_to_fix());
    if (!resolved->via.empty()) {
        note_once(ctx,
                  fmt::format("{}: {}colour space '{}' is not in the OCIO config '{}'; using {}",
                              at.str(), implicit ? implicit : "", name, ctx.color->path(),
                              resolved->via));
    }
    return resolved->name;
}

/** The canonical space a colour is written in. */
std::string space_of(BuildContext& ctx, const ColorDesc& c) {
    return c.space ? resolve_space(ctx, *c.space, c.space_loc) : ctx.bare_space;
}

/** A colour in the working space (negative channels clamped), or `fallback` (already in the
 *  working space) when none is written. */
Vec3 working_color(BuildContext& ctx, const std::optional<ColorDesc>& c, Vec3 fallback) {
    if (!c) return fallback;
    float rgb[3] = {c->rgb.x, c->rgb.y, c->rgb.z};
    const std::string space = space_of(ctx, *c);
    try {
        ctx.color->to_working(space, rgb, 1);
    } catch (const SpangleError& e) {  // the conversion's own (a LUT file missing): said here
        throw_error(c->space ? c->space_loc : c->loc, "{}", e.what());
    }
    // A colour that is finite as written can overflow in the conversion (an sRGB-encoded 1e20
    // decodes to infinity): the light vanished, or an environment turned the image black.
    if (!std::isfinite(rgb[0]) || !std::isfinite(rgb[1]) || !std::isfinite(rgb[2]))
        throw_error(c->loc,
                    "colour ({}, {}, {}) in '{}' is beyond a float in the working space '{}' "
                    "(components above about 1e15 overflow there): make it smaller, or give a "
                    "linear space",
                    c->rgb.x, c->rgb.y, c->rgb.z, space_of(ctx, *c), ctx.color->working_space());
    // Gamut mapping can push a channel a hair below zero; radiance and albedo cannot be negative.
    // More than a hair is a colour outside the working space's gamut: clipped, and said (ACEScg
    // green in lin_rec709 is (-0.62, 1.14, -0.13): its clipped (0, 1.14, 0) is another colour).
    const float most = std::max({std::fabs(rgb[0]), std::fabs(rgb[1]), std::fabs(rgb[2])});
    if (std::min({rgb[0], rgb[1], rgb[2]}) < -1e-3f * most) {
        note_once(ctx, fmt::format("{}: colour ({}, {}, {}) in '{}' is outside the working space "
                                   "'{}' ({:.4g}, {:.4g}, {:.4g}): its negative parts are clipped "
                                   "to 0 (render in a wider working space, such as ACEScg, to "
                                   "keep it)",
                                   c->loc.str(), c->rgb.x, c->rgb.y, c->rgb.z, space_of(ctx, *c),
                                   ctx.color->working_space(), rgb[0], rgb[1], rgb[2]));
    }
    return {std::max(rgb[0], 0.0f), std::max(rgb[1], 0.0f), std::max(rgb[2], 0.0f)};
}

/** The index of a light group (added on first use), its name checked. */
LightGroup light_group_component(BuildContext& ctx, const LightGroupDesc& g) {
    const std::string& name = g.name;
    if (name.empty() || name.size() > 64 ||
        name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_") !=
            std::string::npos)
        throw_error(g.loc,
                    "'light_group' must be 1 to 64 letters, digits or underscores (it names a "
                    "layer of the EXR), got \"{}\"",
                    name);
    std::vector<std::string>& groups = ctx.info->light_groups;
    auto it = std::find(groups.begin(), groups.end(), name);
    if (it == groups.end()) it = groups.insert(groups.end(), name);
    return LightGroup{static_cast<uint32_t>(it - groups.begin())};
}

/** The working space, the bare colours' space, the Film, the frame range and the shutter. */
void build_render(BuildContext& ctx, const RenderDesc& d, ecs::Entity settings) {
    ColorConfig& color = *ctx.color;
    // Every build sets it: a reload that drops `working_space` goes back to the default, the
    // config's scene_linear, else ACEScg (it kept the space of the scene loaded before, which
    // the live config still held).
    // Light is added and multiplied in the working space: an encoded (sRGB), display or data
    // space rendered with no word, its header naming it (a furnace's 0.5 showed as 0.21). Why
    // `space` is not scene-linear, if it is not; a transform that cannot be made is an error at
    // `loc`.
    const auto not_linear = [&](const std::string& space, const FileLoc& loc) {
        try {
            return color.not_scene_linear(space);
        } catch (const SpangleError& e) {
            throw_error(loc, "{}", e.what());
        }
    };
    if (d.working_space) {
        const std::string space = resolve_space(ctx, *d.working_space, d.working_space_loc);
        if (const std::optional<std::string> why = not_linear(space, d.working_space_loc))
            throw_error(d.working_space_loc,
                        "working_space '{}' is not scene-linear ({}): light adds up only in a "
                        "linear space; use a scene-linear one such as ACEScg or lin_rec709 (the "
                        "encoding belongs to textures' 'space' and to the display view)",
                        *d.working_space, *why);
        color.set_working_space(space);
    } else if (!color.default_working_space().empty()) {
        // The config's scene_linear role, checked as a written space is (a role naming a log or
        // sRGB space rendered without a word, the header naming it over linear values).
        const std::string space = color.default_working_space();
        if (const std::optional<std::string> why = not_linear(space, d.loc))
            throw_error(d.loc,
                        "the OCIO config's scene_linear role names '{}', the working space when "
                        "[render] names none, and it is not scene-linear ({}): light adds up "
                        "only in a linear space; write working_space = \"ACEScg\" (or another "
                        "linear space of the config) in [render], or point the role at a "
                        "linear space",
                        space, *why);
        color.set_working_space(space);
    } else
        color.set_working_space(
            resolve_space(ctx, "ACEScg", d.loc, "default (no key written) working "));
    ctx.bare_space = d.color_space
                         ? resolve_space(ctx, *d.color_space, d.color_space_loc)
                         : resolve_space(ctx, "lin_rec709", d.loc, "default (no key written) ");
    Film f;
    f.width = d.width;
    f.height = d.height;
    f.spp = d.spp;
    f.max_depth = d.max_depth;
    f.rr_depth = d.rr_depth;
    f.seed = d.seed;
    f.filter = d.filter;
    f.filter_radius = d.filter_radius;
    f.filter_shared = d.filter_shared ? 1 : 0;
    f.clamp_indirect = d.clamp_indirect;
    f.filter_glossy = d.filter_glossy;
    f.noise_threshold = d.noise_threshold;
    f.min_spp = d.min_spp;
    f.max_spp = d.max_spp;
    f.transparent_background = d.transparent_background ? 1 : 0;
    ctx.registry->put(settings, f);
    SceneInfo& info = *ctx.info;
    info.frame_start = d.frame_start;
    info.frame_end = d.frame_end;
    info.fps = d.fps;
    info.shutter_open = d.shutter_open;
    info.shutter_close = d.shutter_close;
    info.working_space = color.working_space();
    info.color_space = ctx.bare_space;
    info.size_loc = d.size_loc;
    info.spp_loc = d.spp_loc;
    info.noise_threshold_loc = d.noise_threshold_loc;
    if (d.crop) {
        const std::array<double, 4>& c = *d.crop;
        if (!(c[0] >= 0.0 && c[0] < c[1] && c[1] <= 1.0 && c[2] >= 0.0 && c[2] < c[3] &&
              c[3] <= 1.0))
            throw_error(d.crop_loc,
                        "the crop window [{}] must be x0 < x1 and y0 < y1, each within [0, 1]",
                        fmt::join(c, ", "));
        info.crop = c;
        info.crop_loc = d.crop_loc;
    }
    ctx.shutter = frame_shutter(info.time, info.fps, info.shutter_open, info.shutter_close);
}

/** The camera as written, checked: it must look somewhere. */
Camera still_camera(const CameraDesc& d) {
    Camera c;
    c.position = d.position;
    c.look_at = d.look_at;
    c.up = d.up;
    c.fov_deg = static_cast<float>(d.fov_deg);
    const Vec3 dir = c.look_at - c.position;
    // In double: a camera 1e20 away overflowed the float length and was "parallel to 'up'".
    const double dx = static_cast<double>(dir.x), dy = static_cast<double>(dir.y),
                 dz = static_cast<double>(dir.z);
    const double distance = std::sqrt(dx * dx + dy * dy + dz * dz);
    if (!(distance <= 1e15))
        throw_error(d.look_at_loc,
                    "the camera is {:.3g} units from its 'look_at': rays are traced in 32-bit "
                    "floats, keep the camera within 1e15 of what it looks at",
                    distance);
    if (!(length(dir) > 0.0f)) throw_error(d.look_at_loc, "'look_at' must differ from 'position'");
    if (!(length(c.up) > 0.0f)) throw_error(d.up_loc, "'up' must not be zero");
    if (!(length(cross(dir, c.up)) > 1e-6f * length(dir) * length(c.up)))
        throw_error(d.up_loc, "'up' must not be parallel to the viewing direction");
    c.aperture = static_cast<float>(d.aperture);
    c.focus_distance = d.focus_distance ? static_cast<float>(*d.focus_distance) : length(dir);
    c.mirror = d.mirror;
    c.fov_shorter = d.fov_shorter && !d.screen;
    c.ortho_height = static_cast<float>(d.ortho_height);
    c.equirect = d.equirect;
    // Rays leave the lens, or an orthographic camera's film plane, up to this far from the
    // position: beyond it 32-bit rays stop working (Embree refused rays from 3e18 away, and the
    // render aborted). Each value had its own range; their product had none.
    constexpr double kMaxSpread = 1e13;
    if (!(d.aperture <= kMaxSpread))
        throw_error(d.loc,
                    "the camera's lens radius {:.3g} is beyond {:.0g} units: rays are traced in "
                    "32-bit floats",
                    d.aperture, kMaxSpread);
    if (d.ortho_height > 0.0 && !d.equirect) {
        double window = 1.0;
        if (d.screen)
            for (double v : *d.screen) window = std::max(window, std::fabs(v));
        const double half = 0.5 * d.ortho_height * window;
        if (!(half <= kMaxSpread))
            throw_error(d.screen ? d.screen_loc : d.loc,
                        "the orthographic camera's view reaches {:.3g} units from its position "
                        "(ortho_height {:.3g}{}): rays are traced in 32-bit floats, keep it "
                        "within {:.0g}",
                        half, d.ortho_height,
                        d.screen ? fmt::format(", screen window up to {:.3g}", window) : "",
                        kMaxSpread);
    }
    if (d.screen) {
        const std::array<double, 4>& w = *d.screen;
        for (double v : w)
            if (!(std::fabs(v) <= 1e6))
                throw_error(d.screen_loc,
                            "the screen window's bounds must lie within [-1e6, 1e6], got [{}]",
                            fmt::join(w, ", "));
        if (!(w[0] < w[1]) || !(w[2] < w[3]))
            throw_error(d.screen_loc,
                        "the screen window [{}] must have x0 < x1 and y0 < y1 (it spans no area)",
                        fmt::join(w, ", "));
        for (std::size_t i = 0; i < 4; ++i) c.screen[i] = static_cast<float>(w[i]);
    }
    return c;
}

/** The keyframed camera through the shutter; each key's fields default to `base`'s. */
KeyedMotion<Camera> camera_motion(const BuildContext& ctx, const CameraDesc& d,
                                  const Camera& base) {
    const Track track =
        key_track(d.keys, ctx.info->frame_start, ctx.info->fps, [&](const CameraKey& k) {
            const Vec3 p = k.position.value_or(base.position);
            const Vec3 l = k.look_at.value_or(base.look_at);
            const Vec3 u = k.up.value_or(base.up);
            const double fov = k.fov_deg ? *k.fov_deg : static_cast<double>(base.fov_deg);
            return std::vector<double>{p.x, p.y, p.z, l.x, l.y, l.z, u.x, u.y, u.z, fov};
        });
    const auto make = [&](const std::vector<double>& v, double when) {
        const auto f = [&](std::size_t i) { return static_cast<float>(v[i]); };
        Camera c = base;
        c.position = {f(0), f(1), f(2)};
        c.look_at = {f(3), f(4), f(5)};
        c.up = {f(6), f(7), f(8)};
        c.fov_deg = f(9);
        const Vec3 dir = c.look_at - c.position;
        if (!(length(dir) > 0.0f) ||
            !(length(cross(dir, c.up)) > 1e-6f * length(dir) * length(c.up)) ||
            !(c.fov_deg > 0.0f && c.fov_deg < 180.0f))
            throw_error(d.keys.loc,
                        "the keyframed camera at {} s looks nowhere: its look_at meets its "
                        "position, its up is parallel to the view, or its fov leaves (0, 180)",
                        when);
        if (!d.focus_distance) c.focus_distance = length(dir);
        return c;
    };
    return keyed_motion<Camera>(track, ctx.shutter, make);
}

/** Widens the scene's span of keys (SceneInfo::keys_from, keys_to) by `keys`. */
template <class Key>
void note_key_times(SceneInfo& info, const Keys<Key>& keys) {
    for (const Key& k : keys.keys) {
        const double t = key_seconds(k.time, info.frame_start, info.fps);
        info.keys_from = std::min(info.keys_from, t);
        info.keys_to = std::max(info.keys_to, t);
    }
}

/** The Camera (at the shutter's middle) and, when it blurs, its CameraMotion. */
void build_camera(BuildContext& ctx, const CameraDesc& d, ecs::Entity settings) {
    SceneInfo& info = *ctx.info;
    info.camera = still_camera(d);
    if (!d.keys.keys.empty()) {
        const Camera base = info.camera;
        KeyedMotion<Camera> motion = camera_motion(ctx, d, base);
        info.camera = motion.middle;
        if (!motion.steps.empty()) {
            ctx.registry->put(settings, CameraMotion{std::move(motion.steps)});
            info.motion_blur = true;
        }
        info.animated = true;
        note_key_times(info, d.keys);
    }
    ctx.registry->put(settings, info.camera);
}

/** colour x intensity, an emitter's radiance or intensity (working space). Refused beyond
 *  1e18: the film clips a sample at 2^60 (1.15e18) and past a float's range the light went
 *  black, counted only among non-finite samples, though each number passed its own range. */
Vec3 emitted(Vec3 color, double intensity, const FileLoc& at, const char* what) {
    const double most = static_cast<double>(max_component(color)) * intensity;
    if (!(most <= 1e18))
        throw_error(at,
                    "{}: colour x intensity is {:.4g}, beyond 1e18, the most a sample can carry "
                    "(brighter ones are clipped, and past a float's range lost): lower its "
                    "'intensity' (or the scene's units)",
                    what, most);
    return color * static_cast<float>(intensity);
}

/** The environment's entity: its light group and its colour or map. */
void build_environment(BuildContext& ctx, const EnvironmentDesc& d) {
    const auto k = static_cast<float>(d.intensity);
    ecs::Registry& registry = *ctx.registry;
    const ecs::Entity env = registry.create();
    registry.put(env, light_group_component(ctx, d.group));
    if (d.map) {
        EnvironmentMapFile m;
        m.path = d.map->path;
        m.loc = d.map->loc;
        // Without a colour space, the file type's usual one, as for textures: an 8-bit PNG or
        // JPEG is sRGB-encoded (read as linear, 128 became 0.50 instead of 0.22).
        if (d.map->color_space) {
            m.color_space = resolve_space(ctx, *d.map->color_space, d.map->color_space_loc);
        } else {
            // An EXR whose header names a space the config has is read in it (a render of
            // Spangle's in ACEScg was read as lin_rec709).
            std::string unknown;
            const std::string usual = default_image_space(
                d.map->path,
                [&](const std::string& s) { return ctx.color->canonical_name(s).has_value(); },
                unknown);
            // Said at the map's key (was the [environment] line); --env has no colour space
            // of its own to give.
            const bool from_cli = d.map->loc.file == "--env";
            if (!unknown.empty())
                ctx.info->notes.push_back(fmt::format(
                    "{}: environment map '{}' names colour space '{}' in its header, which the "
                    "OCIO config does not have: read as {} ({})",
                    d.map->loc.str(), d.map->path, unknown, usual,
                    from_cli ? "name the map in a scene's [environment] with 'color_space' to "
                               "say otherwise"
                             : "give 'color_space' to say otherwise"));
            m.color_space = resolve_space(ctx, usual, d.map->loc, "default (no key written) ");
        }
        m.rotation_deg = static_cast<float>(d.map->rotation_deg);
        m.intensity = k;
        m.projection = d.map->projection;
        if (m.projection != MapProjection::LatLongYUp) {
            // Only the frame's rotation: a scale or shear in pbrt's light transform does not
            // change where directions point once normalised; its inverse transpose would.
            const Affine& f = d.map->to_world;
            if (!(std::fabs(f.determinant()) > 1e-12f))
                throw_error(d.map->loc, "the environment map's transform is singular");
            m.to_map = f.inverse();
        }
        registry.put(env, m);
    } else {
        registry.put(env, Environment{emitted(working_color(ctx, d.color, {0, 0, 0}), d.intensity,
                                              d.loc, "the environment")});
    }
}

/** A texture's lookup, its colour space resolved ("raw" for data, "" for the default). */
TextureRef texture_ref(BuildContext& ctx, const TextureDesc& t) {
    TextureRef ref;
    ref.path = t.path;
    if (t.space) {
        ref.space = *t.space == "raw" || *t.space == "data"
                        ? "raw"
                        : resolve_space(ctx, *t.space, t.space_loc);
        // A data space by another name ("Non-Color", "Utility - Raw"): raw, so that every use
        // of the texture treats its values as numbers (a coloured scale mixed its channels).
        if (ref.space != "raw" && ctx.color->is_data(ref.space)) ref.space = "raw";
    }
    std::copy(std::begin(t.scale), std::end(t.scale), std::begin(ref.scale));
    std::copy(std::begin(t.uv), std::end(t.uv), std::begin(ref.uv));
    ref.wrap = t.wrap;
    ref.wrap_t = t.wrap_t;
    ref.filter = t.filter;
    ref.amount = t.amount;
    ref.blend = t.blend;
    ref.channel = t.channel;
    ref.vertex_color = t.vertex_color;
    return ref;
}

/** A parameter as the materials system takes it: colours stay in the space they are written in
 *  (canonical name in `text`), textures carry their path in `text`. */
ParamEntry param_entry(BuildContext& ctx, const ParamDesc& d) {
    ParamEntry p;
    p.name = d.name;
    p.loc = d.loc;
    p.key_loc = d.key_loc;
    p.number[0] = d.number;
    p.is_integer = d.is_integer;
    p.text = d.text;
    switch (d.kind) {
        case ParamDesc::Kind::Number:
            p.kind = ParamEntry::Kind::Number;
            break;
        case ParamDesc::Kind::Bool:
            p.kind = ParamEntry::Kind::Bool;
            break;
        case ParamDesc::Kind::String:
            p.kind = ParamEntry::Kind::String;
            break;
        case ParamDesc::Kind::Color:
            p.kind = ParamEntry::Kind::Color;
            p.number[0] = d.color.rgb.x;
            p.number[1] = d.color.rgb.y;
            p.number[2] = d.color.rgb.z;
            p.text = space_of(ctx, d.color);
            break;
        case ParamDesc::Kind::Texture:
            p.kind = ParamEntry::Kind::Texture;
            p.texture = texture_ref(ctx, d.texture);
            p.text = p.texture.path;
            break;
    }
    return p;
}

/** One material's entity; its name must be new. */
void build_material(BuildContext& ctx, const MaterialDesc& d) {
    Material m;
    m.loc = d.loc;
    m.name = d.name;
    m.quiet_unused = d.quiet_unused;
    m.plugin = d.plugin;
    m.plugin_loc = d.plugin_loc;
    m.model = d.model;
    m.model_loc = d.model_loc;
    for (const ParamDesc& p : d.params) m.params.push_back(param_entry(ctx, p));
    for (const ParamDesc& p : d.maps) m.maps.push_back(param_entry(ctx, p));
    if (d.alpha) {
        m.maps.push_back(param_entry(ctx, *d.alpha));
        if (d.alpha_cutoff) {
            ParamEntry c;
            c.name = "alpha_cutoff";
            c.number[0] = *d.alpha_cutoff;
            c.loc = c.key_loc = d.alpha_cutoff_loc;
            m.maps.push_back(std::move(c));
        }
    }
    std::vector<std::string>& names = ctx.info->material_names;
    if (std::find(names.begin(), names.end(), m.name) != names.end())
        throw_error(d.name_loc, "material '{}' is defined twice", m.name);
    names.push_back(m.name);
    ctx.info->material_catchers.push_back(d.shadow_catcher ? 1 : 0);
    const ecs::Entity e = ctx.registry->create();
    ctx.registry->put(e, m);
    if (d.alpha) ctx.registry->put(e, AlphaCutOut{static_cast<uint32_t>(names.size() - 1)});
}

/** The file a mesh or cage is read from and its rest pose. */
struct PosedFile {
    std::string path;  ///< the file (a sequence's of the frame)
    std::string rest;  ///< the rest pose's file; empty: none
    FileLoc rest_loc;  ///< where the rest pose is named
};

/** The file of an object's mesh or cage `path` (a pattern when `sequence`, named at `loc`) at
 *  the frame the scene is evaluated at, and its rest pose: `rest` (named at `rest_loc`), or a
 *  sequence's file of frame_start (the same in every process and every split of the work).
 *  `what` words them ("mesh", "cage"). */
PosedFile posed_file(BuildContext& ctx, const std::string& path, bool sequence,
                     const std::string& rest, const FileLoc& loc, const FileLoc& rest_loc,
                     const char* what) {
    PosedFile f{path, rest, rest_loc};
    if (!sequence) return f;
    SceneInfo& info = *ctx.info;
    info.animated = true;
    // A numbered file per frame: every frame has its own shape, past the frame range too (--frames
    // checks their files exist), so no frame "holds the nearest key".
    info.keys_from = -std::numeric_limits<double>::infinity();
    info.keys_to = std::numeric_limits<double>::infinity();
    f.path = sequence_file(path, frame_at(info.frame_start, info.fps, info.time), loc, what);
    if (f.rest.empty()) {
        f.rest = expand_frame_pattern(path, info.frame_start);
        f.rest_loc = loc;
        std::error_code ec;
        if (!std::filesystem::is_regular_file(f.rest, ec))
            throw_error(loc,
                        "{} file of frame_start {} not found (looked for {}): without "
                        "'rest_mesh' it is the sequence's rest pose; give 'rest_mesh' or that file",
                        what, info.frame_start, absolute_path(f.rest));
    }
    return f;
}

/** An object's shape as the geometry systems take it. */
void put_shape(BuildContext& ctx, ecs::Entity e, const ObjectDesc& d) {
    if (const auto* m = std::get_if<MeshFileShape>(&d.shape)) {
        PosedFile f =
            posed_file(ctx, m->path, m->sequence, m->rest_path, m->loc, m->rest_loc, "mesh");
        ctx.registry->put(e, MeshFile{std::move(f.path), m->loc, std::move(f.rest), f.rest_loc});
    } else if (const auto* sub = std::get_if<SubdivShape>(&d.shape)) {
        const uint64_t content = sub->cage ? cage_content_hash(*sub->cage) : 0;
        PosedFile f = posed_file(ctx, sub->path, sub->sequence, sub->rest_path, sub->loc,
                                 sub->rest_loc, "cage");
        ctx.registry->put(
            e, SubdivSurface{std::move(f.path), sub->loc, sub->options, sub->max_level,
                             sub->pixel_budget, sub->cage, content, std::move(f.rest), f.rest_loc});
    } else {
        const auto& in = std::get<InlineMeshShape>(d.shape);
        std::shared_ptr<const TriangleMesh> mesh = in.mesh;
        if (in.deformation && in.deformation->animated()) {
            // Its shape at the shutter's middle, where its placement is (a deformation is not
            // blurred within the shutter, as a mesh sequence's is not).
            mesh = in.deformation->at(ctx.shutter.middle);
            SceneInfo& info = *ctx.info;
            info.animated = true;
            info.keys_from = std::min(info.keys_from, in.deformation->first);
            info.keys_to = std::max(info.keys_to, in.deformation->last);
        }
        if (!mesh) throw_error(in.loc, "{}: its triangle mesh is missing", d.what);
        auto [it, added] = ctx.mesh_hashes.emplace(mesh.get(), 0);
        if (added) it->second = mesh_content_hash(*mesh);
        ctx.registry->put(e, InlineMesh{mesh, it->second, in.loc});
    }
}

/** The index of the material an object names. */
uint32_t material_index(const BuildContext& ctx, const ObjectDesc& d) {
    const std::vector<std::string>& names = ctx.info->material_names;
    const auto it = std::find(names.begin(), names.end(), d.material);
    if (it == names.end())
        throw_error(
            d.material_loc, "unknown material '{}' (defined: {})", d.material,
            names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", ")));
    return static_cast<uint32_t>(it - names.begin());
}

}  // namespace

std::string object_name(const ObjectDesc& d, uint32_t index) {
    if (!d.name.empty()) return d.name;
    std::string file;
    if (const auto* m = std::get_if<MeshFileShape>(&d.shape)) file = m->path;
    if (const auto* c = std::get_if<SubdivShape>(&d.shape)) file = c->path;
    std::string stem = std::filesystem::path(file).stem().string();
    // A sequence's pattern names its frames with a run of '#': the object is the sequence.
    while (!stem.empty() && (stem.back() == '#' || stem.back() == '.' || stem.back() == '_'))
        stem.pop_back();
    return stem.empty() ? fmt::format("object{}", index + 1) : stem;
}

namespace {

/** One object's entity: what it is, its shape, material, placement, emission and motion. */
void build_object(BuildContext& ctx, const ObjectDesc& d, uint32_t index) {
    ecs::Registry& registry = *ctx.registry;
    SceneInfo& info = *ctx.info;
    const ecs::Entity e = registry.create();
    const uint32_t material = material_index(ctx, d);
    const bool catcher = d.shadow_catcher || info.material_catchers[material] != 0;
    registry.put(e, ObjectInfo{d.name, d.loc, index, static_cast<uint8_t>(catcher)});
    info.object_names.push_back(object_name(d, index));
    info.shadow_catchers.push_back(catcher ? 1 : 0);
    put_shape(ctx, e, d);
    registry.put(e, MaterialRef{material});
    KeyedMotion<Affine> motion =
        placement_motion(d, ctx.info->frame_start, ctx.info->fps, ctx.shutter);
    if (!d.keys.keys.empty() || !d.matrix_keys.keys.empty()) info.animated = true;
    note_key_times(info, d.keys);
    note_key_times(info, d.matrix_keys);
    if (d.parent) {  // imported: the importing file's placement of the import, after its own
        motion.middle = d.parent->compose(motion.middle);
        for (Affine& step : motion.steps) step = d.parent->compose(step);
    }
    // Every placement through the shutter is checked (object_placement.h).
    check_placement(d, motion.middle, !motion.steps.empty());
    for (const Affine& step : motion.steps) check_placement(d, step, true);
    registry.put(e, Transform{motion.middle});
    info.object_to_world.push_back(motion.middle);
    const auto* file = std::get_if<MeshFileShape>(&d.shape);
    const auto* cage = std::get_if<SubdivShape>(&d.shape);
    const auto* in = std::get_if<InlineMeshShape>(&d.shape);
    if ((file && (file->sequence || !file->rest_path.empty())) ||
        (cage && (cage->sequence || !cage->rest_path.empty())) ||
        (in && (in->deformation || (in->mesh && !in->mesh->rest_positions.empty())))) {
        info.rest_pose.resize(index + 1, 0);
        info.rest_pose[index] = 1;
    }
    if (d.emission) {
        const Vec3 le = emitted(working_color(ctx, d.emission->color, {0, 0, 0}),
                                d.emission->intensity, d.emission->color.loc, d.what.c_str());
        if (max_component(le) > 0.0f) {
            registry.put(e, Emission{le, d.emission->two_sided});
            if (d.emission->texture)
                registry.put(e, EmissionImage{texture_ref(ctx, *d.emission->texture),
                                              d.emission->color.loc});
        }
        registry.put(e, light_group_component(ctx, d.emission->group));
    }
    if (motion.steps.empty()) return;
    if (registry.has<Emission>(e)) {
        info.notes.push_back(
            fmt::format("{}: {} moves while the shutter is open but emits light: it is not "
                        "blurred (lights are placed at the shutter's middle)",
                        (d.keys.keys.empty() ? d.matrix_keys.loc : d.keys.loc).str(), d.what));
    } else {
        registry.put(e, Motion{std::move(motion.steps)});
        info.motion_blur = true;
    }
}

/** Puts a light's own component on its entity, checking its geometry. */
struct LightPut {
    ecs::Registry& registry;  ///< where
    ecs::Entity e;            ///< the light's entity
    Vec3 value;               ///< colour x intensity, working space
    FileLoc loc;              ///< the light

    /** Refuses a light whose shape reaches beyond what the ray tracer holds (it was black). */
    void check_reach(double reach) const {
        if (!(reach < static_cast<double>(kEmbreeReach)))
            throw_error(loc,
                        "the light reaches {:.3g} from the origin, and the ray tracer (Embree) "
                        "leaves out geometry beyond 1.8e18: scale the scene down",
                        reach);
    }

    /** A quad: its edges must span an area. */
    void operator()(const QuadLightDesc& d) const {
        if (!(length(cross(d.edge1, d.edge2)) > 0.0f))
            throw_error(d.edge2_loc, "quad light edges must span a non-zero area");
        double reach = 0.0;
        for (const Vec3 c :
             {d.corner, d.corner + d.edge1, d.corner + d.edge2, d.corner + d.edge1 + d.edge2})
            reach = std::max(
                reach,
                static_cast<double>(std::max({std::fabs(c.x), std::fabs(c.y), std::fabs(c.z)})));
        check_reach(reach);
        registry.put(e, QuadLight{d.corner, d.edge1, d.edge2, value, d.two_sided, d.transparent});
    }
    /** A sphere. */
    void operator()(const SphereLightDesc& d) const {
        check_reach(d.radius +
                    static_cast<double>(std::max(
                        {std::fabs(d.center.x), std::fabs(d.center.y), std::fabs(d.center.z)})));
        registry.put(e, SphereLight{d.center, static_cast<float>(d.radius), value});
    }
    /** A point light: a PointLight with no cone. */
    void operator()(const PointLightDesc& d) const {
        registry.put(e, PointLight{d.position, value, {}, -1.0f, -1.0f});
    }
    /** A spot light: its cone must point somewhere and fade within its angle. */
    void operator()(const SpotLightDesc& d) const {
        if (!(length(d.look_at - d.position) > 0.0f))
            throw_error(d.look_at_loc, "'look_at' must differ from 'position'");
        const Vec3 axis = normalize(d.look_at - d.position);
        if (d.cone_falloff > d.cone_angle)
            throw_error(d.cone_falloff_loc, "'cone_falloff' ({}) must not exceed 'cone_angle' ({})",
                        d.cone_falloff, d.cone_angle);
        const auto cos_outer = static_cast<float>(std::cos(d.cone_angle * M_PI / 180.0));
        const auto cos_inner =
            static_cast<float>(std::cos((d.cone_angle - d.cone_falloff) * M_PI / 180.0));
        registry.put(e, PointLight{d.position, value, axis, cos_outer, cos_inner, d.quartic});
    }
    /** A distant light: its direction must not be zero. */
    void operator()(const DistantLightDesc& d) const {
        if (!(length(d.direction) > 0.0f))
            throw_error(d.direction_loc, "'direction' must not be zero");
        registry.put(e, DistantLight{normalize(d.direction), value,
                                     static_cast<float>(d.angular_radius_deg)});
    }
};

/** One light's entity: its light group and its light. */
void build_light(BuildContext& ctx, const LightDesc& d) {
    const Vec3 value = emitted(working_color(ctx, d.color, {1, 1, 1}), d.intensity, d.loc, "light");
    const ecs::Entity e = ctx.registry->create();
    ctx.registry->put(e, light_group_component(ctx, d.group));
    std::visit(LightPut{*ctx.registry, e, value, d.loc}, d.shape);
}

}  // namespace

SceneInfo build_scene(const SceneDescription& scene, ColorConfig& color, ecs::Registry& registry,
                      double time) {
    SceneInfo info;
    info.path = scene.path;
    info.files = scene.files;
    info.scene_files_hash = scene_content_hash(scene.path, scene.files);
    // And the camera looked through (a file may hold several: crop parts through others differ).
    info.content_hash = hash2(info.scene_files_hash, camera_hash(scene.camera));
    info.notes = scene.notes;
    info.output = scene.render.output.value_or("");
    info.output_loc = scene.render.output_loc;
    info.time = time;
    BuildContext ctx{&color, &registry, &info, {}, {}, {}};
    const ecs::Entity settings = registry.create();
    build_render(ctx, scene.render, settings);
    build_camera(ctx, scene.camera, settings);
    if (scene.environment) build_environment(ctx, *scene.environment);
    for (const MaterialDesc& m : scene.materials) build_material(ctx, m);
    for (std::size_t i = 0; i < scene.objects.size(); ++i)
        build_object(ctx, scene.objects[i], static_cast<uint32_t>(i));
    for (const LightDesc& l : scene.lights) build_light(ctx, l);
    // Nothing emits: the image is black. Said, as pbrt does, rather than left to be found.
    bool lit = registry.count<QuadLight>() > 0 || registry.count<SphereLight>() > 0 ||
               registry.count<PointLight>() > 0 || registry.count<DistantLight>() > 0 ||
               registry.count<Emission>() > 0 || registry.count<EnvironmentMapFile>() > 0;
    if (const auto* env = registry.find_pool<Environment>())
        for (std::size_t i = 0; i < env->size() && !lit; ++i)
            lit = max_component(env->columns().get(i).radiance) > 0.0f;
    if (!lit)
        info.notes.push_back(fmt::format(
            "{}: the scene has no light (no light, no emitting object, a black environment): "
            "it renders black",
            scene.path));
    // The camera inside a sphere light: it emits outward, so from within it is black and lights
    // nothing (a "dome" made of one).
    for (std::size_t i = 0; i < scene.lights.size(); ++i)
        if (const auto* sphere = std::get_if<SphereLightDesc>(&scene.lights[i].shape)) {
            const Vec3 d = scene.camera.position - sphere->center;
            const double dist = std::hypot(double(d.x), double(d.y), double(d.z));
            if (dist < sphere->radius)
                info.notes.push_back(fmt::format(
                    "{}: the camera is inside this sphere light, which emits outward: from within "
                    "it is black and lights nothing (for light all around, use [environment])",
                    scene.lights[i].loc.str()));
        }
    // Objects of one name: the Cryptomatte (and every tool that picks objects by name) cannot
    // tell them apart. Said once, with the first pair.
    {
        std::unordered_map<std::string, const ObjectDesc*> named;
        std::size_t shared = 0;
        std::string first;
        for (const ObjectDesc& o : scene.objects) {
            if (o.name.empty()) continue;
            const auto [it, fresh] = named.emplace(o.name, &o);
            if (fresh) continue;
            if (shared++ == 0)
                first =
                    fmt::format("'{}' at {} and {}", o.name, it->second->loc.str(), o.loc.str());
        }
        if (shared > 0)
            info.notes.push_back(fmt::format(
                "{}: {} object{} share{} a name with an earlier one ({}): their Cryptomatte "
                "mattes are one; give each its own `name` to pick them apart",
                scene.path, shared, shared == 1 ? "" : "s", shared == 1 ? "s" : "", first));
    }
    // Nothing to see at all: no objects and no environment (an environment alone is a
    // panorama of it, rendered on purpose).
    if (scene.objects.empty() && !scene.environment)
        info.notes.push_back(
            fmt::format("{}: the scene has no objects and no environment: the image shows only "
                        "the lights seen directly",
                        scene.path));
    return info;
}

}  // namespace spangle
