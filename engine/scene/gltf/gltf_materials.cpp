// glTF materials as Spangle materials (docs/gltf.md has the whole mapping):
//   - SPANGLE_materials_flakes: the flake plugin, every member of the extension a parameter;
//   - KHR_materials_transmission: the smooth plugin's dielectric;
//   - everything else: the smooth plugin's metal_rough, glTF's metallic-roughness BRDF with
//     KHR_materials_ior, _specular and _clearcoat;
// the normal texture as the host's normal map, emission (KHR_materials_emissive_strength) as the
// objects' emission. Colours are linear Rec.709 factors and sRGB-encoded textures; data
// textures are raw.

#include <algorithm>
#include <cmath>

#include "scene/gltf/gltf_parts.h"
#include "scene/gltf/gltf_textures.h"

namespace spangle::gltf {
namespace {

/** Extensions of a material that are read here (others are noted). */
const std::set<std::string> kMaterialExtensions = {"KHR_materials_clearcoat",
                                                   "KHR_materials_ior",
                                                   "KHR_materials_specular",
                                                   "KHR_materials_transmission",
                                                   "KHR_materials_emissive_strength",
                                                   "KHR_materials_volume",
                                                   "KHR_materials_pbrSpecularGlossiness",
                                                   "KHR_materials_unlit",
                                                   "KHR_materials_sheen",
                                                   "SPANGLE_materials_flakes"};

/** Builds one MaterialDesc's parameters, each blamed on its place in the JSON. */
struct Builder {
    Context& ctx;
    MaterialDesc& m;

