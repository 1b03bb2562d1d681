// pbrt's materials onto the plugins' models: smooth (diffuse, conductor, dielectric, plastic)
// and flake. Each input keeps pbrt's default (written out, since Spangle's defaults differ),
// roughness is remapped as each version remaps it, and what a model cannot carry is dropped
// with one warning naming what stands in. docs/pbrt.md has the table.

#include <cmath>
#include <cstdio>
#include <fstream>

#include "scene/pbrt/pbrt_spectra.h"
#include "scene/pbrt/pbrt_state.h"

namespace spangle::pbrt {

namespace {

/** Which remapping of "roughness" a material's version uses. */
enum class Remap { V3, V4 };

/** Builds one MaterialDesc from a pbrt material's parameters. */
class MaterialBuilder {
public:
    MaterialBuilder(Reader& r, const ParamList& p, const FileLoc& loc, std::string type)
        : r_(r), p_(p), loc_(loc), type_(std::move(type)) {
        m_.loc = loc;
        m_.name_loc = loc;
        m_.plugin_loc = loc;
        m_.model_loc = loc;
    }

    /** Sets the plugin and model. */
    void model(const char* plugin, const char* model) {
        m_.plugin = plugin;
        m_.model = model;
    }

    /** A note about this material. */
    void note(const std::string& what) {
        r_.notes.add(loc_, fmt::format("Material \"{}\": {}", type_, what));
    }

    /** A number parameter. */
    void number(const char* name, double v) {
        ParamDesc d;
        d.name = name;
        d.number = v;
        d.loc = d.key_loc = loc_;
        m_.params.push_back(std::move(d));
    }

    /** An integer parameter (a plugin refuses a seed written as a float). */
    void integer(const char* name, double v) {
        number(name, v);
        m_.params.back().is_integer = true;
    }

    /** A true/false parameter. */
    void boolean(const char* name, bool v) {
        number(name, v ? 1.0 : 0.0);
        m_.params.back().kind = ParamDesc::Kind::Bool;
    }

    /** A string parameter. */
    void string(const char* name, const std::string& v) {
        ParamDesc d;
        d.name = name;
        d.kind = ParamDesc::Kind::String;
        d.text = v;
        d.loc = d.key_loc = loc_;
        m_.params.push_back(std::move(d));
    }

    /** A three-number parameter (a colour or a vec3 such as eta). */
    void triple(const char* name, const ColorDesc& c) {
        ParamDesc d;
        d.name = name;
        d.kind = ParamDesc::Kind::Color;
        d.color = c;
        d.loc = d.key_loc = c.loc.file.empty() ? loc_ : c.loc;
        m_.params.push_back(std::move(d));
    }

    /** The named texture `name` of `table`, or null with a warning. */
    const TextureValue* texture(const Param& q, bool color) {
        const auto& table = color ? r_.color_textures : r_.float_textures;
        const auto& other = color ? r_.float_textures : r_.color_textures;
        const std::string& name = q.strings.empty() ? std::string() : q.strings[0];
        if (const auto it = table.find(name); it != table.end()) return &it->second;
        if (const auto it = other.find(name); it != other.end()) return &it->second;
        r_.notes.add(q.loc, fmt::format("texture '{}' is not defined: the default of '{}' "
                                        "stands in",
                                        name, q.name));
        return nullptr;
    }

    /** The colour input `pbrt` (texture, rgb, spectrum, blackbody or a grey float) as the
     *  model's `name`, pbrt's default `fallback`, clamped to [0, 1] (albedos). */
    void color(const char* pbrt, const char* name, Vec3 fallback) {
        ParamDesc d;
        d.name = name;
        d.loc = d.key_loc = loc_;
        if (const Param* t = p_.find(pbrt, {"texture"})) {
            if (const TextureValue* v = texture(*t, true)) {
                if (v->image) {
                    d.kind = ParamDesc::Kind::Texture;
                    d.texture = v->tex;
                    d.loc = d.key_loc = t->loc;
                    m_.params.push_back(std::move(d));
                    return;
                }
                fallback = v->value;
            }
        } else if (auto c = color_param(r_, p_, pbrt, false)) {
            triple(name, clamp01(*c, pbrt));
            return;
        } else if (const Param* f = p_.find(pbrt, {"float"}); f && !f->numbers.empty()) {
            fallback = Vec3(static_cast<float>(f->numbers[0]));
        }
        triple(name, clamp01(r_.color(fallback, loc_), pbrt));
    }

