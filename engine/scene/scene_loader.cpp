#include "scene/scene_loader.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include "core/pixel_filter.h"
#include "scene/animation.h"
#include "scene/components.h"
#include "scene/toml_reader.h"

namespace fs = std::filesystem;

namespace spangle {

namespace {

constexpr Range kNonNegative{0.0, 1e30, false, false};

/** Everything a section parser needs besides its table. */
struct ParseContext {
    std::string file;                           ///< scene path as given
    fs::path dir;                               ///< directory for relative paths
    ColorConfig* color;                         ///< for conversion to the working space
    std::string bare_space;                     ///< colour space of bare [r, g, b] arrays
    std::vector<std::string>* notes = nullptr;  ///< stand-ins used (SceneInfo)
};

/** Resolves a colour space name or throws at `at` listing the known ones. */
std::string resolve_space(const ParseContext& ctx, const std::string& name, const FileLoc& at,
                          const char* implicit = nullptr) {
    auto resolved = ctx.color->resolve(name);
    if (!resolved)
        throw_error(at, "unknown {}colour space '{}' (known: {}); {}", implicit ? implicit : "",
                    name, fmt::join(ctx.color->space_names(), ", "), ctx.color->how_to_fix());
    if (!resolved->via.empty() && ctx.notes) {
        const std::string note =
            fmt::format("{}: {}colour space '{}' is not in the OCIO config '{}'; using {}",
                        at.str(), implicit ? implicit : "", name, ctx.color->path(), resolved->via);
        auto& notes = *ctx.notes;
        if (std::find(notes.begin(), notes.end(), note) == notes.end()) notes.push_back(note);
    }
    return resolved->name;
}

/** A colour as written: raw numbers and the canonical space they are in. */
struct RawColor {
    Vec3 rgb;
    std::string space;
};

/** Reads `[r, g, b]` (in the bare space) or `{ rgb = [r, g, b], space = "name" }`. */
RawColor parse_raw_color(const ParseContext& ctx, const toml::node& n, std::string_view name) {
    if (auto t = n.as_table()) {
        TableReader r(*t, ctx.file, fmt::format("colour '{}'", name));
        RawColor c;
        c.rgb = r.vec3("rgb");
        c.space =
            r.has("space") ? resolve_space(ctx, r.string("space"), r.loc("space")) : ctx.bare_space;
        r.finish();
        return c;
    }
    if (!n.is_array())
        throw_error(
            loc_of(n, ctx.file),
            "'{}' must be a colour: [r, g, b] or {{ rgb = [r, g, b], space = \"...\" }}, got {}",
            name, toml_type_name(n));
    return {parse_vec3(n, ctx.file, name), ctx.bare_space};
}

/** A non-negative colour converted to the working space. */
Vec3 read_color(const ParseContext& ctx, TableReader& r, std::string_view key, Vec3 fallback) {
    const toml::node* n = r.node(key);
    if (!n) return fallback;
    RawColor c = parse_raw_color(ctx, *n, key);
    if (c.rgb.x < 0 || c.rgb.y < 0 || c.rgb.z < 0)
        throw_error(loc_of(*n, ctx.file), "'{}' must be non-negative, got [{}, {}, {}]", key,
                    c.rgb.x, c.rgb.y, c.rgb.z);
    float rgb[3] = {c.rgb.x, c.rgb.y, c.rgb.z};
    ctx.color->to_working(c.space, rgb, 1);
    // Gamut mapping can push a channel a hair below zero; radiance and albedo cannot be negative.
    return {std::max(rgb[0], 0.0f), std::max(rgb[1], 0.0f), std::max(rgb[2], 0.0f)};
}

Film parse_render(TableReader& r) {
    Film f;
    f.width = static_cast<uint32_t>(r.integer("width", 640, {1, 16384}));
    f.height = static_cast<uint32_t>(r.integer("height", 360, {1, 16384}));
    f.spp = static_cast<uint32_t>(r.integer("spp", 16, {1, 1 << 20}));
    f.max_depth = static_cast<uint32_t>(r.integer("max_depth", 5, {1, 1024}));
    f.rr_depth = static_cast<uint32_t>(r.integer("rr_depth", 3, {1, 1024}));
    f.seed = static_cast<uint64_t>(r.integer("seed", 0, {0, 9.0e18}));
    const std::string filter = r.string("filter", "gaussian");
    f.clamp_indirect = static_cast<float>(r.number("clamp_indirect", 0.0, {0.0, 1e30}));
    if (!parse_filter(filter, f.filter))
        throw_error(r.loc("filter"), "unknown filter '{}' (valid: box, gaussian, blackman-harris)",
                    filter);
    return f;
}

Camera parse_camera(TableReader& r) {
    Camera c;
    c.position = r.vec3("position");
    c.look_at = r.vec3("look_at");
    c.up = r.vec3("up", {0, 1, 0});
    c.fov_deg = static_cast<float>(r.number("fov", 40.0, {0.0, 180.0, true, true}));
    const Vec3 dir = c.look_at - c.position;
    if (!(length(dir) > 0.0f))
        throw_error(r.loc("look_at"), "'look_at' must differ from 'position'");
    if (!(length(cross(dir, c.up)) > 1e-6f * length(dir) * length(c.up)))
        throw_error(r.loc("up"), "'up' must not be parallel to the viewing direction");
    c.aperture = static_cast<float>(r.number("aperture", 0.0, {0.0, 1e3}));
    c.focus_distance =
        static_cast<float>(r.number("focus_distance", length(dir), {0.0, 1e30, true}));
    return c;
}

/** An object's placement as written: scale, Euler rotation (degrees), translation. */
struct TransformParts {
    Vec3 scale{1, 1, 1}, rotate{0, 0, 0}, translate{0, 0, 0};
    Affine compose() const {
        // Euler angles in degrees, applied about X, then Y, then Z.
        Affine m = Affine::scale(scale);
        m = Affine::rotate(rotate.x, {1, 0, 0}).compose(m);
        m = Affine::rotate(rotate.y, {0, 1, 0}).compose(m);
        m = Affine::rotate(rotate.z, {0, 0, 1}).compose(m);
        return Affine::translate(translate).compose(m);
    }
};

/** scale, rotate, translate of a table, each defaulting to `base`'s. */
TransformParts parse_transform_parts(TableReader& r, const TransformParts& base = {}) {
    TransformParts t = base;
    if (const toml::node* s = r.node("scale")) {
        Vec3 v;
        if (s->is_number()) {
            const double k = s->value<double>().value_or(0.0);
            v = Vec3(static_cast<float>(k));
        } else {
            v = parse_vec3(*s, r.file(), "scale");
        }
        // Rays are carried into object space by the inverse scale, in floats: beyond 1e8 either
        // way they overflow or lose every bit of precision (1e-20 sent non-finite rays).
        const auto in_range = [](float k) {
            return std::isfinite(k) && std::fabs(k) >= 1e-8f && std::fabs(k) <= 1e8f;
        };
        if (!in_range(v.x) || !in_range(v.y) || !in_range(v.z))
            throw_error(loc_of(*s, r.file()),
                        "'scale' must be between 1e-8 and 1e8 in size in every axis, got [{}, {}, "
                        "{}] (model in other units instead)",
                        v.x, v.y, v.z);
        t.scale = v;
    }
    t.rotate = r.vec3("rotate", base.rotate);
    t.translate = r.vec3("translate", base.translate);
    return t;
}

/** The time `offset` frames after the scene's time (shutter = [open, close] is in frames). */
double shutter_time(const SceneInfo& info, double offset) {
    return info.time + offset / info.fps;
}

/** The middle of the shutter: where what does not blur is placed (the frame's time when the
 *  scene has no shutter). */
double shutter_middle(const SceneInfo& info) {
    return shutter_time(info, 0.5 * (info.shutter_open + info.shutter_close));
}

/** The time of one key: `time` in seconds, or `frame` (a frame number of [render]). */
double key_time(TableReader& r, const SceneInfo& info) {
    const bool has_time = r.has("time"), has_frame = r.has("frame");
    if (has_time == has_frame)
        throw_error(r.loc(), "{} needs exactly one of 'time' (seconds) or 'frame'", r.what());
    if (has_time) return r.number("time", {-1e9, 1e9});
    return frame_time(info, r.integer("frame", 0, {-1e9, 1e9}));
}

/** `interpolation = "smooth" | "linear"` of an animated table. */
bool smooth_interpolation(TableReader& r) {
    const std::string how = r.string("interpolation", "smooth");
    if (how != "smooth" && how != "linear")
        throw_error(r.loc("interpolation"),
                    "'interpolation' must be \"smooth\" or \"linear\", got \"{}\"", how);
    return how == "smooth";
}

/** Appends one key to a track, checking that keys go forward in time. */
void add_key(Track& track, double time, std::vector<double> values, const TableReader& r) {
    if (!track.times.empty() && !(time > track.times.back()))
        throw_error(r.loc(), "{}: keys must be in increasing time ({} s follows {} s)", r.what(),
                    time, track.times.back());
    track.times.push_back(time);
    track.values.push_back(std::move(values));
}

/** `[a, b]`: an array of exactly two numbers, into a and b; false for anything else. */
bool two_numbers(const toml::node& n, float& a, float& b) {
    const auto* arr = n.as_array();
    if (!arr || arr->size() != 2 || !(*arr)[0].is_number() || !(*arr)[1].is_number()) return false;
    a = static_cast<float>((*arr)[0].value<double>().value_or(0.0));
    b = static_cast<float>((*arr)[1].value<double>().value_or(0.0));
    return true;
}

/** Which table a texture is read for: a material parameter, or one of the host's maps. */
enum class TextureUse { Param, NormalMap, BumpMap };

/** `{ texture = "file", space = ..., scale = ..., uv_transform = {...}, wrap = ... }` (plus
 *  `strength` for a normal map, `height` for a bump map). */
TextureRef parse_texture(const ParseContext& ctx, const toml::table& t, std::string_view name,
                         TextureUse use) {
    TableReader r(t, ctx.file, fmt::format("texture '{}'", name));
    TextureRef tex;
    {
        const std::string given = r.string("texture");
        if (given.empty()) throw_error(r.loc("texture"), "'texture' must not be empty");
        fs::path p(given);
        if (p.is_relative()) p = ctx.dir / p;
        std::error_code ec;
        if (!fs::is_regular_file(p, ec))
            throw_error(r.loc("texture"), "texture file '{}' not found (looked for {})", given,
                        p.string());
        tex.path = p.lexically_normal().string();
    }
    if (r.has("space")) {
        const std::string s = r.string("space");
        tex.space = s == "raw" || s == "data" ? "raw" : resolve_space(ctx, s, r.loc("space"));
    }
    if (use == TextureUse::Param && r.has("scale")) {
        const toml::node& n = *r.node("scale");
        if (n.is_array()) {
            const Vec3 v = parse_vec3(n, ctx.file, "scale");
            tex.scale[0] = v.x;
            tex.scale[1] = v.y;
            tex.scale[2] = v.z;
        } else {
            const auto k = static_cast<float>(r.number("scale", 1.0, {0.0, 1e6}));
            tex.scale[0] = tex.scale[1] = tex.scale[2] = k;
        }
        for (float k : tex.scale)
            if (!(k >= 0.0f))
                throw_error(r.loc("scale"), "'scale' must be non-negative, got {}", k);
    }
    if (use == TextureUse::NormalMap)
        tex.amount = static_cast<float>(r.number("strength", 1.0, {0.0, 10.0}));
    if (use == TextureUse::BumpMap)
        tex.amount = static_cast<float>(r.number("height", 0.001, {-1.0, 1.0}));
    if (const toml::table* uv = r.table("uv_transform")) {
        TableReader u(*uv, ctx.file, "uv_transform");
        float su = 1, sv = 1;
        if (u.has("scale")) {
            const toml::node& n = *u.node("scale");
            if (n.is_array()) {
                if (!two_numbers(n, su, sv))
                    throw_error(loc_of(n, ctx.file),
                                "'scale' must be a number or two numbers [su, sv]");
            } else {
                su = sv = static_cast<float>(u.number("scale", 1.0, {-1e6, 1e6}));
            }
            if (su == 0.0f || sv == 0.0f || !std::isfinite(su) || !std::isfinite(sv))
                throw_error(loc_of(n, ctx.file), "uv 'scale' must be finite and non-zero");
        }
        float ou = 0, ov = 0;
        if (u.has("offset")) {
            const toml::node& n = *u.node("offset");
            if (!two_numbers(n, ou, ov))
                throw_error(loc_of(n, ctx.file), "'offset' must be two numbers [ou, ov]");
            if (!std::isfinite(ou) || !std::isfinite(ov))
                throw_error(loc_of(n, ctx.file), "'offset' must be finite");
        }
        const double rot =
            u.number("rotate", 0.0, {-360.0, 360.0}) * 3.14159265358979323846 / 180.0;
        u.finish();
        // uv' = R(rotate) (scale * uv) + offset
        const auto c = static_cast<float>(std::cos(rot)), s = static_cast<float>(std::sin(rot));
        tex.uv[0] = c * su;
        tex.uv[1] = -s * sv;
        tex.uv[2] = ou;
        tex.uv[3] = s * su;
        tex.uv[4] = c * sv;
        tex.uv[5] = ov;
    }
    if (r.has("wrap")) {
        const std::string w = r.string("wrap");
        const char* modes[] = {"periodic", "clamp", "black", "mirror"};
        tex.wrap = -1;
        for (int i = 0; i < 4; ++i)
            if (w == modes[i]) tex.wrap = i;
        if (tex.wrap < 0)
            throw_error(r.loc("wrap"),
                        "'wrap' must be one of periodic, clamp, black, mirror, got \"{}\"", w);
    }
    if (r.has("filter")) {
        const std::string f = r.string("filter");
        if (f != "trilinear" && f != "anisotropic")
            throw_error(r.loc("filter"),
                        "'filter' must be \"trilinear\" or \"anisotropic\", got \"{}\"", f);
        tex.filter = f == "anisotropic" ? 1 : 0;
    }
    r.finish();
    return tex;
}

ParamEntry parse_param(const ParseContext& ctx, const toml::key& k, const toml::node& n) {
    const std::string key(k.str());
    ParamEntry p;
    p.name = key;
    p.loc = loc_of(n, ctx.file);
    p.key_loc = key_location(k, n, ctx.file);
    if (auto i = n.as_integer()) {
        p.kind = ParamEntry::Kind::Number;
        p.number[0] = static_cast<double>(i->get());
        p.is_integer = true;
    } else if (auto f = n.as_floating_point()) {
        if (!std::isfinite(f->get()))
            throw_error(p.loc, "parameter '{}' must be finite, got {}", key, f->get());
        p.kind = ParamEntry::Kind::Number;
        p.number[0] = f->get();
    } else if (auto b = n.as_boolean()) {
        p.kind = ParamEntry::Kind::Bool;
        p.number[0] = b->get() ? 1.0 : 0.0;
    } else if (auto s = n.as_string()) {
        p.kind = ParamEntry::Kind::String;
        p.text = s->get();
    } else if (n.is_table() && n.as_table()->contains("texture")) {
        p.kind = ParamEntry::Kind::Texture;
        p.texture = parse_texture(ctx, *n.as_table(), key, TextureUse::Param);
        p.text = p.texture.path;
    } else if (n.is_array() || n.is_table()) {
        RawColor c = parse_raw_color(ctx, n, key);
        p.kind = ParamEntry::Kind::Color;
        p.number[0] = c.rgb.x;
        p.number[1] = c.rgb.y;
        p.number[2] = c.rgb.z;
        p.text = c.space;
    } else {
        throw_error(p.loc, "parameter '{}' has unsupported type {}", key, toml_type_name(n));
    }
    return p;
}

Material parse_material(const ParseContext& ctx, TableReader& r) {
    Material m;
    m.loc = r.loc();
    m.name = r.string("name");
    m.plugin = r.string("plugin");
    m.plugin_loc = r.loc("plugin");
    m.model = r.string("model", "");
    m.model_loc = r.loc("model");
    if (const toml::table* params = r.table("params"))
        for (auto&& [key, value] : *params) m.params.push_back(parse_param(ctx, key, value));
    // Maps the host applies to the shading frame before the plugin sees the point.
    for (const auto& [key, use] : {std::pair{"normal_map", TextureUse::NormalMap},
                                   std::pair{"bump_map", TextureUse::BumpMap}}) {
        const toml::table* t = r.table(key);
        if (!t) continue;
        ParamEntry p;
        p.name = key;
        p.kind = ParamEntry::Kind::Texture;
        p.loc = r.loc(key);
        p.key_loc = p.loc;
        p.texture = parse_texture(ctx, *t, key, use);
        p.text = p.texture.path;
        m.maps.push_back(std::move(p));
    }
    if (m.maps.size() == 2)
        throw_error(r.loc("bump_map"), "material '{}': give a normal_map or a bump_map, not both",
                    m.name);
    return m;
}

/** Parses and validates a path relative to the scene file. */
std::string resolve_file(const ParseContext& ctx, TableReader& r, std::string_view key) {
    const std::string given = r.string(key);
    if (given.empty()) throw_error(r.loc(key), "'{}' must not be empty", key);
    fs::path p(given);
    if (p.is_relative()) p = ctx.dir / p;
    std::error_code ec;
    if (!fs::is_regular_file(p, ec))
        throw_error(r.loc(key), "{} file '{}' not found (looked for {})", key, given, p.string());
    return p.lexically_normal().string();
}

/** The `subdiv = { ... }` table of an object. */
SubdivSurface parse_subdiv(const ParseContext& ctx, const toml::table& t, std::string path,
                           FileLoc loc) {
    TableReader r(t, ctx.file, "subdiv");
    SubdivSurface s;
    s.path = std::move(path);
    s.loc = loc;
    const std::string scheme = r.string("scheme", "catmull-clark");
    if (scheme == "catmull-clark")
        s.options.scheme = SubdivOptions::Scheme::CatmullClark;
    else if (scheme == "loop")
        s.options.scheme = SubdivOptions::Scheme::Loop;
    else
        throw_error(r.loc("scheme"), "unknown scheme '{}' (valid: catmull-clark, loop)", scheme);
    const std::string boundary = r.string("boundary", "edge_and_corner");
    if (boundary == "none")
        s.options.boundary = SubdivOptions::Boundary::None;
    else if (boundary == "edge_only")
        s.options.boundary = SubdivOptions::Boundary::EdgeOnly;
    else if (boundary == "edge_and_corner")
        s.options.boundary = SubdivOptions::Boundary::EdgeAndCorner;
    else
        throw_error(r.loc("boundary"),
                    "unknown boundary '{}' (valid: none, edge_only, edge_and_corner)", boundary);
    const std::string uv = r.string("uv_interpolation", "corners_only");
    if (uv == "smooth")
        s.options.uv_interpolation = SubdivOptions::UvInterpolation::Smooth;
    else if (uv == "corners_only")
        s.options.uv_interpolation = SubdivOptions::UvInterpolation::CornersOnly;
    else if (uv == "boundaries")
        s.options.uv_interpolation = SubdivOptions::UvInterpolation::Boundaries;
    else if (uv == "all")
        s.options.uv_interpolation = SubdivOptions::UvInterpolation::All;
    else
        throw_error(r.loc("uv_interpolation"),
                    "unknown uv_interpolation '{}' (valid: smooth, corners_only, boundaries, all)",
                    uv);
    s.options.level = -1;
    if (const toml::node* level = r.node("level")) {
        if (level->is_string()) {
            if (level->value<std::string>().value_or("") != "auto")
                throw_error(loc_of(*level, ctx.file),
                            "'level' must be an integer 0..8 or \"auto\"");
        } else {
            s.options.level = static_cast<int>(r.integer("level", 0, {0, 8}));
        }
    }
    s.max_level = static_cast<int>(r.integer("max_level", 5, {0, 8}));
    // Below a thousandth of a pixel every edge would ask for the deepest level anyway.
    s.pixel_budget = static_cast<float>(r.number("pixel_budget", 2.0, {1e-3, 1e6}));
    // creases = [[v0, v1, sharpness], ...], corners = [[v, sharpness], ...]
    const auto read_list = [&](const char* key, std::size_t width, auto&& take) {
        const toml::node* n = r.node(key);
        if (!n) return;
        const toml::array* arr = n->as_array();
        if (!arr) throw_error(loc_of(*n, ctx.file), "'{}' must be an array of arrays", key);
        for (const toml::node& e : *arr) {
            const toml::array* item = e.as_array();
            if (!item || item->size() != width)
                throw_error(loc_of(e, ctx.file),
                            "each entry of '{}' must be an array of {} numbers", key, width);
            std::vector<double> v;
            for (const toml::node& x : *item) {
                if (!x.is_number())
                    throw_error(loc_of(x, ctx.file), "'{}' entries must be numbers", key);
                v.push_back(x.value<double>().value_or(0.0));
            }
            for (std::size_t k = 0; k + 1 < width; ++k)
                if (!(v[k] >= 0 && v[k] <= 2147483647.0) || v[k] != std::floor(v[k]))
                    throw_error(loc_of(e, ctx.file),
                                "'{}' vertex indices must be integers in 0..2147483647, got {}",
                                key, v[k]);
            if (!(v[width - 1] >= 0.0 && v[width - 1] <= 10.0))
                throw_error(loc_of(e, ctx.file), "'{}' sharpness must be in [0, 10], got {}", key,
                            v[width - 1]);
            take(v);
        }
    };
    read_list("creases", 3, [&](const std::vector<double>& v) {
        s.options.crease_vertices.push_back(static_cast<int>(v[0]));
        s.options.crease_vertices.push_back(static_cast<int>(v[1]));
        s.options.crease_sharpness.push_back(static_cast<float>(v[2]));
    });
    read_list("corners", 2, [&](const std::vector<double>& v) {
        s.options.corner_vertices.push_back(static_cast<int>(v[0]));
        s.options.corner_sharpness.push_back(static_cast<float>(v[1]));
    });
    r.finish();
    return s;
}

/** The `light_group` of a light, an emissive object or the environment, as an index into
 *  `groups` (added on first use); "default" when the table names none. */
LightGroup parse_light_group(TableReader& r, std::vector<std::string>& groups) {
    const std::string name = r.string("light_group", "default");
    if (name.empty() || name.size() > 64 ||
        name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_") !=
            std::string::npos)
        throw_error(r.loc("light_group"),
                    "'light_group' must be 1 to 64 letters, digits or underscores (it names a "
                    "layer of the EXR), got \"{}\"",
                    name);
    auto it = std::find(groups.begin(), groups.end(), name);
    if (it == groups.end()) it = groups.insert(groups.end(), name);
    return LightGroup{static_cast<uint32_t>(it - groups.begin())};
}

/** One [[light]] table of any type. */
void parse_light(const ParseContext& ctx, TableReader& r, ecs::Registry& registry,
                 std::vector<std::string>& groups) {
    const std::string type = r.string("type");
    const Vec3 color = read_color(ctx, r, "color", {1, 1, 1});
    const auto intensity = static_cast<float>(r.number("intensity", 1.0, kNonNegative));
    const Vec3 value = color * intensity;
    const ecs::Entity e = registry.create();
    registry.put(e, parse_light_group(r, groups));
    if (type == "quad") {
        QuadLight q;
        q.corner = r.vec3("corner");
        q.edge1 = r.vec3("edge1");
        q.edge2 = r.vec3("edge2");
        if (!(length(cross(q.edge1, q.edge2)) > 0.0f))
            throw_error(r.loc("edge2"), "quad light edges must span a non-zero area");
        q.radiance = value;
        q.two_sided = r.boolean("two_sided", false);
        registry.put(e, q);
    } else if (type == "sphere") {
        SphereLight s;
        s.center = r.vec3("center");
        s.radius = static_cast<float>(r.number("radius", {0.0, 1e30, true}));
        s.radiance = value;
        registry.put(e, s);
    } else if (type == "point" || type == "spot") {
        PointLight p;
        p.position = r.vec3("position");
        p.intensity = value;
        p.cos_outer = p.cos_inner = -1.0f;
        if (type == "spot") {
            const Vec3 target = r.vec3("look_at");
            if (!(length(target - p.position) > 0.0f))
                throw_error(r.loc("look_at"), "'look_at' must differ from 'position'");
            p.axis = normalize(target - p.position);
            const double angle = r.number("cone_angle", 30.0, {0.0, 90.0, true, false});
            const double falloff = r.number("cone_falloff", 5.0, {0.0, 90.0});
            if (falloff > angle)
                throw_error(r.loc("cone_falloff"),
                            "'cone_falloff' ({}) must not exceed 'cone_angle' ({})", falloff,
                            angle);
            p.cos_outer = static_cast<float>(std::cos(angle * M_PI / 180.0));
            p.cos_inner = static_cast<float>(std::cos((angle - falloff) * M_PI / 180.0));
        }
        registry.put(e, p);
    } else if (type == "distant") {
        DistantLight d;
        const Vec3 dir = r.vec3("direction");
        if (!(length(dir) > 0.0f)) throw_error(r.loc("direction"), "'direction' must not be zero");
        d.direction = normalize(dir);
        d.irradiance = value;
        d.angular_radius_deg = static_cast<float>(r.number("angular_radius", 0.0, {0.0, 45.0}));
        registry.put(e, d);
    } else {
        throw_error(r.loc("type"),
                    "unknown light type '{}' (valid: quad, sphere, point, spot, distant)", type);
    }
}

std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/** The TOML parser recurses once per nesting level and per dotted key part: a hostile file
 *  (50,000 dotted parts, arrays nested 100,000 deep) overflowed the stack. This scan, over the
 *  raw text with strings and comments skipped, refuses such files first. */
void check_nesting(const std::string& text, const std::string& path) {
    constexpr int kMaxDepth = 64, kMaxKeyParts = 128;
    std::vector<char> open;  // '[' or '{' not yet closed
    bool key = true;         // in a key: before '=' on a line or after '{' or ',' in a table
    int parts = 1, line = 1, column = 1;
    const auto fail = [&](const char* what, int limit) {
        throw_error(FileLoc{path, line, column}, "{} (at most {}); the scene cannot be this deep",
                    what, limit);
    };
    for (std::size_t i = 0; i < text.size(); ++i, ++column) {
        const char c = text[i];
        if (c == '\n') {
            ++line;
            column = 0;
            if (open.empty()) key = true, parts = 1;
            continue;
        }
        if (c == '#') {  // a comment, to the end of the line
            while (i + 1 < text.size() && text[i + 1] != '\n') ++i;
            continue;
        }
        if (c == '"' || c == '\'') {  // a string: basic, literal, or either multi-line
            const bool triple = text.compare(i, 3, std::string(3, c)) == 0;
            i += triple ? 3 : 1;
            for (; i < text.size(); ++i) {
                if (text[i] == '\n') ++line, column = 0;
                if (c == '"' && text[i] == '\\') {
                    ++i;
                    continue;
                }
                if (text[i] == c && (!triple || text.compare(i, 3, std::string(3, c)) == 0)) {
                    if (triple) i += 2;
                    break;
                }
            }
            continue;
        }
        if (c == '[' || c == '{') {
            open.push_back(c);
            if (static_cast<int>(open.size()) > kMaxDepth)
                fail("arrays and tables nested too deep", kMaxDepth);
            if (c == '{') key = true, parts = 1;
        } else if ((c == ']' || c == '}') && !open.empty()) {
            open.pop_back();
        } else if (c == '=') {
            key = false;
        } else if (c == ',' && !open.empty() && open.back() == '{') {
            key = true;
            parts = 1;
        } else if (c == '.' && key) {
            if (++parts > kMaxKeyParts) fail("a key of too many dotted parts", kMaxKeyParts);
        }
    }
}

}  // namespace

SceneInfo load_scene(const std::string& path, ColorConfig& color, ecs::Registry& registry,
                     double time) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw_error("scene file '{}' not found", path);
    if (!fs::is_regular_file(path, ec))
        throw_error("scene file '{}' is not a regular file (a folder, a device or a pipe)", path);

