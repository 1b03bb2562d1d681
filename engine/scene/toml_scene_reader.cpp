#include "scene/toml_scene_reader.h"

#include <cmath>
#include <utility>

#include "scene/frame_sequence.h"
#include "scene/scene_paths.h"
#include "scene/toml_scene_parts.h"

namespace spangle {

namespace {

using toml_scene::kNonNegative;
using toml_scene::ReadContext;

/** The file named by `key`, relative to the scene's folder, checked to exist. */
std::string read_file(const ReadContext& ctx, TableReader& r, std::string_view key) {
    return find_scene_file(r.string(key), ctx.dir, key, r.loc(key));
}

/** `key = [x0, x1, y0, y1]`: four finite numbers (a window; the builder checks its order and
 *  range); none when absent. */
std::optional<std::array<double, 4>> read_window(TableReader& r, std::string_view key) {
    const toml::node* n = r.node(key);
    if (!n) return std::nullopt;
    std::vector<double> v;
    if (!toml_scene::finite_numbers(*n, 4, v))
        throw_error(loc_of(*n, r.file()), "'{}' must be 4 finite numbers: x0, x1, y0, y1", key);
    return std::array<double, 4>{v[0], v[1], v[2], v[3]};
}

/** The [render] table (or an empty one). */
RenderDesc read_render(TableReader& r) {
    RenderDesc d;
    d.loc = r.loc();
    if (r.has("working_space")) {
        d.working_space = r.string("working_space");
        d.working_space_loc = r.loc("working_space");
    }
    if (r.has("color_space")) {
        d.color_space = r.string("color_space");
        d.color_space_loc = r.loc("color_space");
    }
    if (r.has("width") || r.has("height")) d.size_loc = r.loc(r.has("width") ? "width" : "height");
    d.width = static_cast<uint32_t>(r.integer("width", d.width, {1, 16384}));
    d.height = static_cast<uint32_t>(r.integer("height", d.height, {1, 16384}));
    if (r.has("spp")) d.spp_loc = r.loc("spp");
    d.spp = static_cast<uint32_t>(r.integer("spp", d.spp, {1, 1 << 20}));
    d.max_depth = static_cast<uint32_t>(r.integer("max_depth", d.max_depth, {1, 1024}));
    d.rr_depth = static_cast<uint32_t>(r.integer("rr_depth", d.rr_depth, {1, 1024}));
    d.seed = static_cast<uint64_t>(r.integer("seed", 0, {0, 9.0e18}));
    const std::string filter = r.string("filter", "gaussian");
    d.clamp_indirect = static_cast<float>(r.number("clamp_indirect", 0.0, {0.0, 1e30}));
    d.filter_glossy = static_cast<float>(r.number("filter_glossy", 0.0, {0.0, 100.0}));
    const double threshold = r.number("noise_threshold", 0.0, {0.0, 1.0});
    if (const std::string why = noise_threshold_problem(threshold); !why.empty())
        throw_error(r.loc("noise_threshold"), "noise_threshold {}", why);
    d.noise_threshold = static_cast<float>(threshold);
    if (r.has("noise_threshold")) d.noise_threshold_loc = r.loc("noise_threshold");
    // 0 is not a count a pixel can take (left out, they default: 16, and spp).
    d.min_spp = static_cast<uint32_t>(r.integer("min_spp", 0, {1, 1 << 20}));
    d.max_spp = static_cast<uint32_t>(r.integer("max_spp", 0, {1, 1 << 20}));
    d.transparent_background = r.boolean("transparent_background", false);
    if (d.min_spp > 0 && d.max_spp > 0 && d.min_spp > d.max_spp)
        throw_error(r.loc("min_spp"), "min_spp = {} is more than max_spp = {}", d.min_spp,
                    d.max_spp);
    if (d.min_spp > 0 && d.max_spp == 0 && d.min_spp > d.spp)
        throw_error(r.loc("min_spp"), "min_spp = {} is more than spp = {} (the most a pixel takes)",
                    d.min_spp, d.spp);
    if (!parse_filter(filter, d.filter))
        throw_error(r.loc("filter"), "unknown filter '{}' (valid: box, gaussian, blackman-harris)",
                    filter);
    // A filter's reach in pixels (Cycles' Blackman-Harris of width 1.5 is radius 1.5 here).
    d.filter_radius = static_cast<float>(r.number("filter_radius", 0.0, {0.05, 8.0}));
    // Whose samples a pixel's filter weighs: its own, drawn where the filter weighs most, or
    // every pixel's within its reach (docs/adaptive.md, "Shared samples").
    const std::string samples = r.string("filter_samples", "own");
    if (samples != "own" && samples != "shared")
        throw_error(r.loc("filter_samples"), "unknown filter_samples '{}' (valid: own, shared)",
                    samples);
    d.filter_shared = samples == "shared";
    d.frame_start = r.integer("frame_start", d.frame_start, {-1e9, 1e9});
    d.frame_end = r.integer("frame_end", d.frame_start, {static_cast<double>(d.frame_start), 1e9});
    d.fps = r.number("fps", d.fps, {0.0, 1e6, true});
    if (const toml::node* n = r.node("shutter")) {
        float open = 0.0f, close = 0.0f;
        if (!toml_scene::two_numbers(*n, open, close) || !std::isfinite(open) ||
            !std::isfinite(close))
            throw_error(loc_of(*n, r.file()),
                        "'shutter' must be [open, close]: two numbers, in frames from the "
                        "frame's time (e.g. [-0.25, 0.25] for a 180-degree shutter centred "
                        "on the frame)");
        if (!(open <= close) || !(std::fabs(open) <= 16.0f && std::fabs(close) <= 16.0f))
            throw_error(loc_of(*n, r.file()),
                        "'shutter' = [{}, {}]: open must not come after close, and both "
                        "must lie within 16 frames of the frame",
                        open, close);
        d.shutter_open = open;
        d.shutter_close = close;
    }
    d.crop = read_window(r, "crop_window");
    d.crop_loc = r.loc("crop_window");
    // The image the scene asks for when -o gives none (pbrt's Film "filename", which `spangle
    // convert` writes here): relative to the working folder, as pbrt's.
    if (r.has("output")) {
        d.output = r.string("output");
        d.output_loc = r.loc("output");
        if (d.output->empty() || d.output->back() == '/')
            throw_error(r.loc("output"), "'output' must name an image file, got \"{}\"", *d.output);
    }
    r.finish();
    return d;
}

/** The time of one key: `time` in seconds, or `frame` (a frame number of [render]). */
KeyTime read_key_time(TableReader& r) {
    const bool has_time = r.has("time"), has_frame = r.has("frame");
    if (has_time == has_frame)
        throw_error(r.loc(), "{} needs exactly one of 'time' (seconds) or 'frame'", r.what());
    KeyTime t;
    if (has_time)
        t.seconds = r.number("time", {-1e9, 1e9});
    else
        t.frame = r.integer("frame", 0, {-1e9, 1e9});
    return t;
}

/** `interpolation = "smooth" | "linear"` of an animated table. */
bool read_interpolation(TableReader& r) {
    const std::string how = r.string("interpolation", "smooth");
    if (how != "smooth" && how != "linear")
        throw_error(r.loc("interpolation"),
                    "'interpolation' must be \"smooth\" or \"linear\", got \"{}\"", how);
    return how == "smooth";
}

/** A 3-vector under `key`, or none when absent. */
std::optional<Vec3> optional_vec3(TableReader& r, std::string_view key) {
    if (!r.has(key)) return std::nullopt;
    return r.vec3(key);
}

/** The `keys` of an animated table and its interpolation (checked when there are no keys
 *  too); `read_key(kr)` reads one key's table, `name(k)` is what messages call the k-th (from
 *  1). */
template <class Key, class ReadKey, class Name>
Keys<Key> read_keys(TableReader& r, const Name& name, const ReadKey& read_key) {
    Keys<Key> out;
    if (const toml::array* keys = r.table_array("keys")) {
        out.loc = r.loc("keys");
        out.smooth = read_interpolation(r);
        for (std::size_t k = 0; k < keys->size(); ++k) {
            TableReader kr(*(*keys)[k].as_table(), r.file(), name(k + 1));
            Key key = read_key(kr);
            key.loc = kr.loc();
            key.what = kr.what();
            kr.finish();
            out.keys.push_back(std::move(key));
        }
    } else if (r.has("interpolation")) {
        read_interpolation(r);
    }
    return out;
}

/** The [camera] table and its keys. */
CameraDesc read_camera(TableReader& r) {
    CameraDesc c;
    c.loc = r.loc();
    const bool focus_given = r.has("focus_distance");
    c.position = r.vec3("position");
    c.look_at = r.vec3("look_at");
    c.look_at_loc = r.loc("look_at");
    c.up = r.vec3("up", c.up);
    c.up_loc = r.loc("up");
    // "perspective" (the default), "orthographic" (with ortho_height; ortho_height alone also
    // makes one) or "equirectangular".
    std::string projection = "perspective";
    if (r.has("projection")) {
        projection = r.string("projection");
        if (projection != "perspective" && projection != "orthographic" &&
            projection != "equirectangular")
            throw_error(r.loc("projection"),
                        "'projection' must be \"perspective\", \"orthographic\" or "
                        "\"equirectangular\", got \"{}\"",
                        projection);
        if (projection == "orthographic" && !r.has("ortho_height"))
            throw_error(r.loc("projection"),
                        "an orthographic camera needs 'ortho_height' (the view's height in scene "
                        "units)");
        if (projection != "orthographic" && r.has("ortho_height"))
            throw_error(r.loc("ortho_height"),
                        "'ortho_height' is an orthographic camera's, not a{} {} one's",
                        projection == "perspective" ? "" : "n", projection);
    }
    c.equirect = projection == "equirectangular";
    if (c.equirect)
        for (const char* key : {"fov", "fov_axis", "screen_window", "aperture", "focus_distance"})
            if (r.has(key))
                throw_error(r.loc(key),
                            "'{}' is not for an equirectangular camera: it sees every direction "
                            "from its position (360 degrees across the image, 180 up it) through "
                            "a pinhole",
                            key);
    if (r.has("ortho_height")) {
        if (r.has("fov"))
            throw_error(r.loc("fov"),
                        "'fov' and 'ortho_height' are both given: an orthographic camera "
                        "(ortho_height, the view's height in scene units) has no field of view");
        c.ortho_height = r.number("ortho_height", {0.0, 2e13, true});
    }
    c.fov_deg = r.number("fov", c.fov_deg, {0.0, 180.0, true, true});
    // "vertical" (the default) or "shorter": the image's shorter side, as pbrt takes fov.
    if (r.has("fov_axis")) {
        const std::string axis = r.string("fov_axis");
        if (axis != "vertical" && axis != "shorter")
            throw_error(r.loc("fov_axis"),
                        "'fov_axis' must be \"vertical\" or \"shorter\", got "
                        "\"{}\"",
                        axis);
        c.fov_shorter = axis == "shorter";
    }
    c.aperture = r.number("aperture", c.aperture, {0.0, 1e3});
    if (focus_given) c.focus_distance = r.number("focus_distance", {0.0, 1e30, true});
    c.mirror = r.boolean("mirror", c.mirror);
    c.screen = read_window(r, "screen_window");
    c.screen_loc = r.loc("screen_window");
    const auto name = [](std::size_t k) { return fmt::format("[[camera.keys]] #{}", k); };
    c.keys = read_keys<CameraKey>(r, name, [&c](TableReader& kr) {
        CameraKey key;
        key.time = read_key_time(kr);
        key.position = optional_vec3(kr, "position");
        key.look_at = optional_vec3(kr, "look_at");
        key.up = optional_vec3(kr, "up");
        if (kr.has("fov")) {
            if (c.ortho_height > 0.0 || c.equirect)
                throw_error(
                    kr.loc("fov"), "an {} has no field of view to key",
                    c.equirect ? "equirectangular camera" : "orthographic camera (ortho_height)");
            key.fov_deg = kr.number("fov", {0.0, 180.0, true, true});
        }
        return key;
    });
    r.finish();
    return c;
}

/** `light_group = "name"` (checked by the builder). */
LightGroupDesc read_light_group(TableReader& r) {
    LightGroupDesc g;
    g.name = r.string("light_group", g.name);
    g.loc = r.loc("light_group");
    return g;
}

std::optional<Affine> read_matrix(TableReader& r, std::string_view key);

/** The [environment] table: a colour or a map. */
EnvironmentDesc read_environment(const ReadContext& ctx, TableReader& r) {
    EnvironmentDesc e;
    e.loc = r.loc();
    e.intensity = r.number("intensity", e.intensity, kNonNegative);
    e.group = read_light_group(r);
    if (r.has("map")) {
        if (r.has("color"))
            throw_error(r.loc("color"), "give either 'color' or 'map' in [environment], not both");
        EnvironmentDesc::Map m;
        m.path = read_file(ctx, r, "map");
        m.loc = r.loc("map");
        if (r.has("color_space")) {
            m.color_space = r.string("color_space");
            m.color_space_loc = r.loc("color_space");
        }
        m.rotation_deg = r.number("rotation", m.rotation_deg, {-360.0, 360.0});
        // pbrt's layouts, as `spangle convert` writes a pbrt scene's map: the projection and the
        // map's frame (a matrix, map to world).
        const std::string projection = r.string("projection", "latlong");
        if (projection == "latlong_z_up")
            m.projection = MapProjection::LatLongZUp;
        else if (projection == "equal_area")
            m.projection = MapProjection::EqualArea;
        else if (projection != "latlong")
            throw_error(r.loc("projection"),
                        "unknown projection '{}' (valid: latlong, latlong_z_up, equal_area)",
                        projection);
        if (const std::optional<Affine> frame = read_matrix(r, "frame")) {
            // (Taken without a word and ignored: Spangle's own layout is turned by 'rotation'.)
            if (m.projection == MapProjection::LatLongYUp)
                throw_error(r.loc("frame"),
                            "'frame' places a map of projection \"latlong_z_up\" or "
                            "\"equal_area\" (pbrt's layouts); a \"latlong\" map is turned by "
                            "'rotation'");
            m.to_world = *frame;
        }
        e.map = std::move(m);
    } else {
        // The map's own keys without a map: said as such (they were "unknown keys", though the
        // README lists them).
        for (const char* key : {"color_space", "rotation", "projection", "frame"})
            if (r.has(key))
                throw_error(r.loc(key), "'{}' applies to an environment 'map'; this one has none",
                            key);
        e.color = toml_scene::read_color(ctx, r, "color");
    }
    r.finish();
    return e;
}

/** An object's or a key's `scale`: one number or [x, y, z], each within 1e-8..1e8 in size. */
std::optional<Vec3> read_scale(TableReader& r) {
    const toml::node* s = r.node("scale");
    if (!s) return std::nullopt;
    Vec3 v;
    if (s->is_number())
        v = Vec3(static_cast<float>(s->value<double>().value_or(0.0)));
    else
        v = parse_vec3(*s, r.file(), "scale");
    // Rays are carried into object space by the inverse scale, in floats: beyond 1e8 either way
    // they overflow or lose every bit of precision (1e-20 sent non-finite rays).
    const auto in_range = [](float k) {
        return std::isfinite(k) && std::fabs(k) >= 1e-8f && std::fabs(k) <= 1e8f;
    };
    if (!in_range(v.x) || !in_range(v.y) || !in_range(v.z))
        throw_error(loc_of(*s, r.file()),
                    "'scale' must be between 1e-8 and 1e8 in size in every axis, got [{}, {}, "
                    "{}] (model in other units instead)",
                    v.x, v.y, v.z);
    return v;
}

/** `key = [...]` (by default `matrix`): 12 numbers, the rows of a 3x4 object-to-world matrix,
 *  or 16, a 4x4 one whose last row is 0 0 0 1 (as `spangle convert` writes placements that are
 *  no scale, rotate and translate); none when absent. */
std::optional<Affine> read_matrix(TableReader& r, std::string_view key) {
    const toml::node* n = r.node(key);
    if (!n) return std::nullopt;
    const auto fail = [&]() {
        throw_error(loc_of(*n, r.file()),
                    "'{}' must be 12 numbers (the rows of a 3x4 object-to-world matrix) or 16 (a "
                    "4x4 one with last row 0, 0, 0, 1)",
                    key);
    };
    std::vector<double> v;
    if (!toml_scene::finite_numbers(*n, 12, v, 16)) {
        // Of the right length: the entry that is no finite number, where it is (twelve entries
        // with a nan among them were told to be twelve numbers).
        if (const toml::array* arr = n->as_array(); arr && (arr->size() == 12 || arr->size() == 16))
            for (std::size_t i = 0; i < arr->size(); ++i) {
                const toml::node& x = (*arr)[i];
                const auto d = x.value<double>();
                if (!x.is_number())
                    throw_error(loc_of(x, r.file()), "'{}' entry {} must be a number, got {}", key,
                                i + 1, toml_type_name(x));
                if (!d || !std::isfinite(*d))
                    throw_error(loc_of(x, r.file()), "'{}' entry {} must be finite, got {}", key,
                                i + 1, d ? *d : 0.0);
            }
        fail();
    }
    if (v.size() == 16 && !(v[12] == 0 && v[13] == 0 && v[14] == 0 && v[15] == 1)) fail();
    Affine m;
    for (int row = 0; row < 3; ++row) {
        for (int c = 0; c < 3; ++c) m.m[row][c] = static_cast<float>(v[4 * row + c]);
    }
    m.t = {static_cast<float>(v[3]), static_cast<float>(v[7]), static_cast<float>(v[11])};
    const float det = m.determinant();
    if (!(std::fabs(det) > 1e-30f) || !std::isfinite(det)) {
        // In double: an invertible matrix whose determinant a float under- or overflows (a
        // uniform 1e-20 was "not invertible (determinant 0)", 1e30 "determinant inf") is said by
        // its scale; a flat one (dependent columns) as not invertible.
        double len[3];
        for (int c = 0; c < 3; ++c)
            len[c] = std::sqrt(v[c] * v[c] + v[4 + c] * v[4 + c] + v[8 + c] * v[8 + c]);
        const double det_d = v[0] * (v[5] * v[10] - v[6] * v[9]) -
                             v[1] * (v[4] * v[10] - v[6] * v[8]) +
                             v[2] * (v[4] * v[9] - v[5] * v[8]);
        const double volume = len[0] * len[1] * len[2];
        if (std::isfinite(det_d) && volume > 0.0 && std::isfinite(volume) &&
            std::fabs(det_d) > 1e-6 * volume)
            throw_error(
                loc_of(*n, r.file()),
                "'{}' scales its axes by {:.3g}, {:.3g} and {:.3g}: beyond what single "
                "precision holds (its determinant {:.3g} is {}); model in other units "
                "instead",
                key, len[0], len[1], len[2], det_d,
                std::fabs(det_d) < 1.0 ? "below the 1e-30 it takes" : "beyond a float's range");
        throw_error(loc_of(*n, r.file()),
                    "'{}' is not invertible (determinant {}): it flattens the object onto a "
                    "plane, a line or a point",
                    key, det);
    }
    return m;
}

/** A placement: `matrix`, or scale, rotate and translate (not both). */
PlacementDesc read_placement(TableReader& r) {
    PlacementDesc p;
    p.matrix = read_matrix(r, "matrix");
    if (p.matrix) {
        for (const char* key : {"scale", "rotate", "translate"})
            if (r.has(key))
                throw_error(r.loc(key),
                            "give either 'matrix' or scale, rotate and translate, "
                            "not both");
        return p;
    }
    TransformParts& parts = p.parts;
    parts.scale = read_scale(r).value_or(parts.scale);
    parts.rotate = r.vec3("rotate", parts.rotate);
    parts.translate = r.vec3("translate", parts.translate);
    return p;
}

/** The `subdiv = { ... }` table's scheme, boundary and uv interpolation. */
void read_subdiv_rules(TableReader& r, SubdivOptions& o) {
    const std::string scheme = r.string("scheme", "catmull-clark");
    if (scheme == "catmull-clark")
        o.scheme = SubdivOptions::Scheme::CatmullClark;
    else if (scheme == "loop")
        o.scheme = SubdivOptions::Scheme::Loop;
    else
        throw_error(r.loc("scheme"), "unknown scheme '{}' (valid: catmull-clark, loop)", scheme);
    const std::string boundary = r.string("boundary", "edge_and_corner");
    if (boundary == "none")
        o.boundary = SubdivOptions::Boundary::None;
    else if (boundary == "edge_only")
        o.boundary = SubdivOptions::Boundary::EdgeOnly;
    else if (boundary == "edge_and_corner")
        o.boundary = SubdivOptions::Boundary::EdgeAndCorner;
    else
        throw_error(r.loc("boundary"),
                    "unknown boundary '{}' (valid: none, edge_only, edge_and_corner)", boundary);
    const std::string uv = r.string("uv_interpolation", "corners_only");
    if (uv == "smooth")
        o.uv_interpolation = SubdivOptions::UvInterpolation::Smooth;
    else if (uv == "corners_only")
        o.uv_interpolation = SubdivOptions::UvInterpolation::CornersOnly;
    else if (uv == "boundaries")
        o.uv_interpolation = SubdivOptions::UvInterpolation::Boundaries;
    else if (uv == "all")
        o.uv_interpolation = SubdivOptions::UvInterpolation::All;
    else
        throw_error(r.loc("uv_interpolation"),
                    "unknown uv_interpolation '{}' (valid: smooth, corners_only, boundaries, all)",
                    uv);
}

/** `key = [[v0, ..., sharpness], ...]` of a subdiv table: each entry `width` numbers, vertex
 *  indices first; `take` gets each entry. */
template <class Take>
void read_sharp_list(const ReadContext& ctx, TableReader& r, const char* key, std::size_t width,
                     const Take& take) {
    const toml::node* n = r.node(key);
    if (!n) return;
    const toml::array* arr = n->as_array();
    if (!arr) throw_error(loc_of(*n, ctx.file), "'{}' must be an array of arrays", key);
    for (const toml::node& e : *arr) {
        const toml::array* item = e.as_array();
        if (!item || item->size() != width)
            throw_error(loc_of(e, ctx.file), "each entry of '{}' must be an array of {} numbers",
                        key, width);
        std::vector<double> v;
        for (const toml::node& x : *item) {
            if (!x.is_number())
                throw_error(loc_of(x, ctx.file), "'{}' entries must be numbers", key);
            v.push_back(x.value<double>().value_or(0.0));
        }
        for (std::size_t k = 0; k + 1 < width; ++k)
            if (!(v[k] >= 0 && v[k] <= 2147483647.0) || v[k] != std::floor(v[k]))
                throw_error(loc_of(e, ctx.file),
                            "'{}' vertex indices must be integers in 0..2147483647, got {}", key,
                            v[k]);
        if (!(v[width - 1] >= 0.0 && v[width - 1] <= 10.0))
            throw_error(loc_of(e, ctx.file), "'{}' sharpness must be in [0, 10], got {}", key,
                        v[width - 1]);
        take(v);
    }
}

/** The `subdiv = { ... }` table of an object whose cage is `path`, named at `loc`. */
SubdivShape read_subdiv(const ReadContext& ctx, const toml::table& t, std::string path,
                        FileLoc loc) {
    TableReader r(t, ctx.file, "subdiv");
    SubdivShape s;
    s.path = std::move(path);
    s.loc = std::move(loc);
    read_subdiv_rules(r, s.options);
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
    s.max_level = static_cast<int>(r.integer("max_level", s.max_level, {0, 8}));
    // Below a thousandth of a pixel every edge would ask for the deepest level anyway.
    s.pixel_budget = static_cast<float>(r.number("pixel_budget", 2.0, {1e-3, 1e6}));
    SubdivOptions& o = s.options;
    read_sharp_list(ctx, r, "creases", 3, [&](const std::vector<double>& v) {
        o.crease_vertices.push_back(static_cast<int>(v[0]));
        o.crease_vertices.push_back(static_cast<int>(v[1]));
        o.crease_sharpness.push_back(static_cast<float>(v[2]));
    });
    read_sharp_list(ctx, r, "corners", 2, [&](const std::vector<double>& v) {
        o.corner_vertices.push_back(static_cast<int>(v[0]));
        o.corner_sharpness.push_back(static_cast<float>(v[1]));
    });
    r.finish();
    return s;
}

/** `mesh`: a file, checked to exist, or a sequence's pattern (a run of '#' in the file name,
 *  scene/frame_sequence.h) made absolute, whose files the builder checks frame by frame. */
std::string read_mesh_path(const ReadContext& ctx, TableReader& r, bool& sequence) {
    const std::string given = r.string("mesh");
    const FrameRun run = find_frame_run(given);
    sequence = run.count > 0;
    if (!sequence) return find_scene_file(given, ctx.dir, "mesh", r.loc("mesh"));
    if (run.several)
        throw_error(r.loc("mesh"),
                    "'mesh' = \"{}\" has more than one run of '#' in its file name: a sequence "
                    "numbers its frames with one run (e.g. \"body.####.ply\")",
                    given);
    std::filesystem::path p(given);
    if (p.is_relative()) p = ctx.dir / p;
    return std::filesystem::absolute(p).lexically_normal().string();
}

/** An object's shape: a mesh file or sequence, or a cage or cage sequence (`subdiv`), with its
 *  rest pose (`rest_mesh`). */
ShapeDesc read_shape(const ReadContext& ctx, TableReader& r) {
    bool sequence = false;
    std::string mesh_path = read_mesh_path(ctx, r, sequence);
    std::string rest_path;
    if (r.has("rest_mesh")) rest_path = read_file(ctx, r, "rest_mesh");
    if (const toml::table* sub = r.table("subdiv")) {
        SubdivShape s = read_subdiv(ctx, *sub, std::move(mesh_path), r.loc("mesh"));
        s.sequence = sequence;
        s.rest_path = std::move(rest_path);
        s.rest_loc = r.loc("rest_mesh");
        return s;
    }
    return MeshFileShape{std::move(mesh_path), r.loc("mesh"), sequence, std::move(rest_path),
                         r.loc("rest_mesh")};
}

/** One [[object]] table: its mesh or cage, material, placement, keys and emission. */
ObjectDesc read_object(const ReadContext& ctx, TableReader& r) {
    ObjectDesc o;
    o.loc = r.loc();
    o.name = r.string("name", "");
    // Messages name the object as the file does: "[[object]] #3 'body'".
    o.what = o.name.empty() ? r.what() : fmt::format("{} '{}'", r.what(), o.name);
    o.shape = read_shape(ctx, r);
    o.material = r.string("material");
    o.material_loc = r.loc("material");
    o.placement = read_placement(r);
    o.parent = read_matrix(r, "import_matrix");
    o.shadow_catcher = r.boolean("shadow_catcher", false);
    const auto name = [&](std::size_t k) {
        return fmt::format("[[object.keys]] #{} of {}", k, r.what());
    };
    // Keys of the parts, or (an object placed by a matrix) keys of whole matrices.
    if (o.placement.matrix) {
        o.matrix_keys = read_keys<MatrixKey>(r, name, [](TableReader& kr) {
            MatrixKey key;
            key.time = read_key_time(kr);
            const std::optional<Affine> m = read_matrix(kr, "matrix");
            if (!m) kr.missing("matrix");
            key.matrix = *m;
            return key;
        });
        // From a mirrored placement to one that is not (or back), the interpolated matrices
        // pass through a flat one: the object would vanish in between (as scale keys through 0,
        // refused alike). (Imported animations keep their own rule: a glTF scale through 0 is
        // the spec's.)
        const auto& mk = o.matrix_keys.keys;
        for (std::size_t k = 1; k < mk.size(); ++k) {
            const float d0 = mk[k - 1].matrix.determinant(), d1 = mk[k].matrix.determinant();
            if ((d0 < 0.0f) != (d1 < 0.0f))
                throw_error(mk[k].loc,
                            "{}: its matrix {} and the key's before {} (determinants {:.4g} "
                            "and {:.4g}): in between the object would pass through flat; key a "
                            "mirrored object mirrored at every key",
                            mk[k].what, d1 < 0.0f ? "mirrors" : "does not mirror",
                            d1 < 0.0f ? "does not" : "does", d1, d0);
        }
        // Matrices interpolate linearly (decomposed); an explicit "smooth" would be ignored.
        if (!o.matrix_keys.keys.empty() && r.has("interpolation") && o.matrix_keys.smooth)
            throw_error(r.loc("interpolation"),
                        "{}: keys of whole matrices interpolate linearly (decomposed into "
                        "rotation, stretch and translation); interpolation = \"smooth\" is for "
                        "keys of scale, rotate and translate",
                        r.what());
    } else {
        o.keys = read_keys<ObjectKey>(r, name, [](TableReader& kr) {
            ObjectKey key;
            key.time = read_key_time(kr);
            key.scale = read_scale(kr);
            key.rotate = optional_vec3(kr, "rotate");
            key.translate = optional_vec3(kr, "translate");
            return key;
        });
    }
    if (r.has("emission")) {
        EmissionDesc e;
        // A colour, or an image: `emission = { texture = "screen.png", scale = ... }`.
        const toml::node* en = r.node("emission");
        const toml::table* et = en ? en->as_table() : nullptr;
        if (et && !et->contains("texture") && !et->contains("rgb") && !et->contains("vertex_color"))
            throw_error(r.loc("emission"),
                        "'emission' is a colour ([r, g, b] or {{ rgb = [r, g, b], space = ... }}) "
                        "or an image {{ texture = \"file\", ... }}");
        if (et && et->contains("vertex_color"))
            throw_error(r.loc("emission"),
                        "'emission' is a colour or {{ texture = \"file\", ... }}: vertex colours "
                        "are for material parameters");
        if (const toml::table* t = et; t && t->contains("texture")) {
            e.texture = toml_scene::read_color_texture(ctx, *t, "emission");
            // White (the image's own colours), in the space glTF's importer names for it.
            e.color = ColorDesc{
                {1, 1, 1}, std::string("lin_rec709"), r.loc("emission"), r.loc("emission")};
        } else {
            e.color = *toml_scene::read_color(ctx, r, "emission");
        }
        e.intensity = r.number("emission_intensity", e.intensity, kNonNegative);
        e.two_sided = r.boolean("emission_two_sided", e.two_sided);
        e.group = read_light_group(r);
        o.emission = std::move(e);
    } else {
        // Keys of an emitting object on one that does not emit: say what is missing (they were
        // "unknown key ... did you mean 'emission'?").
        for (const char* k : {"emission_intensity", "emission_two_sided", "light_group"})
            if (r.has(k))
                throw_error(r.loc(k),
                            "'{}' is for an object that emits: give it 'emission' (the emitted "
                            "radiance, RGB) too",
                            k);
    }
    r.finish();
    return o;
}

/** The fields of a [[light]] table of type `type`. */
LightShapeDesc read_light_shape(TableReader& r, const std::string& type) {
    if (type == "quad") {
        QuadLightDesc q;
        q.corner = r.vec3("corner");
        q.edge1 = r.vec3("edge1");
        q.edge2 = r.vec3("edge2");
        q.edge2_loc = r.loc("edge2");
        q.two_sided = r.boolean("two_sided", q.two_sided);
        q.transparent = r.boolean("transparent", q.transparent);
        return q;
    }
    if (type == "sphere") {
        SphereLightDesc s;
        s.center = r.vec3("center");
        s.radius = r.number("radius", {0.0, 1e30, true});
        return s;
    }
    if (type == "point") return PointLightDesc{r.vec3("position")};
    if (type == "spot") {
        SpotLightDesc s;
        s.position = r.vec3("position");
        s.look_at = r.vec3("look_at");
        s.look_at_loc = r.loc("look_at");
        s.cone_angle = r.number("cone_angle", s.cone_angle, {0.0, 90.0, true, false});
        s.cone_falloff = r.number("cone_falloff", s.cone_falloff, {0.0, 90.0});
        s.cone_falloff_loc = r.loc("cone_falloff");
        if (r.has("falloff")) {
            const std::string f = r.string("falloff");
            if (f != "smoothstep" && f != "quartic")
                throw_error(r.loc("falloff"),
                            "'falloff' must be \"smoothstep\" or \"quartic\", got \"{}\"", f);
            s.quartic = f == "quartic";
        }
        return s;
    }
    if (type == "distant") {
        DistantLightDesc d;
        d.direction = r.vec3("direction");
        d.direction_loc = r.loc("direction");
        d.angular_radius_deg = r.number("angular_radius", 0.0, {0.0, 45.0});
        return d;
    }
    throw_error(r.loc("type"),
                "unknown light type '{}' (valid: quad, sphere, point, spot, distant)", type);
}

/** One [[light]] table of any type. */
LightDesc read_light(const ReadContext& ctx, TableReader& r) {
    LightDesc l;
    l.loc = r.loc();
    const std::string type = r.string("type");
    l.color = toml_scene::read_color(ctx, r, "color");
    l.intensity = r.number("intensity", l.intensity, kNonNegative);
    l.group = read_light_group(r);
    l.shape = read_light_shape(r, type);
    r.finish();
    return l;
}

/** Each table of the array `key` of the root, read by `read` into `out`; the k-th is called
 *  "[[key]] #k" in messages. */
template <class Desc, class Read>
void read_each(TableReader& top, const char* key, std::vector<Desc>& out, const Read& read);

/** One [[import]] table: the file, where it is placed, what of it is taken. */
ImportDesc read_import(const ReadContext& ctx, TableReader& r) {
    ImportDesc i;
    i.loc = r.loc();
    i.path = read_file(ctx, r, "file");
    i.placement = read_placement(r);
    i.camera = r.boolean("camera", i.camera);
    i.lights = r.boolean("lights", i.lights);
    i.environment = r.boolean("environment", i.environment);
    r.finish();
    return i;
}

template <class Desc, class Read>
void read_each(TableReader& top, const char* key, std::vector<Desc>& out, const Read& read) {
    const toml::array* tables = top.table_array(key);
    if (!tables) return;
    for (std::size_t i = 0; i < tables->size(); ++i) {
        TableReader r(*(*tables)[i].as_table(), top.file(), fmt::format("[[{}]] #{}", key, i + 1));
        out.push_back(read(r));
    }
}

}  // namespace

SceneDescription read_toml_scene(const std::string& path, const SceneReadOptions& options) {
    const toml::table root = parse_toml_file(path);
    SceneDescription d;
    d.path = path;
    const ReadContext ctx{path, std::filesystem::path(path).parent_path()};
    TableReader top(root, path, "the scene");
    top.set_whole_file();
    read_each(top, "import", d.imports, [&](TableReader& r) { return read_import(ctx, r); });
    {
        const toml::table* t = top.table("render");
        const toml::table empty;
        TableReader r(t ? *t : empty, path, "[render]");
        d.render = read_render(r);
        if (t)
            for (auto&& [key, value] : *t) d.render.written.emplace_back(key.str());
    }
    if (const toml::table* t = top.table("camera")) {
        TableReader r(*t, path, "[camera]");
        d.camera = read_camera(r);
    } else if (d.imports.empty() && !options.imported) {
        top.missing("camera");
    } else {
        d.has_camera = false;  // an import gives it
    }
    if (const toml::table* t = top.table("environment")) {
        TableReader r(*t, path, "[environment]");
        d.environment = read_environment(ctx, r);
    }
    read_each(top, "material", d.materials,
              [&](TableReader& r) { return toml_scene::read_material(ctx, r); });
    read_each(top, "object", d.objects, [&](TableReader& r) { return read_object(ctx, r); });
    read_each(top, "light", d.lights, [&](TableReader& r) { return read_light(ctx, r); });
    top.finish();
    return d;
}

}  // namespace spangle