    /** A colour clamped to [0, 1], with a note when it was not. */
    ColorDesc clamp01(ColorDesc c, const char* pbrt) {
        const Vec3 v = c.rgb;
        c.rgb = Vec3(std::clamp(v.x, 0.0f, 1.0f), std::clamp(v.y, 0.0f, 1.0f),
                     std::clamp(v.z, 0.0f, 1.0f));
        if (!(c.rgb == v)) note(fmt::format("'{}' outside [0, 1] is clamped into it", pbrt));
        return c;
    }

    /** A constant colour of `pbrt` (for checks that a weight is 1), or `fallback`. */
    Vec3 constant(const char* pbrt, Vec3 fallback) {
        if (p_.find(pbrt, {"texture"})) return Vec3(-1.0f);
        if (auto c = color_param(r_, p_, pbrt, false)) return c->rgb;
        if (const Param* f = p_.find(pbrt, {"float"}); f && !f->numbers.empty())
            return Vec3(static_cast<float>(f->numbers[0]));
        return fallback;
    }

    /** GGX alpha of pbrt's roughness `v` under `remap`. */
    static double alpha(double v, Remap remap) {
        if (v <= 0.0) return 0.0;
        if (remap == Remap::V4) return std::sqrt(v);
        // pbrt-v3's TrowbridgeReitzDistribution::RoughnessToAlpha: a quartic in log(roughness).
        const double x = std::log(std::max(v, 1e-3));
        return 1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x * x * x +
               0.000640711 * x * x * x * x;
    }

    /** A roughness input `pbrt` (a float or a float texture) as `name`, remapped. */
    void roughness(const char* pbrt, const char* name, double fallback, Remap remap,
                   bool remap_on) {
        if (const Param* t = p_.find(pbrt, {"texture"})) {
            if (const TextureValue* v = texture(*t, false)) {
                // Spangle's plastic (coateddiffuse, v3 plastic, uber, substrate) tabulates its
                // coat's albedo for one roughness: it takes a constant, the material's default.
                if (v->image && (m_.model == "plastic" || std::string(name) == "coat_roughness")) {
                    note(fmt::format(
                        "a texture of '{}' is not supported on this material (its coat takes one "
                        "roughness): '{}' {} stands in",
                        pbrt, pbrt, fallback));
                } else if (v->image) {
                    if (remap_on)
                        note(
                            fmt::format("a texture of '{}' cannot be remapped: its values are "
                                        "used as GGX alpha",
                                        pbrt));
                    ParamDesc d;
                    d.name = name;
                    d.kind = ParamDesc::Kind::Texture;
                    d.texture = v->tex;
                    d.loc = d.key_loc = t->loc;
                    m_.params.push_back(std::move(d));
                    return;
                } else {
                    fallback = v->value.x;
                }
            }
        } else {
            fallback = p_.number(pbrt, fallback);
        }
        double a = remap_on ? alpha(fallback, remap) : fallback;
        if (!(a >= 0.0 && a <= 1.0)) {
            note(
                fmt::format("'{}' {} is GGX alpha {}, outside [0, 1]: clamped", pbrt, fallback, a));
            a = std::clamp(a, 0.0, 1.0);
        }
        number(name, a);
    }

    /** "roughness", or "uroughness" and "vroughness", as roughness / roughness_v. */
    void roughness_uv(double fallback, Remap remap) {
        const bool remap_on = p_.boolean("remaproughness", true);
        const bool aniso = p_.find("uroughness") || p_.find("vroughness");
        if (aniso) {
            roughness("uroughness", "roughness", fallback, remap, remap_on);
            roughness("vroughness", "roughness_v", fallback, remap, remap_on);
        } else {
            roughness("roughness", "roughness", fallback, remap, remap_on);
        }
    }