    toml::table root;
    try {
        const std::string text = read_text(path);
        check_nesting(text, path);
        root = toml::parse(text, path);
    } catch (const toml::parse_error& e) {
        const auto& s = e.source().begin;
        throw_error(FileLoc{path, static_cast<int>(s.line), static_cast<int>(s.column)},
                    "invalid TOML: {}", e.description());
    }

    SceneInfo info;
    info.path = path;
    info.time = time;
    ParseContext ctx{path, fs::path(path).parent_path(), &color, {}, &info.notes};
    TableReader top(root, path, "the scene");
    top.set_whole_file();

    const ecs::Entity settings = registry.create();
    {
        const toml::table* t = top.table("render");
        toml::table empty;
        TableReader r(t ? *t : empty, path, "[render]");
        if (r.has("working_space"))
            color.set_working_space(
                resolve_space(ctx, r.string("working_space"), r.loc("working_space")));
        if (color.working_space().empty())
            color.set_working_space(
                resolve_space(ctx, "ACEScg", r.loc(), "default (no key written) working "));
        ctx.bare_space =
            r.has("color_space")
                ? resolve_space(ctx, r.string("color_space"), r.loc("color_space"))
                : resolve_space(ctx, "lin_rec709", r.loc(), "default (no key written) ");
        registry.put(settings, parse_render(r));
        info.frame_start = r.integer("frame_start", 1, {-1e9, 1e9});
        info.frame_end =
            r.integer("frame_end", info.frame_start, {static_cast<double>(info.frame_start), 1e9});
        info.fps = r.number("fps", 24.0, {0.0, 1e6, true});
        if (const toml::node* n = r.node("shutter")) {
            float open = 0.0f, close = 0.0f;
            if (!two_numbers(*n, open, close) || !std::isfinite(open) || !std::isfinite(close))
                throw_error(loc_of(*n, path),
                            "'shutter' must be [open, close]: two numbers, in frames from the "
                            "frame's time (e.g. [-0.25, 0.25] for a 180-degree shutter centred "
                            "on the frame)");
            if (!(open <= close) || !(std::fabs(open) <= 16.0f && std::fabs(close) <= 16.0f))
                throw_error(loc_of(*n, path),
                            "'shutter' = [{}, {}]: open must not come after close, and both "
                            "must lie within 16 frames of the frame",
                            open, close);
            info.shutter_open = open;
            info.shutter_close = close;
        }
        r.finish();
        info.working_space = color.working_space();
        info.color_space = ctx.bare_space;
    }
    {
        const toml::table* t = top.table("camera");
        if (!t) top.missing("camera");
        TableReader r(*t, path, "[camera]");
        const bool focus_given = r.has("focus_distance");
        info.camera = parse_camera(r);
        if (const toml::array* keys = r.table_array("keys")) {
            // Keyframed camera: position, look_at, up and fov per key, each defaulting to the
            // [camera] table's own.
            const Camera base = info.camera;
            Track track;
            track.smooth = smooth_interpolation(r);
            for (std::size_t k = 0; k < keys->size(); ++k) {
                TableReader kr(*(*keys)[k].as_table(), path,
                               fmt::format("[[camera.keys]] #{}", k + 1));
                const double when = key_time(kr, info);
                const Vec3 p = kr.vec3("position", base.position);
                const Vec3 l = kr.vec3("look_at", base.look_at);
                const Vec3 u = kr.vec3("up", base.up);
                const double fov = kr.number("fov", base.fov_deg, {0.0, 180.0, true, true});
                kr.finish();
                add_key(track, when, {p.x, p.y, p.z, l.x, l.y, l.z, u.x, u.y, u.z, fov}, kr);
            }
            // The camera at time t; the component is the camera at the shutter's middle.
            const auto camera_at = [&](double when) {
                const std::vector<double> v = evaluate(track, when);
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
                    throw_error(r.loc("keys"),
                                "the keyframed camera at {} s looks nowhere: its look_at meets "
                                "its position, its up is parallel to the view, or its fov leaves "
                                "(0, 180)",
                                when);
                if (!focus_given) c.focus_distance = length(dir);
                return c;
            };
            info.camera = camera_at(shutter_middle(info));
            if (info.shutter_open < info.shutter_close) {
                // Straight enough: the eye and the point looked at stray from the straight line
                // by under 1% of the distance they move; up and fov by under 1e-3.
                const auto close = [](const Camera& ca, const Camera& cb, const Camera& cm,
                                      float q) {
                    const auto off = [q](Vec3 x0, Vec3 x1, Vec3 xm) {
                        return length(xm - (x0 + (x1 - x0) * q));
                    };
                    const float moved =
                        length(cb.position - ca.position) + length(cb.look_at - ca.look_at);
                    return off(ca.position, cb.position, cm.position) <= 0.01f * moved + 1e-6f &&
                           off(ca.look_at, cb.look_at, cm.look_at) <= 0.01f * moved + 1e-6f &&
                           off(ca.up, cb.up, cm.up) <= 1e-3f * length(cm.up) &&
                           std::fabs(cm.fov_deg - (ca.fov_deg + (cb.fov_deg - ca.fov_deg) * q)) <=
                               1e-3f * cm.fov_deg;
                };
                std::vector<Camera> steps = motion_steps(shutter_time(info, info.shutter_open),
                                                         shutter_time(info, info.shutter_close),
                                                         camera_at, close, Camera::same);
                if (!steps.empty()) {
                    registry.put(settings, CameraMotion{std::move(steps)});
                    info.motion_blur = true;
                }
            }
            info.animated = true;
        } else if (r.has("interpolation")) {
            smooth_interpolation(r);
        }
        registry.put(settings, info.camera);
        r.finish();
    }
    if (const toml::table* t = top.table("environment")) {
        TableReader r(*t, path, "[environment]");
        const auto k = static_cast<float>(r.number("intensity", 1.0, kNonNegative));
        const ecs::Entity env = registry.create();
        registry.put(env, parse_light_group(r, info.light_groups));
        if (r.has("map")) {
            if (r.has("color"))
                throw_error(r.loc("color"),
                            "give either 'color' or 'map' in [environment], not both");
            EnvironmentMapFile m;
            m.path = resolve_file(ctx, r, "map");
            m.loc = r.loc("map");
            m.color_space =
                r.has("color_space")
                    ? resolve_space(ctx, r.string("color_space"), r.loc("color_space"))
                    : resolve_space(ctx, "lin_rec709", r.loc(), "default (no key written) ");
            m.rotation_deg = static_cast<float>(r.number("rotation", 0.0, {-360.0, 360.0}));
            m.intensity = k;
            r.finish();
            registry.put(env, m);
        } else {
            const Vec3 c = read_color(ctx, r, "color", {0, 0, 0});
            r.finish();
            registry.put(env, Environment{c * k});
        }
    }

