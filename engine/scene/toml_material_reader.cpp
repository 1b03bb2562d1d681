// The TOML scene reader's materials: [[material]] tables, their parameters, colours and textures,
// read as written (colour spaces are names here; the builder resolves them).

#include <cmath>
#include <utility>

#include "core/text.h"
#include "scene/scene_paths.h"
#include "scene/toml_scene_parts.h"

namespace spangle::toml_scene {

ColorDesc read_raw_color(const ReadContext& ctx, const toml::node& n, std::string_view name) {
    ColorDesc c;
    c.loc = loc_of(n, ctx.file);
    c.space_loc = c.loc;
    if (auto t = n.as_table()) {
        TableReader r(*t, ctx.file, fmt::format("colour '{}'", name));
        c.rgb = r.vec3("rgb");
        if (r.has("space")) {
            c.space = r.string("space");
            c.space_loc = r.loc("space");
        }
        r.finish();
        return c;
    }
    if (!n.is_array())
        throw_error(
            c.loc,
            "'{}' must be a colour: [r, g, b] or {{ rgb = [r, g, b], space = \"...\" }}, got {}",
            name, toml_type_name(n));
    c.rgb = parse_vec3(n, ctx.file, name);
    return c;
}

std::optional<ColorDesc> read_color(const ReadContext& ctx, TableReader& r, std::string_view key) {
    const toml::node* n = r.node(key);
    if (!n) return std::nullopt;
    ColorDesc c = read_raw_color(ctx, *n, key);
    if (c.rgb.x < 0 || c.rgb.y < 0 || c.rgb.z < 0)
        throw_error(loc_of(*n, ctx.file), "'{}' must be non-negative, got [{}, {}, {}]", key,
                    c.rgb.x, c.rgb.y, c.rgb.z);
    return c;
}

bool two_numbers(const toml::node& n, float& a, float& b) {
    const auto* arr = n.as_array();
    if (!arr || arr->size() != 2 || !(*arr)[0].is_number() || !(*arr)[1].is_number()) return false;
    a = static_cast<float>((*arr)[0].value<double>().value_or(0.0));
    b = static_cast<float>((*arr)[1].value<double>().value_or(0.0));
    return true;
}

bool finite_numbers(const toml::node& n, std::size_t size, std::vector<double>& out,
                    std::size_t other_size) {
    const auto* arr = n.as_array();
    if (!arr || (arr->size() != size && (other_size == 0 || arr->size() != other_size)))
        return false;
    out.clear();
    for (const toml::node& x : *arr) {
        const auto v = x.value<double>();
        if (!x.is_number() || !v || !std::isfinite(*v)) return false;
        out.push_back(*v);
    }
    return true;
}

namespace {

/** Which table a texture is read for: a material parameter, or one of the host's maps. */
enum class TextureUse { Param, NormalMap, BumpMap, Alpha, Emission };

/** `uv_transform = { scale = s | [su, sv], offset = [ou, ov], rotate = degrees }` into the
 *  texture's uv matrix: uv' = R(rotate) (scale * uv) + offset. */
void read_uv_transform(const ReadContext& ctx, const toml::table& t, TextureDesc& tex) {
    TableReader u(t, ctx.file, "uv_transform");
    // `matrix = [m0, ..., m5]`: the 2x3 matrix itself, (u, v) -> (m0 u + m1 v + m2, m3 u + m4 v
    // + m5), as `spangle convert` writes it.
    if (const toml::node* n = u.node("matrix")) {
        std::vector<double> m;
        const bool ok = finite_numbers(*n, 6, m);
        for (std::size_t i = 0; ok && i < 6; ++i) tex.uv[i] = static_cast<float>(m[i]);
        if (!ok)
            throw_error(loc_of(*n, ctx.file),
                        "'matrix' must be 6 finite numbers: (u, v) -> (m0 u + m1 v + m2, m3 u + "
                        "m4 v + m5)");
        for (const char* key : {"scale", "offset", "rotate"})
            if (u.has(key))
                throw_error(u.loc(key),
                            "give either 'matrix' or scale, offset and rotate, not both");
        u.finish();
        return;
    }
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
    const double rot = u.number("rotate", 0.0, {-360.0, 360.0}) * 3.14159265358979323846 / 180.0;
    u.finish();
    const auto c = static_cast<float>(std::cos(rot)), s = static_cast<float>(std::sin(rot));
    tex.uv[0] = c * su;
    tex.uv[1] = -s * sv;
    tex.uv[2] = ou;
    tex.uv[3] = s * su;
    tex.uv[4] = c * sv;
    tex.uv[5] = ov;
}

/** A parameter texture's `scale`: a number, or one per channel; non-negative. */
void read_texture_scale(const ReadContext& ctx, TableReader& r, TextureDesc& tex) {
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
        if (!(k >= 0.0f)) throw_error(r.loc("scale"), "'scale' must be non-negative, got {}", k);
}

/** `{ texture = "file", space = ..., scale = ..., uv_transform = {...}, wrap = ..., filter =
 *  ... }` (plus `strength` for a normal map, `height` and `strength` for a bump map; `scale` only
 * for a parameter). */
TextureDesc read_texture(const ReadContext& ctx, const toml::table& t, std::string_view name,
                         TextureUse use) {
    TableReader r(t, ctx.file, fmt::format("texture '{}'", name));
    TextureDesc tex;
    // A parameter's `vertex_color = true`: times the meshes' vertex colours, with or without an
    // image.
    if (use == TextureUse::Param && r.has("vertex_color")) {
        tex.vertex_color = r.boolean("vertex_color", false);
        if (!tex.vertex_color && !r.has("texture"))
            throw_error(r.loc("vertex_color"),
                        "parameter '{}': 'vertex_color = false' with no 'texture' reads nothing "
                        "(give a colour instead)",
                        name);
    }
    if (!tex.vertex_color || r.has("texture"))
        tex.path = find_scene_file(r.string("texture"), ctx.dir, "texture", r.loc("texture"));
    else
        for (const char* key : {"space", "uv_transform", "wrap", "filter"})
            if (r.has(key))
                throw_error(r.loc(key),
                            "parameter '{}': '{}' applies to an image, and there is no "
                            "'texture' (vertex colours are linear Rec.709, converted as "
                            "colours)",
                            name, key);
    if (r.has("space")) {
        tex.space = r.string("space");
        tex.space_loc = r.loc("space");
    }
    if ((use == TextureUse::Param || use == TextureUse::Emission) && r.has("scale"))
        read_texture_scale(ctx, r, tex);
    if (use == TextureUse::Param && r.has("channel")) {
        // Which of a colour image's channels a number parameter reads (by default its first).
        const std::string c = r.string("channel");
        tex.channel = c == "r"           ? 0
                      : c == "g"         ? 1
                      : c == "b"         ? 2
                      : c == "luminance" ? kLuminance
                                         : -2;
        if (tex.channel == -2)
            throw_error(r.loc("channel"),
                        "parameter '{}': 'channel' must be one of \"r\", \"g\", \"b\", "
                        "\"luminance\", got \"{}\"",
                        name, c);
    }
    if (use == TextureUse::Alpha) {
        const auto k = static_cast<float>(r.number("scale", 1.0, {0.0, 1e6}));
        tex.scale[0] = tex.scale[1] = tex.scale[2] = k;
        if (r.has("channel")) {
            const std::string c = r.string("channel");
            const char* names[] = {"r", "g", "b", "a"};
            tex.channel = c == "pbrt" ? kAlphaPbrt : -2;
            for (int i = 0; i < 4; ++i)
                if (c == names[i]) tex.channel = i;
            if (tex.channel == -2)
                throw_error(r.loc("channel"),
                            "'channel' must be one of \"r\", \"g\", \"b\", \"a\", \"pbrt\", "
                            "got \"{}\"",
                            c);
        }
    }
    if (use == TextureUse::NormalMap)
        tex.amount = static_cast<float>(r.number("strength", 1.0, {-10.0, 10.0}));  // < 0: inverted
    if (use == TextureUse::BumpMap) {
        tex.amount = static_cast<float>(r.number("height", 0.001, {-1.0, 1.0}));
        // Cycles' Bump Strength: the normal is the surface's blended with the bumped one.
        tex.blend = static_cast<float>(r.number("strength", 1.0, {0.0, 1.0}));
    }
    if (const toml::table* uv = r.table("uv_transform")) read_uv_transform(ctx, *uv, tex);
    if (r.has("wrap")) {
        // One mode, or [s, t]: one per axis (glTF's wrapS and wrapT).
        const char* modes[] = {"periodic", "clamp", "black", "mirror"};
        const auto mode = [&](const std::string& w) {
            for (int i = 0; i < 4; ++i)
                if (w == modes[i]) return i;
            throw_error(r.loc("wrap"),
                        "'wrap' must be one of periodic, clamp, black, mirror (or [s, t] of "
                        "them), got \"{}\"",
                        w);
        };
        if (const toml::array* both = r.node("wrap")->as_array()) {
            if (both->size() != 2 || !(*both)[0].is_string() || !(*both)[1].is_string())
                throw_error(r.loc("wrap"),
                            "'wrap' as an array gives two modes, [s, t], as strings");
            tex.wrap = mode(*(*both)[0].value<std::string>());
            tex.wrap_t = mode(*(*both)[1].value<std::string>());
            if (tex.wrap_t == tex.wrap) tex.wrap_t = -1;
        } else {
            tex.wrap = mode(r.string("wrap"));
        }
    }
    if (r.has("filter")) {
        const std::string f = r.string("filter");
        if (f != "trilinear" && f != "anisotropic" && f != "closest")
            throw_error(
                r.loc("filter"),
                "'filter' must be \"trilinear\", \"anisotropic\" or \"closest\", got \"{}\"", f);
        tex.filter = f == "anisotropic" ? 1 : f == "closest" ? 2 : 0;
    }
    r.finish();
    return tex;
}

/** One entry of a material's `params`: a number, bool, string, colour or texture. */
ParamDesc read_param(const ReadContext& ctx, const toml::key& k, const toml::node& n) {
    const std::string key(k.str());
    ParamDesc p;
    p.name = key;
    p.loc = loc_of(n, ctx.file);
    p.key_loc = key_location(k, n, ctx.file);
    if (auto i = n.as_integer()) {
        p.kind = ParamDesc::Kind::Number;
        p.number = static_cast<double>(i->get());
        p.is_integer = true;
    } else if (auto f = n.as_floating_point()) {
        if (!std::isfinite(f->get()))
            throw_error(p.loc, "parameter '{}' must be finite, got {}", key, f->get());
        p.kind = ParamDesc::Kind::Number;
        p.number = f->get();
    } else if (auto b = n.as_boolean()) {
        p.kind = ParamDesc::Kind::Bool;
        p.number = b->get() ? 1.0 : 0.0;
    } else if (auto s = n.as_string()) {
        p.kind = ParamDesc::Kind::String;
        p.text = s->get();
    } else if (n.is_table() &&
               (n.as_table()->contains("texture") || n.as_table()->contains("vertex_color"))) {
        p.kind = ParamDesc::Kind::Texture;
        p.texture = read_texture(ctx, *n.as_table(), key, TextureUse::Param);
    } else if (n.is_array() || n.is_table()) {
        // A table is a colour ({ rgb, space }) or a texture: a misspelt 'texture' said so (it
        // was "colour 'albedo' is missing required key 'rgb'").
        if (const toml::table* t = n.as_table(); t && !t->contains("rgb"))
            for (auto&& [inner, value] : *t) {
                if (inner.str() == "space") continue;
                const std::string hint =
                    did_you_mean(inner.str(), {"texture", "rgb", "space", "vertex_color"});
                throw_error(key_location(inner, value, ctx.file),
                            "parameter '{}': unknown key '{}'{} (a colour is {{ rgb = [r, g, b], "
                            "space = ... }}, an image {{ texture = \"file\", ... }}, the "
                            "meshes' vertex colours {{ vertex_color = true, ... }})",
                            key, inner.str(), hint);
            }
        p.kind = ParamDesc::Kind::Color;
        p.color = read_raw_color(ctx, n, key);
    } else {
        throw_error(p.loc, "parameter '{}' has unsupported type {}", key, toml_type_name(n));
    }
    return p;
}

}  // namespace

TextureDesc read_color_texture(const ReadContext& ctx, const toml::table& t,
                               std::string_view name) {
    return read_texture(ctx, t, name, TextureUse::Emission);
}

MaterialDesc read_material(const ReadContext& ctx, TableReader& r) {
    MaterialDesc m;
    m.loc = r.loc();
    m.name = r.string("name");
    m.name_loc = r.loc("name");
    if (m.name.empty()) throw_error(m.name_loc, "a material's 'name' must not be empty");
    m.plugin = r.string("plugin");
    m.plugin_loc = r.loc("plugin");
    m.model = r.string("model", "");
    m.model_loc = r.loc("model");
    if (const toml::table* params = r.table("params"))
        for (auto&& [key, value] : *params) {
            // Its errors say whose parameter it is, as the plugin's own checks do.
            try {
                m.params.push_back(read_param(ctx, key, value));
            } catch (const SpangleError& e) {
                throw with_context(e, fmt::format("material '{}'", m.name));
            }
        }
    for (const auto& [key, use] : {std::pair{"normal_map", TextureUse::NormalMap},
                                   std::pair{"bump_map", TextureUse::BumpMap}}) {
        const toml::table* t = r.table(key);
        if (!t) continue;
        ParamDesc p;
        p.name = key;
        p.kind = ParamDesc::Kind::Texture;
        p.loc = r.loc(key);
        p.key_loc = p.loc;
        p.texture = read_texture(ctx, *t, key, use);
        m.maps.push_back(std::move(p));
    }
    if (const toml::node* n = r.node("alpha")) {
        ParamDesc p;
        p.name = "alpha";
        p.loc = r.loc("alpha");
        p.key_loc = p.loc;
        if (const toml::table* t = n->as_table()) {
            p.kind = ParamDesc::Kind::Texture;
            p.texture = read_texture(ctx, *t, "alpha", TextureUse::Alpha);
        } else {
            p.kind = ParamDesc::Kind::Number;
            p.number = r.number("alpha", 1.0, {0.0, 1.0});
        }
        m.alpha = std::move(p);
    }
    if (r.has("alpha_cutoff")) {
        m.alpha_cutoff_loc = r.loc("alpha_cutoff");
        m.alpha_cutoff = r.number("alpha_cutoff", 0.5, {0.0, 1.0});
        if (!m.alpha)
            throw_error(m.alpha_cutoff_loc,
                        "material '{}': alpha_cutoff needs an alpha (a number or a texture) to "
                        "cut by",
                        m.name);
    }
    m.shadow_catcher = r.boolean("shadow_catcher", false);
    if (m.maps.size() == 2)
        throw_error(r.loc("bump_map"), "material '{}': give a normal_map or a bump_map, not both",
                    m.name);
    r.finish();
    return m;
}

}  // namespace spangle::toml_scene