    /** An index of refraction `pbrt` (float, or a named glass spectrum) as `name`. */
    void ior(const char* pbrt, const char* name, double fallback) {
        double eta = fallback;
        if (const Param* q = p_.find(pbrt, {"float"}); q && !q->numbers.empty()) {
            eta = q->numbers[0];
        } else if (const Param* s = p_.find(pbrt, {"spectrum"})) {
            const auto glass = s->strings.empty() ? std::nullopt : named_glass_ior(s->strings[0]);
            if (glass)
                eta = *glass;
            else if (s->strings.empty() && s->numbers.size() >= 2)
                eta = spectrum_at(s->numbers, 587.6);  // the d line, as glass indices are quoted
            else
                note(fmt::format("spectrum '{}' is no known glass: {} stands in", pbrt, eta));
        }
        if (eta < 1.0 && eta > 0.0) {
            note(
                fmt::format("'{}' {} < 1 is read as its inverse {} (Spangle's index is inside "
                            "over outside)",
                            pbrt, eta, 1.0 / eta));
            eta = 1.0 / eta;
        }
        if (!(eta >= 1.0 && eta <= 10.0)) {
            note(fmt::format("'{}' {} is outside [1, 10]: clamped", pbrt, eta));
            eta = std::clamp(eta, 1.0, 10.0);
        }
        number(name, eta);
    }

    /** The conductor's index: "eta" and "k" (named metals, rgb, spectra) or "reflectance". */
    void metal(const char* eta_name, const char* k_name, const char* refl_name) {
        if (refl_name && p_.find(refl_name)) {
            // Index 1 with the extinction that gives the same normal-incidence reflectance:
            // F0 = k^2 / (4 + k^2), so k = 2 sqrt(F0 / (1 - F0)).
            const Vec3 f0 = constant(refl_name, Vec3(1.0f));
            if (f0.x < 0.0f) {
                note(fmt::format("a texture of '{}' is not supported: its metal is copper",
                                 refl_name));
                string("preset", "copper");
                return;
            }
            const auto k = [](float f) {
                const double c = std::clamp(static_cast<double>(f), 0.0, 0.9996);
                return static_cast<float>(2.0 * std::sqrt(c / (1.0 - c)));
            };
            string("preset", "custom");
            triple("eta", r_.color(Vec3(1.0f), loc_));
            triple("k", r_.color(Vec3(k(f0.x), k(f0.y), k(f0.z)), loc_));
            return;
        }
        const Param* eta = p_.find(eta_name, {"spectrum", "rgb", "float"});
        const Param* k = p_.find(k_name, {"spectrum", "rgb", "float"});
        if (!eta && !k) {
            string("preset", "copper");  // pbrt's default metal in both versions
            return;
        }
        if (eta && eta->type == "spectrum" && !eta->strings.empty() &&
            eta->strings[0].rfind("metal-", 0) == 0) {
            const auto named = named_metal(eta->strings[0]);
            if (!named) {
                note(fmt::format("unknown metal \"{}\": copper stands in", eta->strings[0]));
                string("preset", "copper");
                return;
            }
            if (named->stand_in)
                note(fmt::format("no optical data for \"{}\" here: {} stands in", eta->strings[0],
                                 named->preset == "custom" ? fmt::format("eta {} k 0", named->eta.x)
                                                           : named->preset));
            string("preset", named->preset);
            if (named->preset == "custom") {
                triple("eta", r_.color(named->eta, loc_));
                triple("k", r_.color(named->k, loc_));
            }
            return;
        }
        string("preset", "custom");
        triple("eta", r_.color(band_values(eta, Vec3(0.2f, 0.924f, 1.102f)), loc_));
        triple("k", r_.color(band_values(k, Vec3(3.912f, 2.452f, 2.142f)), loc_));
    }