    if (const toml::array* mats = top.table_array("material")) {
        for (std::size_t i = 0; i < mats->size(); ++i) {
            TableReader r(*(*mats)[i].as_table(), path, fmt::format("[[material]] #{}", i + 1));
            Material m = parse_material(ctx, r);
            r.finish();
            for (const auto& existing : info.material_names)
                if (existing == m.name)
                    throw_error(r.loc("name"), "material '{}' is defined twice", m.name);
            info.material_names.push_back(m.name);
            registry.put(registry.create(), m);
        }
    }

    if (const toml::array* objs = top.table_array("object")) {
        for (std::size_t i = 0; i < objs->size(); ++i) {
            TableReader r(*(*objs)[i].as_table(), path, fmt::format("[[object]] #{}", i + 1));
            const ecs::Entity e = registry.create();
            registry.put(e, ObjectInfo{r.string("name", ""), r.loc(), static_cast<uint32_t>(i)});
            const std::string mesh_path = resolve_file(ctx, r, "mesh");
            if (const toml::table* sub = r.table("subdiv"))
                registry.put(e, parse_subdiv(ctx, *sub, mesh_path, r.loc("mesh")));
            else
                registry.put(e, MeshFile{mesh_path, r.loc("mesh")});
            const std::string mat = r.string("material");
            uint32_t index = 0;
            while (index < info.material_names.size() && info.material_names[index] != mat) ++index;
            if (index == info.material_names.size())
                throw_error(r.loc("material"), "unknown material '{}' (defined: {})", mat,
                            info.material_names.empty()
                                ? std::string("none")
                                : fmt::format("{}", fmt::join(info.material_names, ", ")));
            registry.put(e, MaterialRef{index});
            const TransformParts base = parse_transform_parts(r);
            std::optional<Motion> blur;  // its motion while the shutter is open
            Affine placement = base.compose();
            if (const toml::array* keys = r.table_array("keys")) {
                // Keyframed placement: each key's scale, rotate, translate default to the
                // object's own.
                Track track;
                track.smooth = smooth_interpolation(r);
                for (std::size_t k = 0; k < keys->size(); ++k) {
                    TableReader kr(*(*keys)[k].as_table(), path,
                                   fmt::format("[[object.keys]] #{} of {}", k + 1, r.what()));
                    const double t = key_time(kr, info);
                    const TransformParts p = parse_transform_parts(kr, base);
                    kr.finish();
                    add_key(track, t,
                            {p.scale.x, p.scale.y, p.scale.z, p.rotate.x, p.rotate.y, p.rotate.z,
                             p.translate.x, p.translate.y, p.translate.z},
                            kr);
                }
                // The placement at time t; Transform is the one at the shutter's middle.
                const auto placement_at = [&](double t) {
                    const std::vector<double> v = evaluate(track, t);
                    const auto f = [&](std::size_t j) { return static_cast<float>(v[j]); };
                    TransformParts now{{f(0), f(1), f(2)}, {f(3), f(4), f(5)}, {f(6), f(7), f(8)}};
                    for (int a = 0; a < 3; ++a)
                        if (!(std::fabs(f(static_cast<std::size_t>(a))) >= 1e-8f))
                            throw_error(r.loc("keys"),
                                        "{}: the keyframed scale passes through 0 at {} s (the "
                                        "object would vanish into a plane)",
                                        r.what(), t);
                    return now.compose();
                };
                placement = placement_at(shutter_middle(info));
                if (info.shutter_open < info.shutter_close) {
                    // Straight enough: the linear part strays from the straight line by under
                    // 2.5e-4 of its size (a rotation cut into steps of about 2.5 degrees), the
                    // translation by under 1% of how far it moves.
                    const auto close = [](const Affine& ma, const Affine& mb, const Affine& mm,
                                          float q) {
                        float size = 0.0f;
                        for (int row = 0; row < 3; ++row)
                            for (int j = 0; j < 3; ++j)
                                size = std::max(
                                    {size, std::fabs(ma.m[row][j]), std::fabs(mb.m[row][j])});
                        for (int row = 0; row < 3; ++row)
                            for (int j = 0; j < 3; ++j)
                                if (std::fabs(mm.m[row][j] -
                                              (ma.m[row][j] + (mb.m[row][j] - ma.m[row][j]) * q)) >
                                    2.5e-4f * size)
                                    return false;
                        return length(mm.t - (ma.t + (mb.t - ma.t) * q)) <=
                               0.01f * length(mb.t - ma.t) + 1e-6f * length(mm.t);
                    };
                    std::vector<Affine> steps =
                        motion_steps(shutter_time(info, info.shutter_open),
                                     shutter_time(info, info.shutter_close), placement_at, close,
                                     [](const Affine& x, const Affine& y) { return x == y; });
                    if (!steps.empty()) blur = Motion{std::move(steps)};  // unless it emits (below)
                }
                info.animated = true;
            } else if (r.has("interpolation")) {
                smooth_interpolation(r);
            }
            registry.put(e, Transform{placement});
            info.object_to_world.push_back(placement);
            if (r.has("emission")) {
                const Vec3 le =
                    read_color(ctx, r, "emission", {0, 0, 0}) *
                    static_cast<float>(r.number("emission_intensity", 1.0, kNonNegative));
                if (max_component(le) > 0.0f) registry.put(e, Emission{le});
                registry.put(e, parse_light_group(r, info.light_groups));
            }
            if (blur && registry.has<Emission>(e)) {
                info.notes.push_back(fmt::format(
                    "{}: {} moves while the shutter is open but emits light: it is not blurred "
                    "(lights are placed at the shutter's middle)",
                    r.loc("keys").str(), r.what()));
            } else if (blur) {
                registry.put(e, std::move(*blur));
                info.motion_blur = true;
            }
            r.finish();
        }
    }

    if (const toml::array* lights = top.table_array("light")) {
        for (std::size_t i = 0; i < lights->size(); ++i) {
            TableReader r(*(*lights)[i].as_table(), path, fmt::format("[[light]] #{}", i + 1));
            parse_light(ctx, r, registry, info.light_groups);
            r.finish();
        }
    }
    top.finish();
    return info;
}

}  // namespace spangle