    ParamDesc base(const std::string& name, const std::string& path) const {
        ParamDesc p;
        p.name = name;
        p.loc = ctx.at(path);
        p.key_loc = p.loc;
        return p;
    }
    void number(const std::string& name, double x, const std::string& path, bool integer = false) {
        ParamDesc p = base(name, path);
        p.number = x;
        p.is_integer = integer;
        m.params.push_back(std::move(p));
    }
    void color(const std::string& name, Vec3 rgb, const std::string& path,
               const std::string& space = "lin_rec709") {
        ParamDesc p = base(name, path);
        p.kind = ParamDesc::Kind::Color;
        p.color = ColorDesc{rgb, space, p.loc, p.loc};
        m.params.push_back(std::move(p));
    }
    void texture(const std::string& name, TextureDesc tex, const std::string& path) {
        ParamDesc p = base(name, path);
        p.kind = ParamDesc::Kind::Texture;
        p.texture = std::move(tex);
        m.params.push_back(std::move(p));
    }
    bool has(const std::string& name) const {
        for (const ParamDesc& p : m.params)
            if (p.name == name) return true;
        return false;
    }
};

const tinygltf::Value* extension(const tinygltf::Material& g, const char* name) {
    const auto it = g.extensions.find(name);
    return it == g.extensions.end() ? nullptr : &it->second;
}

/** Member `key` of extension value x as a finite number, else `fallback`. */
double number_of(const tinygltf::Value* x, const char* key, double fallback) {
    if (!x || !x->IsObject() || !x->Has(key) || !x->Get(key).IsNumber()) return fallback;
    const double v = x->Get(key).GetNumberAsDouble();
    return std::isfinite(v) ? v : fallback;
}

/** Three finite numbers, or none. */
std::optional<Vec3> three_numbers(const tinygltf::Value& a) {
    if (!a.IsArray() || a.ArrayLen() != 3) return std::nullopt;
    float v[3];
    for (int c = 0; c < 3; ++c) {
        if (!a.Get(c).IsNumber()) return std::nullopt;
        v[c] = narrow(a.Get(c).GetNumberAsDouble());
        if (!std::isfinite(v[c])) return std::nullopt;
    }
    return Vec3{v[0], v[1], v[2]};
}

/** Member `key` of x as three finite numbers, else `fallback`. */
Vec3 vec3_of(const tinygltf::Value* x, const char* key, Vec3 fallback) {
    if (!x || !x->IsObject() || !x->Has(key)) return fallback;
    return three_numbers(x->Get(key)).value_or(fallback);
}

/** A textureInfo inside an extension's JSON value (tinygltf parses only the core ones). */
std::optional<TextureUse> texture_in(const tinygltf::Value* x, const char* key) {
    if (!x || !x->IsObject() || !x->Has(key) || !x->Get(key).IsObject()) return std::nullopt;
    const tinygltf::Value& t = x->Get(key);
    if (!t.Has("index") || !t.Get("index").IsInt()) return std::nullopt;
    TextureUse u;
    u.index = t.Get("index").GetNumberAsInt();
    u.tex_coord =
        t.Has("texCoord") && t.Get("texCoord").IsInt() ? t.Get("texCoord").GetNumberAsInt() : 0;
    return u;
}

/** Colour parameter `name`: the factor (written at `factor_path`), or where extension value x
 *  (at JSON path xp) has a colour texture `texture_key` that can be had, that texture (sRGB)
 *  scaled per channel by the factor. */
void factor_or_texture(Builder& b, const std::string& name, Vec3 factor, const tinygltf::Value* x,
                       const char* texture_key, const std::string& xp,
                       const std::string& factor_path) {
    const std::string tp = xp + "/" + texture_key;
    std::optional<TextureDesc> tex;
    if (auto u = texture_in(x, texture_key)) tex = texture_desc(b.ctx, *u, tp, true);
    if (!tex) return b.color(name, factor, factor_path);
    tex->scale[0] = factor.x;
    tex->scale[1] = factor.y;
    tex->scale[2] = factor.z;
    b.texture(name, std::move(*tex), tp);
}

/** A core textureInfo as a TextureUse. */
TextureUse use_of(const tinygltf::TextureInfo& t) {
    return {t.index, t.texCoord, &t.extensions};
}

/** Each component clamped to [lo, hi]. */
Vec3 clamp3(Vec3 v, float lo, float hi) {
    return {std::clamp(v.x, lo, hi), std::clamp(v.y, lo, hi), std::clamp(v.z, lo, hi)};
}

/** base_color: the factor, or the sRGB texture scaled by it; times the vertex colours where the
 *  material's primitives have COLOR_0. */
void base_color(Builder& b, const tinygltf::Material& g, const std::string& mp) {
    const std::vector<double>& f = g.pbrMetallicRoughness.baseColorFactor;
    Vec3 rgb{1, 1, 1};
    if (f.size() >= 3) rgb = {narrow(f[0]), narrow(f[1]), narrow(f[2])};
    if (!std::isfinite(rgb.x + rgb.y + rgb.z))
        throw_error(b.ctx.at(mp + "/pbrMetallicRoughness/baseColorFactor"),
                    "baseColorFactor holds a number that is not a finite float");
    rgb = clamp3(rgb, 0.0f, 1.0f);
    const std::string at = mp + "/pbrMetallicRoughness/baseColorFactor";
    const std::string tp = mp + "/pbrMetallicRoughness/baseColorTexture";
    if (g.pbrMetallicRoughness.baseColorTexture.index >= 0)
        if (auto tex =
                texture_desc(b.ctx, use_of(g.pbrMetallicRoughness.baseColorTexture), tp, true)) {
            tex->scale[0] = rgb.x;
            tex->scale[1] = rgb.y;
            tex->scale[2] = rgb.z;
            tex->vertex_color = b.ctx.vertex_colors;
            return b.texture("base_color", std::move(*tex), tp);
        }
    if (b.ctx.vertex_colors) {
        TextureDesc tex;
        tex.vertex_color = true;
        tex.scale[0] = rgb.x;
        tex.scale[1] = rgb.y;
        tex.scale[2] = rgb.z;
        return b.texture("base_color", std::move(tex), at);
    }
    b.color("base_color", rgb, at);
}

/** glTF's metallic-roughness BRDF with its ior, specular and clearcoat extensions. */
void metal_rough(Builder& b, const tinygltf::Material& g, const std::string& mp) {
    Context& ctx = b.ctx;
    const tinygltf::PbrMetallicRoughness& pbr = g.pbrMetallicRoughness;
    b.m.plugin = "smooth";
    b.m.model = "metal_rough";
    base_color(b, g, mp);
    const std::string pp = mp + "/pbrMetallicRoughness";
    b.number("metallic", std::clamp(pbr.metallicFactor, 0.0, 1.0), pp + "/metallicFactor");
    b.number("roughness", std::clamp(pbr.roughnessFactor, 0.0, 1.0), pp + "/roughnessFactor");
    if (pbr.metallicRoughnessTexture.index >= 0)
        if (auto tex = texture_desc(ctx, use_of(pbr.metallicRoughnessTexture),
                                    pp + "/metallicRoughnessTexture", false))
            b.texture("metallic_roughness", std::move(*tex), pp + "/metallicRoughnessTexture");
    if (const tinygltf::Value* x = extension(g, "KHR_materials_ior")) {
        const std::string xp = mp + "/extensions/KHR_materials_ior";
        const double ior = number_of(x, "ior", 1.5);
        if (ior < 1.0 || ior > 10.0)
            ctx.note("ior range", ctx.at(xp + "/ior"),
                     fmt::format("ior {} is outside [1, 10]: {} stands in", ior,
                                 std::clamp(ior, 1.0, 10.0)));
        b.number("ior", std::clamp(ior, 1.0, 10.0), xp + "/ior");
    }
    if (const tinygltf::Value* x = extension(g, "KHR_materials_specular")) {
        const std::string xp = mp + "/extensions/KHR_materials_specular";
        b.number("specular", std::clamp(number_of(x, "specularFactor", 1.0), 0.0, 1.0),
                 xp + "/specularFactor");
        factor_or_texture(b, "specular_color",
                          clamp3(vec3_of(x, "specularColorFactor", {1, 1, 1}), 0.0f, 10.0f), x,
                          "specularColorTexture", xp, xp + "/specularColorFactor");
        if (texture_in(x, "specularTexture"))
            ctx.note("specularTexture", ctx.at(xp + "/specularTexture"),
                     "specularTexture (its alpha channel) is dropped: specularFactor stands in");
    }
    if (const tinygltf::Value* x = extension(g, "KHR_materials_sheen")) {
        const std::string xp = mp + "/extensions/KHR_materials_sheen";
        factor_or_texture(b, "sheen_color",
                          clamp3(vec3_of(x, "sheenColorFactor", {0, 0, 0}), 0.0f, 1.0f), x,
                          "sheenColorTexture", xp, xp + "/sheenColorFactor");
        b.number("sheen_roughness", std::clamp(number_of(x, "sheenRoughnessFactor", 0.0), 0.0, 1.0),
                 xp + "/sheenRoughnessFactor");
        if (texture_in(x, "sheenRoughnessTexture"))
            ctx.note("sheenRoughnessTexture", ctx.at(xp + "/sheenRoughnessTexture"),
                     "sheenRoughnessTexture (its alpha channel) is dropped: sheenRoughnessFactor "
                     "stands in");
    }
    if (const tinygltf::Value* x = extension(g, "KHR_materials_clearcoat")) {
        const std::string xp = mp + "/extensions/KHR_materials_clearcoat";
        const double cc = std::clamp(number_of(x, "clearcoatFactor", 0.0), 0.0, 1.0);
        std::optional<TextureDesc> tex;
        if (auto u = texture_in(x, "clearcoatTexture"))
            tex = texture_desc(ctx, *u, xp + "/clearcoatTexture", false);
        if (tex) {
            tex->scale[0] = tex->scale[1] = tex->scale[2] = static_cast<float>(cc);
            b.texture("clearcoat", std::move(*tex), xp + "/clearcoatTexture");
        } else {
            b.number("clearcoat", cc, xp + "/clearcoatFactor");
        }
        b.number("clearcoat_roughness",
                 std::clamp(number_of(x, "clearcoatRoughnessFactor", 0.0), 0.0, 1.0),
                 xp + "/clearcoatRoughnessFactor");
        for (const char* key : {"clearcoatRoughnessTexture", "clearcoatNormalTexture"})
            if (texture_in(x, key))
                ctx.note(key, ctx.at(xp + "/" + key),
                         fmt::format("{} is dropped: {}", key,
                                     std::string(key) == "clearcoatNormalTexture"
                                         ? "the coat follows the base's normal"
                                         : "clearcoatRoughnessFactor stands in"));
    }
}

/** KHR_materials_pbrSpecularGlossiness onto metal_rough as a dielectric (metallic 0) whose
 *  F0 is the specular colour, through KHR_materials_specular's terms: the index sets the
 *  largest F0 the colour can reach (1.5 up to 0.4, higher for brighter speculars: F0 = 1 at
 *  10 x 0.67), specular_color = specular / ((ior - 1) / (ior + 1))^2; base colour = the diffuse
 *  colour; roughness = 1 - glossiness (its texture's alpha made a roughness image). */
void spec_gloss(Builder& b, const tinygltf::Material& g, const std::string& mp,
                const tinygltf::Value* x) {
    (void)g;
    Context& ctx = b.ctx;
    const std::string xp = mp + "/extensions/KHR_materials_pbrSpecularGlossiness";
    b.m.plugin = "smooth";
    b.m.model = "metal_rough";
    // Its values as the schema says, else an error at them (a wrong one fell back to white
    // or to chrome without a word).
    if (!x->IsObject())
        throw_error(ctx.at(xp), "KHR_materials_pbrSpecularGlossiness must be an object");
    const auto numbers = [&](const char* key, int count, float lo, float hi) {
        std::vector<float> v;
        if (!x->Has(key)) return v;
        const tinygltf::Value& a = x->Get(key);
        bool ok = a.IsArray() && a.ArrayLen() == static_cast<std::size_t>(count);
        for (int c = 0; ok && c < count; ++c) {
            ok = a.Get(c).IsNumber();
            if (ok) v.push_back(narrow(a.Get(c).GetNumberAsDouble()));
            ok = ok && std::isfinite(v.back()) && v.back() >= lo && v.back() <= hi;
        }
        if (!ok)
            throw_error(ctx.at(xp + "/" + key), "'{}' must be {} numbers in [{}, {}]", key, count,
                        lo, hi);
        return v;
    };
    const std::vector<float> df = numbers("diffuseFactor", 4, 0.0f, 1.0f);
    const std::vector<float> sf = numbers("specularFactor", 3, 0.0f, 1.0f);
    if (x->Has("glossinessFactor") && (!x->Get("glossinessFactor").IsNumber() ||
                                       !(number_of(x, "glossinessFactor", -1.0) >= 0.0 &&
                                         number_of(x, "glossinessFactor", -1.0) <= 1.0)))
        throw_error(ctx.at(xp + "/glossinessFactor"), "'glossinessFactor' must be in [0, 1]");
    Vec3 diffuse{1, 1, 1};
    if (!df.empty()) diffuse = {df[0], df[1], df[2]};
    std::optional<TextureDesc> dtex;
    if (auto u = texture_in(x, "diffuseTexture"))
        dtex = texture_desc(ctx, *u, xp + "/diffuseTexture", true);
    if (dtex || ctx.vertex_colors) {
        TextureDesc tex = dtex ? std::move(*dtex) : TextureDesc{};
        tex.scale[0] = diffuse.x;
        tex.scale[1] = diffuse.y;
        tex.scale[2] = diffuse.z;
        tex.vertex_color = ctx.vertex_colors;
        b.texture("base_color", std::move(tex), xp + (dtex ? "/diffuseTexture" : ""));
    } else {
        b.color("base_color", diffuse, xp + "/diffuseFactor");
    }
    const Vec3 spec = sf.empty() ? Vec3{1, 1, 1} : Vec3{sf[0], sf[1], sf[2]};
    const double gloss = std::clamp(number_of(x, "glossinessFactor", 1.0), 0.0, 1.0);
    // With textures: converted texel by texel to metallic-roughness (the glTF converter's
    // solve), so metal texels are metals whose light between microfacets metal_rough keeps.
    const std::optional<TextureUse> du = texture_in(x, "diffuseTexture"),
                                    su = texture_in(x, "specularGlossinessTexture");
    if (du || su) {
        if (std::optional<MetalRoughImages> mr = metal_rough_from_spec_gloss(
                ctx, du, xp + "/diffuseTexture", su, xp + "/specularGlossinessTexture", diffuse,
                spec, gloss)) {
            ParamDesc& bc = b.m.params.back();  // the base colour written above
            bc.kind = ParamDesc::Kind::Texture;
            const bool vc = ctx.vertex_colors;
            bc.texture = std::move(mr->base);
            bc.texture.vertex_color = vc;
            b.number("metallic", 1.0, xp);
            b.number("roughness", 1.0, xp);
            b.texture("metallic_roughness", std::move(mr->packed),
                      xp + (su ? "/specularGlossinessTexture" : "/diffuseTexture"));
            return;
        }
        ctx.note("spec-gloss textures", ctx.at(xp),
                 "the specular-glossiness textures could not be combined (mapped differently, or "
                 "an image that cannot be decoded): the material is drawn as a dielectric of "
                 "their specular colour");
    }
    // Without textures: where the specular is a metal's (the converter's solve), a metal, whose
    // light between microfacets metal_rough keeps (a rough chrome rendered 30% dark as a
    // dielectric of F0 1); otherwise the dielectric of exactly that F0 below.
    if (!du && !su) {
        double metal = 0.0;
        Vec3 base;
        spec_gloss_to_metal(diffuse, spec, metal, base);
        if (metal > 0.5) {
            ParamDesc& bc = b.m.params.back();          // the base colour written above
            if (bc.kind == ParamDesc::Kind::Texture) {  // vertex colours: their scale
                bc.texture.scale[0] = base.x;
                bc.texture.scale[1] = base.y;
                bc.texture.scale[2] = base.z;
            } else {
                bc.color.rgb = base;
            }
            b.number("metallic", metal, xp + "/specularFactor");
            b.number("roughness", 1.0 - gloss, xp + "/glossinessFactor");
            return;
        }
    }
    b.number("metallic", 0.0, xp);
    constexpr double kMaxR0 = (9.0 / 11.0) * (9.0 / 11.0);  // ior 10, the largest
    const double r0 =
        std::clamp(static_cast<double>(std::max({spec.x, spec.y, spec.z})), 0.04, kMaxR0);
    const double ior = (1.0 + std::sqrt(r0)) / (1.0 - std::sqrt(r0));
    b.number("ior", std::clamp(ior, 1.0, 10.0), xp + "/specularFactor");
    b.number("specular", 1.0, xp + "/specularFactor");
    factor_or_texture(b, "specular_color", spec * static_cast<float>(1.0 / r0), x,
                      "specularGlossinessTexture", xp, xp + "/specularFactor");
    std::optional<TextureDesc> rough;
    if (auto u = texture_in(x, "specularGlossinessTexture"))
        rough = roughness_from_gloss(ctx, *u, xp + "/specularGlossinessTexture", gloss);
    if (rough)
        b.texture("roughness", std::move(*rough), xp + "/specularGlossinessTexture");
    else
        b.number("roughness", 1.0 - gloss, xp + "/glossinessFactor");
}

/** KHR_materials_transmission onto the smooth plugin's dielectric, tinted by the base colour
 *  (and KHR_materials_volume's attenuation). */
void transmissive(Builder& b, const tinygltf::Material& g, const std::string& mp,
                  const tinygltf::Value* x) {
    Context& ctx = b.ctx;
    const std::string xp = mp + "/extensions/KHR_materials_transmission";
    b.m.plugin = "smooth";
    b.m.model = "dielectric";
    const double t = number_of(x, "transmissionFactor", 0.0);
    if (t < 1.0 || texture_in(x, "transmissionTexture"))
        ctx.note("partial transmission", ctx.at(xp),
                 fmt::format("transmission {}{} is drawn as the dielectric, fully transmissive", t,
                             texture_in(x, "transmissionTexture") ? " with a texture" : ""));
    if (g.pbrMetallicRoughness.metallicFactor > 0.0)
        ctx.note("transmission metal", ctx.at(mp + "/pbrMetallicRoughness/metallicFactor"),
                 "a transmissive material's metalness is dropped: it is drawn as glass");
    // The base colour (its texture and vertex colours too) tints the transmitted light, as
    // glTF's BTDF has it; KHR_materials_volume's attenuation deepens the tint (below).
    base_color(b, g, mp);
    b.m.params.back().name = "transmission_color";
    if (const tinygltf::Value* v = extension(g, "KHR_materials_volume")) {
        const std::string vp = mp + "/extensions/KHR_materials_volume";
        const Vec3 c = clamp3(vec3_of(v, "attenuationColor", {1, 1, 1}), 0.0f, 1.0f);
        const double d = number_of(v, "attenuationDistance", 0.0);
        const double thick = std::max(0.0, number_of(v, "thicknessFactor", 0.0));
        if (d > 0.0 && thick > 0.0 && (c.x < 1.0f || c.y < 1.0f || c.z < 1.0f)) {
            // Beer-Lambert over a path of thicknessFactor through the object: c^(t / d) (the
            // dielectric's colour of a passage in and out). Spangle has no participating
            // media: thinner and thicker parts of the object get the same tint.
            const double k = thick / d;
            const auto power = [&](float value) {
                return static_cast<float>(std::pow(static_cast<double>(value), k));
            };
            const Vec3 tint{power(c.x), power(c.y), power(c.z)};
            ParamDesc& p = b.m.params.back();
            if (p.kind == ParamDesc::Kind::Color) {
                p.color.rgb = p.color.rgb * tint;
            } else {
                p.texture.scale[0] *= tint.x;
                p.texture.scale[1] *= tint.y;
                p.texture.scale[2] *= tint.z;
            }
            ctx.note(
                "volume attenuation", ctx.at(vp),
                std::string("KHR_materials_volume's attenuation is approximated by a tint "
                            "of the light that passes through, as if every path inside "
                            "were thicknessFactor long (Spangle has no absorbing media)") +
                    (texture_in(v, "thicknessTexture") ? "; thicknessTexture is dropped" : ""));
        }
    }
    const double r = std::clamp(g.pbrMetallicRoughness.roughnessFactor, 0.0, 1.0);
    b.number("roughness", r * r, mp + "/pbrMetallicRoughness/roughnessFactor");
    // Rough glass keeps the light of further bounces between microfacets, as metal_rough's
    // metal does (its multiscatter is on by default; the dielectric's is off unless asked).
    ParamDesc ms = b.base("multiscatter", mp);
    ms.kind = ParamDesc::Kind::Bool;
    ms.number = 1.0;
    b.m.params.push_back(std::move(ms));
    if (const tinygltf::Value* i = extension(g, "KHR_materials_ior"))
        b.number("ior", std::clamp(number_of(i, "ior", 1.5), 1.0, 10.0),
                 mp + "/extensions/KHR_materials_ior/ior");
}

/** One member of SPANGLE_materials_flakes as a flake parameter (docs/gltf.md): a number,
 *  true/false, a string, [r, g, b] (linear Rec.709), {"rgb": [r, g, b], "space": NAME} or a
 *  textureInfo {"index": N, ...} (sRGB for parameters named *color, data otherwise, unless
 *  "space" says). The flake plugin's schema checks names, types and ranges later. */
void flake_param(Builder& b, const std::string& key, const tinygltf::Value& v,
                 const std::string& path) {
    Context& ctx = b.ctx;
    if (v.IsBool()) {
        ParamDesc p = b.base(key, path);
        p.kind = ParamDesc::Kind::Bool;
        p.number = v.Get<bool>() ? 1.0 : 0.0;
        return b.m.params.push_back(std::move(p));
    }
    if (v.IsNumber()) return b.number(key, v.GetNumberAsDouble(), path, v.IsInt());
    if (v.IsString()) {
        ParamDesc p = b.base(key, path);
        p.kind = ParamDesc::Kind::String;
        p.text = v.Get<std::string>();
        return b.m.params.push_back(std::move(p));
    }
    if (auto rgb = three_numbers(v)) return b.color(key, *rgb, path);
    const bool is_color = key.size() >= 5 && key.compare(key.size() - 5, 5, "color") == 0;
    if (v.IsObject() && v.Has("space") && !v.Get("space").IsString())
        throw_error(ctx.at(path + "/space"), "'space' must be a colour space's name");
    const std::string space =
        v.IsObject() && v.Has("space") ? v.Get("space").Get<std::string>() : std::string();
    if (v.IsObject() && v.Has("rgb")) {
        auto rgb = three_numbers(v.Get("rgb"));
        if (!rgb) throw_error(ctx.at(path + "/rgb"), "'rgb' must be three finite numbers");
        return b.color(key, *rgb, path, space.empty() ? "lin_rec709" : space);
    }
    if (v.IsObject() && v.Has("index")) {
        if (!v.Get("index").IsInt())
            throw_error(ctx.at(path + "/index"), "'index' must be a texture's index");
        TextureUse u;
        u.index = v.Get("index").GetNumberAsInt();
        if (v.Has("texCoord") && v.Get("texCoord").IsInt())
            u.tex_coord = v.Get("texCoord").GetNumberAsInt();
        auto tex = texture_desc(ctx, u, path, is_color);
        if (!tex) return;
        if (!space.empty()) tex->space = space;
        if (v.Has("scale")) {
            if (!v.Get("scale").IsNumber() || !(v.Get("scale").GetNumberAsDouble() >= 0.0) ||
                !std::isfinite(narrow(v.Get("scale").GetNumberAsDouble())))
                throw_error(ctx.at(path + "/scale"), "'scale' must be a non-negative number");
            tex->scale[0] = tex->scale[1] = tex->scale[2] =
                narrow(v.Get("scale").GetNumberAsDouble());
        }
        return b.texture(key, std::move(*tex), path);
    }
    throw_error(ctx.at(path),
                "SPANGLE_materials_flakes: '{}' must be a number, true or false, a string, "
                "[r, g, b], {{\"rgb\": [r, g, b], \"space\": NAME}} or a texture {{\"index\": N}}",
                key);
}

/** SPANGLE_materials_flakes onto the flake plugin; base colour and clear coat from the core
 *  material and KHR_materials_clearcoat where the extension does not give them. */
void flakes(Builder& b, const tinygltf::Material& g, const std::string& mp,
            const tinygltf::Value& x) {
    const std::string xp = mp + "/extensions/SPANGLE_materials_flakes";
    if (!x.IsObject())
        throw_error(b.ctx.at(xp), "SPANGLE_materials_flakes must be an object of flake parameters");
    b.m.plugin = "flake";
    b.m.plugin_loc = b.ctx.at(xp);
    for (const std::string& key : x.Keys()) flake_param(b, key, x.Get(key), xp + "/" + key);
    if (!b.has("base_color")) base_color(b, g, mp);
    const tinygltf::Value* cc = extension(g, "KHR_materials_clearcoat");
    if (!b.has("coat") && cc && number_of(cc, "clearcoatFactor", 0.0) > 0.0) {
        const std::string cp = mp + "/extensions/KHR_materials_clearcoat";
        ParamDesc p = b.base("coat", cp + "/clearcoatFactor");
        p.kind = ParamDesc::Kind::Bool;
        p.number = 1.0;
        b.m.params.push_back(std::move(p));
        const double r = std::clamp(number_of(cc, "clearcoatRoughnessFactor", 0.0), 0.0, 1.0);
        if (!b.has("coat_roughness"))
            b.number("coat_roughness", r * r, cp + "/clearcoatRoughnessFactor");
    }
}

/** alphaMode MASK and BLEND as the host's alpha: base colour's alpha (its texture's A times
 *  its factor's fourth), cut at alphaCutoff for MASK, by chance for BLEND. */
void alpha(Builder& b, const tinygltf::Material& g, const std::string& mp) {
    const std::vector<double>& f = g.pbrMetallicRoughness.baseColorFactor;
    double a = f.size() >= 4 && std::isfinite(f[3]) ? std::clamp(f[3], 0.0, 1.0) : 1.0;
    std::optional<TextureUse> use;
    std::string tp = mp + "/pbrMetallicRoughness/baseColorTexture";
    if (g.pbrMetallicRoughness.baseColorTexture.index >= 0)
        use = use_of(g.pbrMetallicRoughness.baseColorTexture);
    // KHR_materials_pbrSpecularGlossiness: its diffuse colour's alpha.
    if (const tinygltf::Value* x = extension(g, "KHR_materials_pbrSpecularGlossiness")) {
        a = 1.0;
        if (x->IsObject() && x->Has("diffuseFactor")) {
            const tinygltf::Value& d = x->Get("diffuseFactor");
            if (d.IsArray() && d.ArrayLen() == 4 && d.Get(3).IsNumber() &&
                std::isfinite(d.Get(3).GetNumberAsDouble()))
                a = std::clamp(d.Get(3).GetNumberAsDouble(), 0.0, 1.0);
        }
        use = texture_in(x, "diffuseTexture");
        tp = mp + "/extensions/KHR_materials_pbrSpecularGlossiness/diffuseTexture";
    }
    if (g.alphaMode != "MASK" && g.alphaMode != "BLEND") {
        if (!g.alphaMode.empty() && g.alphaMode != "OPAQUE")
            b.ctx.note("alphaMode", b.ctx.at(mp + "/alphaMode"),
                       fmt::format("alphaMode \"{}\" is not OPAQUE, MASK or BLEND (glTF spells "
                                   "them in capitals): the surface is drawn opaque",
                                   g.alphaMode));
        return;
    }
    const bool mask = g.alphaMode == "MASK";
    const double cutoff = std::isfinite(g.alphaCutoff) ? std::clamp(g.alphaCutoff, 0.0, 1.0) : 0.5;
    if (mask && cutoff != g.alphaCutoff)
        b.ctx.note(
            "alphaCutoff", b.ctx.at(mp + "/alphaCutoff"),
            fmt::format("alphaCutoff {} is outside [0, 1]: {} stands in", g.alphaCutoff, cutoff));
    ParamDesc p = b.base("alpha", mp + "/alphaMode");
    p.kind = ParamDesc::Kind::Number;
    p.number = a;
    if (use)
        if (auto tex = texture_desc(b.ctx, *use, tp, false)) {
            tex->scale[0] = tex->scale[1] = tex->scale[2] = static_cast<float>(a);
            tex->channel = kAlphaOrOpaque;
            p.kind = ParamDesc::Kind::Texture;
            p.texture = std::move(*tex);
        }
    // A constant alpha the mode draws whole: nothing to cut.
    if (p.kind == ParamDesc::Kind::Number && (a >= 1.0 || (mask && a >= cutoff))) return;
    b.m.alpha = std::move(p);
    if (mask) {
        b.m.alpha_cutoff = cutoff;
        b.m.alpha_cutoff_loc = b.ctx.at(mp + "/alphaCutoff");
    }
}

/** The core material's parts no Spangle material carries, one note each. */
void note_unread(Context& ctx, const tinygltf::Material& g, const std::string& mp) {
    if (g.occlusionTexture.index >= 0)
        ctx.note("occlusion", ctx.at(mp + "/occlusionTexture"),
                 "occlusionTexture is ignored: the path tracer computes occlusion");
    if (g.alphaMode == "BLEND")
        ctx.note("alphaMode BLEND", ctx.at(mp + "/alphaMode"),
                 "alphaMode BLEND is drawn as a cut-out whose alpha is the chance that a ray "
                 "meets the surface (coverage): see-through where alpha is low, but no "
                 "refraction and no blending order");
    // Both sides are shaded whatever doubleSided says; only emission differs from a viewer's.
    const bool emits = std::any_of(g.emissiveFactor.begin(), g.emissiveFactor.end(),
                                   [](double v) { return v > 0.0; });
    if (g.doubleSided && emits)
        ctx.note("doubleSided emission", ctx.at(mp + "/doubleSided"),
                 "a doubleSided emissive material emits from its front faces only (a viewer "
                 "lights both sides)");
    for (const auto& [name, value] : g.extensions) {
        (void)value;
        if (name == "KHR_materials_iridescence")
            ctx.note(name, ctx.at(mp + "/extensions/" + name),
                     "KHR_materials_iridescence is dropped: neither the smooth nor the flake "
                     "plugin has a thin-film layer; the material without it stands in");
        else if (!kMaterialExtensions.count(name))
            ctx.note(name, ctx.at(mp + "/extensions/" + name),
                     fmt::format("material extension {} is not read: the material without it "
                                 "stands in",
                                 name));
    }
}

/** The normal texture as the host's normal map (OpenGL convention, like glTF's). */
void normal_map(Builder& b, const tinygltf::Material& g, const std::string& mp) {
    if (g.normalTexture.index < 0) return;
    const std::string np = mp + "/normalTexture";
    auto tex = texture_desc(
        b.ctx, {g.normalTexture.index, g.normalTexture.texCoord, &g.normalTexture.extensions}, np,
        false);
    if (!tex) return;
    // A negative scale inverts the bumps, as viewers draw it (the schema has no minimum).
    double scale = std::isfinite(g.normalTexture.scale) ? g.normalTexture.scale : 1.0;
    if (scale < -10.0 || scale > 10.0)
        b.ctx.note("normal scale", b.ctx.at(np + "/scale"),
                   fmt::format("normalTexture scale {} is outside [-10, 10]: {} stands in", scale,
                               std::clamp(scale, -10.0, 10.0)));
    tex->amount = static_cast<float>(std::clamp(scale, -10.0, 10.0));
    ParamDesc p = b.base("normal_map", np);
    p.kind = ParamDesc::Kind::Texture;
    p.texture = std::move(*tex);
    b.m.maps.push_back(std::move(p));
}

/** emissiveFactor x KHR_materials_emissive_strength; with an emissive texture (sRGB), the
 *  texture scaled per channel by the factor (as the base colour's), as TOML's `emission =
 *  { texture, scale }` has it. */
/** A material's emission of colour `rgb` (linear Rec.709, written at `at_path`, not black),
 *  times the sRGB texture `tex` (at `tex_path`) where it has one that can be had (scaled per
 *  channel by rgb; its mean then weighs how brightly the emission lights the file: a helmet's
 *  few glowing lights do not light it, the studio light stands in beside them). */
EmissionDesc material_emission(Context& ctx, Vec3 rgb, const std::string& at_path,
                               const tinygltf::TextureInfo& tex, const std::string& tex_path) {
    EmissionDesc d;
    const FileLoc at = ctx.at(at_path);
    d.color = ColorDesc{rgb, std::string("lin_rec709"), at, at};
    if (tex.index >= 0) {
        d.texture = texture_desc(ctx, use_of(tex), tex_path, true);
        if (d.texture) {
            d.texture->scale[0] = rgb.x;
            d.texture->scale[1] = rgb.y;
            d.texture->scale[2] = rgb.z;
            d.color.rgb = {1, 1, 1};
            if (const std::optional<Vec3> mean = texture_mean(ctx, tex.index))
                d.mean = luminance(*mean);
        }
    }
    d.group.loc = at;
    d.of_material = true;
    return d;
}

std::optional<EmissionDesc> emission(Context& ctx, const tinygltf::Material& g,
                                     const std::string& mp) {
    Vec3 e{0, 0, 0};
    if (g.emissiveFactor.size() == 3)
        e = {narrow(g.emissiveFactor[0]), narrow(g.emissiveFactor[1]), narrow(g.emissiveFactor[2])};
    if (!std::isfinite(e.x + e.y + e.z))
        throw_error(ctx.at(mp + "/emissiveFactor"),
                    "emissiveFactor holds a number that is not a finite float");
    e = clamp3(e, 0.0f, 1.0f);
    if (!(e.x > 0 || e.y > 0 || e.z > 0)) return std::nullopt;
    EmissionDesc d = material_emission(ctx, e, mp + "/emissiveFactor", g.emissiveTexture,
                                       mp + "/emissiveTexture");
    if (const tinygltf::Value* x = extension(g, "KHR_materials_emissive_strength"))
        d.intensity = std::max(0.0, number_of(x, "emissiveStrength", 1.0));
    return d;
}

/** KHR_materials_unlit: the base colour (factor x texture) shown as it is, whatever the light:
 *  emitted, from both faces (viewers draw an unlit surface from either side), over a black
 *  surface. */
std::optional<EmissionDesc> unlit_emission(Context& ctx, const tinygltf::Material& g,
                                           const std::string& mp) {
    const std::vector<double>& f = g.pbrMetallicRoughness.baseColorFactor;
    Vec3 rgb{1, 1, 1};
    if (f.size() >= 3) rgb = {narrow(f[0]), narrow(f[1]), narrow(f[2])};
    if (!std::isfinite(rgb.x + rgb.y + rgb.z)) rgb = {1, 1, 1};
    rgb = clamp3(rgb, 0.0f, 1.0f);
    if (!(rgb.x > 0 || rgb.y > 0 || rgb.z > 0)) return std::nullopt;
    const std::string pp = mp + "/pbrMetallicRoughness";
    EmissionDesc d =
        material_emission(ctx, rgb, pp + "/baseColorFactor",
                          g.pbrMetallicRoughness.baseColorTexture, pp + "/baseColorTexture");
    if (ctx.vertex_colors)
        ctx.note("unlit vertex colours", ctx.at(mp),
                 "an unlit material's vertex colours (COLOR_0) are not shown: its base colour "
                 "is emitted, and emission does not read vertex colours");
    d.two_sided = true;
    return d;
}

/** A name unique among the scene's materials: the glTF name, else material_N; a name taken
 *  already gets _2, _3, ... */
std::string unique_name(Context& ctx, const std::string& wanted, int index) {
    const std::string base = wanted.empty() ? fmt::format("material_{}", index) : wanted;
    const auto taken = [&](const std::string& n) {
        for (const MaterialDesc& m : ctx.scene->materials)
            if (m.name == n) return true;
        return false;
    };
    std::string name = base;
    for (int k = 2; taken(name); ++k) name = fmt::format("{}_{}", base, k);
    return name;
}

}  // namespace

/** The uv set a texture reference reads. */
template <class Info>
int tex_coord_of(const Info& t) {
    return uv_set_override(&t.extensions).value_or(t.texCoord);
}

int uv_set_of(const Context& ctx, int material) {
    if (material < 0 || static_cast<std::size_t>(material) >= ctx.model.materials.size()) return 0;
    const tinygltf::Material& g = ctx.model.materials[static_cast<std::size_t>(material)];
    const std::pair<int, int> textures[] = {
        {g.pbrMetallicRoughness.baseColorTexture.index,
         tex_coord_of(g.pbrMetallicRoughness.baseColorTexture)},
        {g.pbrMetallicRoughness.metallicRoughnessTexture.index,
         tex_coord_of(g.pbrMetallicRoughness.metallicRoughnessTexture)},
        {g.normalTexture.index, tex_coord_of(g.normalTexture)},
        {g.emissiveTexture.index, tex_coord_of(g.emissiveTexture)},
        {g.occlusionTexture.index, tex_coord_of(g.occlusionTexture)}};
    for (const auto& [index, set] : textures)
        if (index >= 0) return std::max(0, set);
    if (const tinygltf::Value* x = extension(g, "KHR_materials_pbrSpecularGlossiness"))
        for (const char* key : {"diffuseTexture", "specularGlossinessTexture"})
            if (auto u = texture_in(x, key)) return std::max(0, u->tex_coord);
    return 0;
}

std::string use_material(Context& ctx, int index, std::optional<EmissionDesc>& out) {
    if (auto it = ctx.material_names.find(index); it != ctx.material_names.end()) {
        out = ctx.emissions[index];
        return it->second;
    }
    MaterialDesc m;
    Builder b{ctx, m};
    const tinygltf::Material fallback;  // glTF 2.0, 3.9.6: the default material
    const tinygltf::Material& g =
        index >= 0 ? ctx.model.materials[static_cast<std::size_t>(index)] : fallback;
    const std::string mp =
        index >= 0 ? fmt::format("materials/{}", index) : std::string("materials");
    m.name = unique_name(ctx, index >= 0 ? g.name : std::string("gltf_default"), index);
    m.loc = ctx.at(mp);
    m.name_loc = ctx.at(mp + "/name");
    m.plugin_loc = m.model_loc = m.loc;
    ctx.uv_set = uv_set_of(ctx, index);
    ctx.vertex_colors = has_vertex_colors(ctx, index);
    const bool unlit = extension(g, "KHR_materials_unlit") != nullptr;
    if (unlit) {
        b.m.plugin = "smooth";
        b.m.model = "diffuse";
        b.color("albedo", {0, 0, 0}, mp + "/extensions/KHR_materials_unlit");
    } else if (auto x = g.extensions.find("SPANGLE_materials_flakes"); x != g.extensions.end())
        flakes(b, g, mp, x->second);
    else if (const tinygltf::Value* t = extension(g, "KHR_materials_transmission");
             t && number_of(t, "transmissionFactor", 0.0) > 0.0)
        transmissive(b, g, mp, t);
    else if (const tinygltf::Value* sg = extension(g, "KHR_materials_pbrSpecularGlossiness"))
        spec_gloss(b, g, mp, sg);
    else
        metal_rough(b, g, mp);
    if (!unlit) normal_map(b, g, mp);
    alpha(b, g, mp);
    note_unread(ctx, g, mp);
    out = ctx.emissions[index] = index < 0 ? std::nullopt
                                 : unlit   ? unlit_emission(ctx, g, mp)
                                           : emission(ctx, g, mp);
    ctx.uv_set = 0;
    ctx.vertex_colors = false;
    ctx.material_names[index] = m.name;
    ctx.scene->materials.push_back(std::move(m));
    return ctx.material_names[index];
}

}  // namespace spangle::gltf