    /** A spectral index at the Rec.709 bands (630, 532, 465 nm), or `fallback` (copper). */
    Vec3 band_values(const Param* q, Vec3 fallback) {
        if (!q) return fallback;
        if (q->type == "rgb" && q->numbers.size() == 3)
            return Vec3(static_cast<float>(q->numbers[0]), static_cast<float>(q->numbers[1]),
                        static_cast<float>(q->numbers[2]));
        if (q->type == "float" && !q->numbers.empty())
            return Vec3(static_cast<float>(q->numbers[0]));
        std::vector<double> s = q->numbers;
        if (!q->strings.empty()) {
            if (auto named = named_metal(q->strings[0])) {
                note(fmt::format("\"{}\" with a custom partner: copper's index stands in",
                                 q->strings[0]));
                return fallback;
            }
            s.clear();
            const std::string path = r_.find_file(q->strings[0], "spectrum", q->loc);
            r_.d.files.push_back(path);
            std::ifstream in(path);
            double x = 0.0;
            std::string word;
            while (in >> word)
                if (word[0] != '#' && std::sscanf(word.c_str(), "%lf", &x) == 1) s.push_back(x);
        }
        if (s.size() < 2) return fallback;
        return Vec3(static_cast<float>(spectrum_at(s, 630.0)),
                    static_cast<float>(spectrum_at(s, 532.0)),
                    static_cast<float>(spectrum_at(s, 465.0)));
    }

    /** The bump or normal map ("bumpmap" v3, "displacement" v4, "normalmap" v4). */
    void maps() {
        const Param* bump = p_.find("bumpmap", {"texture"});
        if (!bump) bump = p_.find("displacement", {"texture"});
        const std::string normal = p_.string("normalmap", "");
        if (!normal.empty()) {
            ParamDesc d;
            d.name = "normal_map";
            d.kind = ParamDesc::Kind::Texture;
            d.loc = d.key_loc = loc_;
            d.texture.path = r_.find_file(normal, "normalmap", loc_);
            d.texture.space = "raw";
            m_.maps.push_back(std::move(d));
            if (bump) note("a bump map and a normal map: the normal map is used");
            return;
        }
        if (!bump) return;
        const TextureValue* v = texture(*bump, false);
        if (!v || !v->image) return;  // a constant displacement does not bump
        ParamDesc d;
        d.name = "bump_map";
        d.kind = ParamDesc::Kind::Texture;
        d.loc = d.key_loc = bump->loc;
        d.texture = v->tex;
        // pbrt displaces by the texture's value in scene units: a height of 1 per unit value.
        d.texture.amount = std::clamp(d.texture.scale[0], -1.0f, 1.0f);
        d.texture.scale[0] = d.texture.scale[1] = d.texture.scale[2] = 1.0f;
        // The float texture's own encoding: an 8-bit image is sRGB-decoded unless it says
        // "linear", as pbrt-v3 and v4 read float image maps (it was read raw).
        m_.maps.push_back(std::move(d));
    }

    /** The description, named `name`. */
    MaterialDesc take(std::string name) {
        m_.name = std::move(name);
        return std::move(m_);
    }

private:
    Reader& r_;
    const ParamList& p_;
    FileLoc loc_;
    std::string type_;
    MaterialDesc m_;
};

/** A name no material has yet, `base`, else base#2, base#3, ...; taken from now on. */
std::string unique_name(Reader& r, const std::string& base) {
    std::string name = base;
    for (int k = 2; r.material_names.count(name); ++k) name = fmt::format("{}#{}", base, k);
    r.material_names.insert(name);
    return name;
}

/** The v3 materials. Returns false for a type that is not one of them. */
bool v3_material(MaterialBuilder& b, const std::string& t, const ParamList& p) {
    if (t == "matte") {
        b.model("smooth", "diffuse");
        b.color("Kd", "albedo", Vec3(0.5f));
        const Param* sigma = p.find("sigma", {"float", "texture"});
        if (sigma &&
            (sigma->type == "texture" || (!sigma->numbers.empty() && sigma->numbers[0] != 0.0)))
            b.note("Oren-Nayar 'sigma' is not supported: Lambert stands in");
    } else if (t == "plastic") {
        b.model("smooth", "plastic");
        b.color("Kd", "albedo", Vec3(0.25f));
        b.number("ior", 1.5);
        b.roughness_uv(0.1, Remap::V3);
        if (!(b.constant("Ks", Vec3(0.25f)) == Vec3(1.0f)))
            b.note("'Ks' is not supported: the coat reflects as a dielectric of index 1.5 (Ks 1)");
        p.find("Ks");
    } else if (t == "metal") {
        b.model("smooth", "conductor");
        b.boolean("multiscatter", false);  // pbrt's GGX scatters once
        b.metal("eta", "k", nullptr);
        b.roughness_uv(0.01, Remap::V3);
    } else if (t == "mirror") {
        b.model("smooth", "conductor");
        b.string("preset", "perfect");
        b.number("roughness", 0.0);
        if (!(b.constant("Kr", Vec3(0.9f)) == Vec3(1.0f)))
            b.note(p.find("Kr")
                       ? "'Kr' is not supported: a perfect mirror (Kr 1) stands in"
                       : "a mirror reflects pbrt-v3's default 'Kr' 0.9 at every angle: a perfect "
                         "mirror (1) stands in");
        p.find("Kr");
    } else if (t == "glass") {
        b.model("smooth", "dielectric");
        if (p.find("index"))
            b.ior("index", "ior", 1.5);
        else
            b.ior("eta", "ior", 1.5);
        b.roughness_uv(0.0, Remap::V3);
        if (!(b.constant("Kr", Vec3(1.0f)) == Vec3(1.0f)) ||
            !(b.constant("Kt", Vec3(1.0f)) == Vec3(1.0f)))
            b.note("'Kr' and 'Kt' are not supported: clear glass (1, 1) stands in");
        for (const char* k : {"Kr", "Kt"}) p.find(k);  // said above, not again as dropped
    } else if (t == "uber") {
        b.model("smooth", "plastic");
        b.color("Kd", "albedo", Vec3(0.25f));
        // pbrt-v3's uber takes "index" where "eta" is not given.
        b.ior(p.find("eta") || !p.find("index") ? "eta" : "index", "ior", 1.5);
        b.roughness_uv(0.1, Remap::V3);
        for (const char* k : {"Ks", "Kr", "Kt", "opacity"}) p.find(k);
        b.note(
            "a plastic (Kd under a coat of index eta) stands in; 'Ks', 'Kr', 'Kt' and "
            "'opacity' are dropped");
    } else if (t == "substrate") {
        b.model("smooth", "plastic");
        b.color("Kd", "albedo", Vec3(0.5f));
        b.number("ior", 1.5);
        b.roughness_uv(0.1, Remap::V3);
        p.find("Ks");
        b.note("a plastic stands in: 'Ks' is dropped (the coat reflects as index 1.5)");
    } else if (t == "flake") {
        // The seed report's pbrt-v3 material: Kd the paint, Ks the flakes, roughness the flake
        // normals' GGX alpha, gamma (or coneangle) the cone of each flake in degrees.
        b.model("flake", "flake");
        b.color("Kd", "base_color", Vec3(0.05f));
        b.color("Ks", "flake_color", Vec3(1.0f));
        b.number("flake_roughness", std::clamp(p.number("roughness", 0.15), 0.001, 1.0));
        const double gamma =
            p.find("coneangle") ? p.number("coneangle", 3.0) : p.number("gamma", 3.0);
        b.number("gamma", std::clamp(gamma, 0.01, 45.0));
        if (p.find("density", {"float", "integer"}))
            b.number("density", std::max(1.0, p.number("density", 2e5)));
        if (p.find("seed", {"integer"}))
            b.integer("seed", std::clamp(p.number("seed", 0), 0.0, 2147483647.0));
    } else {
        return false;
    }
    return true;
}

/** The v4 materials. Returns false for a type that is not one of them. */
bool v4_material(MaterialBuilder& b, const std::string& t, const ParamList& p) {
    if (t == "diffuse") {
        b.model("smooth", "diffuse");
        b.color("reflectance", "albedo", Vec3(0.5f));
    } else if (t == "coateddiffuse") {
        b.model("smooth", "plastic");
        b.color("reflectance", "albedo", Vec3(0.5f));
        b.ior("eta", "ior", 1.5);
        b.roughness_uv(0.0, Remap::V4);
    } else if (t == "conductor") {
        b.model("smooth", "conductor");
        b.boolean("multiscatter", false);  // pbrt's GGX scatters once
        b.metal("eta", "k", "reflectance");
        b.roughness_uv(0.0, Remap::V4);
    } else if (t == "coatedconductor") {
        b.model("smooth", "conductor");
        b.boolean("multiscatter", false);  // pbrt's GGX scatters once
        b.metal("conductor.eta", "conductor.k", "reflectance");
        const bool remap_on = p.boolean("remaproughness", true);
        if (p.find("conductor.uroughness") || p.find("conductor.vroughness")) {
            // Each falls back to conductor.roughness, as in pbrt-v4.
            const double both = p.number("conductor.roughness", 0.0);
            b.roughness("conductor.uroughness", "roughness", both, Remap::V4, remap_on);
            b.roughness("conductor.vroughness", "roughness_v", both, Remap::V4, remap_on);
        } else {
            b.roughness("conductor.roughness", "roughness", 0.0, Remap::V4, remap_on);
        }
        // The coat: the conductor's own (a clear dielectric over the metal, whose index it
        // takes relative to the coat's, as pbrt-v4 does).
        b.number("coat", 1.0);
        b.ior("interface.eta", "coat_ior", 1.5);
        if (p.find("interface.uroughness") || p.find("interface.vroughness")) {
            b.roughness("interface.uroughness", "coat_roughness",
                        p.number("interface.roughness", 0.0), Remap::V4, remap_on);
            p.find("interface.vroughness");
            b.note("the coat takes one roughness: 'interface.uroughness' stands in for both");
        } else {
            b.roughness("interface.roughness", "coat_roughness", 0.0, Remap::V4, remap_on);
        }
    } else if (t == "dielectric" || t == "thindielectric") {
        b.model("smooth", "dielectric");
        b.ior("eta", "ior", 1.5);
        if (t == "dielectric")
            b.roughness_uv(0.0, Remap::V4);
        else
            b.note("a solid dielectric of the same index stands in for the thin one");
    } else if (t == "diffusetransmission") {
        b.model("smooth", "diffuse");
        b.color("reflectance", "albedo", Vec3(0.25f));
        p.find("transmittance");
        b.note("a diffuse reflector of its 'reflectance' stands in: 'transmittance' is dropped");
    } else {
        return false;
    }
    return true;
}

/** Whether `t` names a material of pbrt-v4 only. */
bool is_v4_type(const std::string& t) {
    for (const char* n : {"diffuse", "coateddiffuse", "conductor", "coatedconductor", "dielectric",
                          "thindielectric", "diffusetransmission", "interface"})
        if (t == n) return true;
    return false;
}

/** Whether `t` names a material of pbrt-v3 only. */
bool is_v3_type(const std::string& t) {
    for (const char* n : {"matte", "plastic", "metal", "mirror", "glass", "uber", "substrate",
                          "translucent", "kdsubsurface", "fourier", "disney", "flake"})
        if (t == n) return true;
    return false;
}

/** v3's and v4's mix: the heavier material stands in. */
std::string mix_material(Reader& r, const ParamList& p, const std::string& name,
                         const FileLoc& loc) {
    std::string first, second;
    double w_second = 0.5;  // the weight of the second material
    if (const Param* ms = p.find("materials", {"string"}); ms && ms->strings.size() == 2) {
        r.sign(true, loc, "Material \"mix\" \"materials\"");
        first = ms->strings[0];
        second = ms->strings[1];
        w_second = p.number("amount", 0.5);  // v4: amount is the chance of the second
    } else {
        first = p.string("namedmaterial1", "");
        second = p.string("namedmaterial2", "");
        // v3: amount weighs namedmaterial1 (its colour's mean when it is an rgb).
        double a = p.number("amount", 0.5);
        if (auto c = color_param(r, p, "amount", false))
            a = static_cast<double>(c->rgb.x + c->rgb.y + c->rgb.z) / 3.0;
        w_second = 1.0 - a;
    }
    p.find("amount");
    const std::string& pick = w_second > 0.5 ? second : first;
    r.notes.add(loc, fmt::format("Material \"mix\": blends are not supported: its heavier "
                                 "material '{}' stands in",
                                 pick));
    const auto it = r.materials.find(pick);
    if (it == r.materials.end()) {
        // Maybe defined further on (pbrt-v4 resolves names once the scene is read): pending, as
        // a NamedMaterial of it is; said at the end when it never is.
        if (r.pending_materials.emplace(pick, loc).second) r.pending_from_mix.insert(pick);
        return std::string(kPendingMaterial) + pick;
    }
    if (it->second.empty()) return default_material(r, loc);
    if (name.empty()) return it->second;
    // A named mix is a material of its own name (an [[import]] override can replace it).
    for (const MaterialDesc& m : r.d.materials)
        if (m.name == it->second) {
            MaterialDesc copy = m;
            copy.name = unique_name(r, name);
            copy.loc = copy.name_loc = loc;
            r.d.materials.push_back(copy);
            return r.d.materials.back().name;
        }
    return it->second;
}

}  // namespace

std::string default_material(Reader& r, const FileLoc& loc) {
    if (r.default_material.empty()) {
        // pbrt's default in both versions: a diffuse reflector of 0.5.
        MaterialDesc m;
        m.name = unique_name(r, "pbrt_default");
        m.plugin = "smooth";
        m.model = "diffuse";
        m.loc = m.name_loc = m.plugin_loc = m.model_loc = loc;
        ParamDesc d;
        d.name = "albedo";
        d.kind = ParamDesc::Kind::Color;
        d.color.rgb = Vec3(0.5f);
        d.color.loc = d.color.space_loc = d.loc = d.key_loc = loc;
        m.params.push_back(std::move(d));
        r.default_material = m.name;
        r.d.materials.push_back(std::move(m));
    }
    return r.default_material;
}

std::string read_material(Reader& r, const std::string& type, const std::string& name, ParamList& p,
                          const FileLoc& loc) {
    const std::string what = name.empty() ? fmt::format("Material \"{}\"", type)
                                          : fmt::format("MakeNamedMaterial \"{}\"", name);
    if (type == "" || type == "none" || type == "interface") {
        if (type == "interface") r.sign(true, loc, "Material \"interface\"");
        for (const Param& q : p.all()) q.used = true;
        return "";
    }
    if (type == "mix") {
        const std::string m = mix_material(r, p, name, loc);
        r.notes.unused(p, what);
        return m;
    }
    if (is_v4_type(type)) r.sign(true, loc, "a pbrt-v4 material");
    if (is_v3_type(type)) r.sign(false, loc, "a pbrt-v3 material");
    MaterialBuilder b(r, p, loc, type);
    if (!v3_material(b, type, p) && !v4_material(b, type, p)) {
        b.model("smooth", "diffuse");
        const bool v4 = p.find("reflectance") != nullptr;
        b.color(v4 ? "reflectance" : "Kd", "albedo", Vec3(0.5f));
        for (const Param& q : p.all()) q.used = true;
        // Another pbrt type (hair, measured, subsurface) is one Spangle lacks; any other name
        // is no pbrt material at all (a typo: pbrt refuses the file).
        const bool known = is_v4_type(type) || is_v3_type(type) || type == "hair" ||
                           type == "measured" || type == "subsurface";
        b.note(known ? "not supported; a diffuse reflector of its colour (or 0.5) stands in"
                     : "not a pbrt material type (pbrt-v4's: diffuse, coateddiffuse, "
                       "conductor, coatedconductor, dielectric, thindielectric, "
                       "diffusetransmission, mix, interface, hair, measured, subsurface): a "
                       "diffuse reflector of its colour (or 0.5) stands in");
    }
    b.maps();
    p.string("type", "");
    r.notes.unused(p, what);
    MaterialDesc m =
        b.take(unique_name(r, name.empty() ? fmt::format("{}#{}", type, ++r.anonymous) : name));
    if (!name.empty() && m.name != name)
        r.notes.add(loc, fmt::format("material '{}' is defined again: the later definition is "
                                     "'{}' (shapes that follow use it)",
                                     name, m.name));
    r.d.materials.push_back(std::move(m));
    return r.d.materials.back().name;
}

}  // namespace spangle::pbrt
