// pbrt's textures and colour-valued parameters: image maps become Spangle texture lookups (their
// uv scale and offset, wrap, encoding and scale), constants stay constants, scale and mix of a
// constant and an image fold into the image's scale; procedural textures are baked to a constant
// with a warning. Colours: rgb as written, spectra and blackbodies through the CIE 1931 curves.

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/text.h"
#include "scene/pbrt/pbrt_spectra.h"
#include "scene/pbrt/pbrt_state.h"

namespace spangle::pbrt {

namespace {

/** Whether an image file holds 8-bit values, which pbrt decodes from sRGB by default. */
bool eight_bit(const std::string& path) {
    const std::string ext = ascii_lower(std::filesystem::path(path).extension().string());
    return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tga" || ext == ".bmp" ||
           ext == ".gif";
}

/** The numbers of a spectrum file (pbrt's .spd: lambda-value pairs, '#' comments). */
std::vector<double> spd_file(Reader& r, const std::string& given, const FileLoc& at) {
    const std::string path = r.find_file(given, "spectrum", at);
    r.d.files.push_back(path);
    std::ifstream in(path);
    std::vector<double> v;
    std::string line;
    while (std::getline(in, line)) {
        line = line.substr(0, line.find('#'));
        std::istringstream s(line);
        double x = 0.0;
        while (s >> x) v.push_back(x);
    }
    if (v.size() < 2 || v.size() % 2 != 0)
        throw_error(at, "spectrum file '{}' must hold wavelength-value pairs", path);
    return v;
}

/** An imagemap texture's lookup. */
TextureValue imagemap(Reader& r, const std::string& kind, const ParamList& p, const FileLoc& loc) {
    TextureValue t;
    t.image = true;
    t.loc = loc;
    const std::string file = p.string("filename", "");
    if (file.empty()) throw_error(loc, "imagemap needs \"string filename\"");
    TextureDesc& tex = t.tex;
    tex.path = r.find_file(file, "imagemap filename", loc);
    tex.space_loc = loc;
    // pbrt's (s, t) = (uscale u + udelta, vscale v + vdelta); both read images with t = 0 at
    // the bottom row, as Spangle does.
    tex.uv[0] = static_cast<float>(p.number("uscale", 1.0));
    tex.uv[2] = static_cast<float>(p.number("udelta", 0.0));
    tex.uv[4] = static_cast<float>(p.number("vscale", 1.0));
    tex.uv[5] = static_cast<float>(p.number("vdelta", 0.0));
    const std::string mapping = p.string("mapping", "uv");
    if (mapping != "uv")
        r.notes.add(loc, fmt::format("texture mapping \"{}\" is not supported: the mesh's uv "
                                     "stands in",
                                     mapping));
    const std::string wrap = p.string("wrap", "repeat");
    tex.wrap = wrap == "clamp" ? 1 : wrap == "black" ? 2 : 0;
    if (wrap != "repeat" && wrap != "clamp" && wrap != "black")
        r.notes.add(loc,
                    fmt::format("texture wrap \"{}\" is not supported: repeat stands in", wrap));
    bool srgb = eight_bit(tex.path);
    if (const Param* g = p.find("gamma", {"bool"}); g && !g->bools.empty()) srgb = g->bools[0];
    if (const Param* e = p.find("encoding", {"string"}); e && !e->strings.empty()) {
        const std::string& enc = e->strings[0];
        if (enc == "sRGB") {
            srgb = true;
        } else if (enc == "linear") {
            srgb = false;
        } else {
            r.notes.add(e->loc, fmt::format("texture encoding \"{}\" is not supported: sRGB "
                                            "stands in",
                                            enc));
            srgb = true;
        }
    }
    // Images that are not 8-bit are linear whatever the encoding says (as in pbrt).
    if (!eight_bit(tex.path)) srgb = false;
    if (kind == "float")
        tex.space = srgb ? std::optional<std::string>("srgb_texture") : "raw";
    else
        tex.space = srgb ? std::string("srgb_texture") : r.gs.space.value_or("lin_rec709");
    const auto k = static_cast<float>(p.number("scale", 1.0));
    tex.scale[0] = tex.scale[1] = tex.scale[2] = k;
    if (p.boolean("invert", false))
        r.notes.add(loc, "imagemap \"invert\" is not supported: the image is used as it is");
    const std::string filter = p.string("filter", "bilinear");
    tex.filter = filter == "ewa" ? 1 : 0;
    p.number("maxanisotropy", 8.0);
    p.boolean("trilinear", false);
    return t;
}

/** A constant of a texture's operand `name`: "float" / "rgb" / "spectrum", or `fallback`. */
std::optional<Vec3> constant_operand(Reader& r, const ParamList& p, const char* name) {
    if (const Param* f = p.find(name, {"float"}); f && !f->numbers.empty())
        return Vec3(static_cast<float>(f->numbers[0]));
    if (auto c = color_param(r, p, name, false)) return c->rgb;
    return std::nullopt;
}

/** The texture operand `name` of a scale or mix texture: a named texture or a constant. */
TextureValue operand(Reader& r, const std::string& kind, const ParamList& p, const char* name,
                     Vec3 fallback, const FileLoc& loc) {
    if (const Param* t = p.find(name, {"texture"}); t && !t->strings.empty()) {
        auto& table = kind == "float" ? r.float_textures : r.color_textures;
        const auto it = table.find(t->strings[0]);
        if (it != table.end()) return it->second;
        // pbrt-v4's scale of a spectrum texture is a float texture (a grey factor).
        if (kind != "float")
            if (const auto f = r.float_textures.find(t->strings[0]); f != r.float_textures.end())
                return f->second;
        r.notes.add(t->loc, fmt::format("texture '{}' is not defined: {} stands in", t->strings[0],
                                        fallback.x));
    }
    TextureValue v;
    v.value = constant_operand(r, p, name).value_or(fallback);
    v.loc = loc;
    return v;
}

/** A scale texture: an image times a constant folds into the image's scale. */
TextureValue scale_texture(Reader& r, const std::string& kind, const ParamList& p,
                           const FileLoc& loc) {
    const bool v3 = p.find("tex1") != nullptr || p.find("tex2") != nullptr;
    TextureValue a = operand(r, kind, p, v3 ? "tex1" : "tex", Vec3(1.0f), loc);
    TextureValue b = operand(r, kind, p, v3 ? "tex2" : "scale", Vec3(1.0f), loc);
    if (a.image && b.image) {
        r.notes.add(loc,
                    "a scale texture of two images is not supported: the first image "
                    "stands in");
        return a;
    }
    if (b.image) std::swap(a, b);
    if (!a.image) {
        a.value = a.value * b.value;
        return a;
    }
    for (int c = 0; c < 3; ++c) a.tex.scale[c] *= b.value[c];
    return a;
}

/** A mix texture: constants blend; with an image, the heavier operand stands in. */
TextureValue mix_texture(Reader& r, const std::string& kind, const ParamList& p,
                         const FileLoc& loc) {
    const TextureValue a = operand(r, kind, p, "tex1", Vec3(0.0f), loc);
    const TextureValue b = operand(r, kind, p, "tex2", Vec3(1.0f), loc);
    const TextureValue amount = operand(r, "float", p, "amount", Vec3(0.5f), loc);
    if (!a.image && !b.image && !amount.image) {
        TextureValue v = a;
        v.value = a.value * (1.0f - amount.value.x) + b.value * amount.value.x;
        return v;
    }
    if (!a.image && !b.image) {
        // Constant operands blended by an image: their average (amount 0.5) stands in.
        r.notes.add(loc,
                    "a mix texture whose 'amount' is an image is not supported: the average of "
                    "its two operands stands in");
        TextureValue v = a;
        v.value = (a.value + b.value) * 0.5f;
        return v;
    }
    const bool second = !amount.image && amount.value.x > 0.5f;
    r.notes.add(loc, fmt::format("a mix texture of images is not supported: its {} operand "
                                 "stands in",
                                 second ? "second" : "first"));
    return second ? b : a;
}

}  // namespace

std::optional<ColorDesc> color_param(Reader& r, const ParamList& p, const char* name,
                                     bool illuminant) {
    const Param* q = p.find(name, {"rgb", "spectrum", "blackbody", "xyz"});
    if (!q) return std::nullopt;
    ColorDesc c = r.color(Vec3(0.0f), q->loc);
    const auto& v = q->numbers;
    if (q->type == "rgb") {
        if (v.size() != 3) throw_error(q->loc, "'rgb {}' needs 3 numbers, got {}", name, v.size());
        c.rgb = Vec3(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
        return c;
    }
    c.space = "lin_rec709";  // computed from a spectrum: linear Rec.709 whatever ColorSpace says
    if (q->type == "xyz") {
        if (v.size() != 3) throw_error(q->loc, "'xyz {}' needs 3 numbers, got {}", name, v.size());
        c.rgb = xyz_to_rec709(
            Vec3(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])));
        return c;
    }
    if (q->type == "blackbody") {
        // v3: [kelvin scale], the spectrum's peak normalised to 1; v4: kelvin, and a light's
        // spectrum normalised to unit luminance.
        if (v.empty() || v.size() > 2)
            throw_error(q->loc,
                        "'blackbody {}' needs a temperature (v4) or [temperature scale] "
                        "(v3)",
                        name);
        r.sign(v.size() == 1, q->loc, v.size() == 1 ? "a one-number blackbody" : "blackbody [T s]");
        // A temperature of 0 or below (or beyond any star's) is no blackbody: it emitted black
        // with only "the scene has no light" to say so.
        if (!(v[0] > 0.0 && v[0] <= 1e6))
            throw_error(q->loc,
                        "'blackbody {}' has temperature {} K; it must be above 0 (up to 1e6)", name,
                        v[0]);
        c.rgb = blackbody_rgb(v[0]);
        if (v.size() == 2)
            c.rgb *= static_cast<float>(v[1]);
        else if (illuminant)
            c.rgb = unit_luminance(c.rgb);
        return c;
    }
    if (!q->strings.empty()) {
        const std::string& s = q->strings[0];
        bool exact = true;
        if (auto ill = named_illuminant(s, exact)) {
            if (!exact)
                r.notes.add(q->loc, fmt::format("spectrum \"{}\": a blackbody of its colour "
                                                "temperature stands in",
                                                s));
            c.rgb = *ill;
            return c;
        }
        if (s.rfind("metal-", 0) == 0 || s.rfind("glass-", 0) == 0) {
            r.notes.add(q->loc, fmt::format("spectrum \"{}\" is no colour: white stands in for "
                                            "'{}'",
                                            s, name));
            c.rgb = Vec3(1.0f);
            return c;
        }
        const std::vector<double> pairs = spd_file(r, s, q->loc);
        c.rgb = illuminant ? sampled_spectrum_rgb(pairs) : reflectance_spectrum_rgb(pairs);
    } else {
        if (v.size() < 2 || v.size() % 2 != 0)
            throw_error(q->loc, "'spectrum {}' needs wavelength-value pairs", name);
        c.rgb = illuminant ? sampled_spectrum_rgb(v) : reflectance_spectrum_rgb(v);
    }
    if (illuminant && r.v4()) c.rgb = unit_luminance(c.rgb);
    c.rgb = Vec3(std::max(c.rgb.x, 0.0f), std::max(c.rgb.y, 0.0f), std::max(c.rgb.z, 0.0f));
    return c;
}

void read_texture(Reader& r, const std::string& name, const std::string& kind,
                  const std::string& cls, ParamList& p, const FileLoc& loc) {
    if (kind != "float" && kind != "spectrum" && kind != "color" && kind != "rgb")
        throw_error(loc, "Texture '{}': its type must be \"float\" or \"spectrum\", got \"{}\"",
                    name, kind);
    const std::string k = kind == "float" ? "float" : "spectrum";
    TextureValue t;
    t.loc = loc;
    if (cls == "imagemap") {
        t = imagemap(r, k, p, loc);
    } else if (cls == "constant") {
        t.value = constant_operand(r, p, "value").value_or(Vec3(1.0f));
    } else if (cls == "scale") {
        t = scale_texture(r, k, p, loc);
    } else if (cls == "mix") {
        t = mix_texture(r, k, p, loc);
    } else if (cls == "checkerboard") {
        const TextureValue a = operand(r, k, p, "tex1", Vec3(1.0f), loc);
        const TextureValue b = operand(r, k, p, "tex2", Vec3(0.0f), loc);
        for (const char* u : {"uscale", "vscale", "udelta", "vdelta", "dimension"}) p.number(u, 0);
        p.string("mapping", "uv");
        if (a.image || b.image) {
            t = a.image ? a : b;
            r.notes.add(loc, "checkerboard of images is not supported: one image stands in");
        } else {
            t.value = (a.value + b.value) * 0.5f;
            r.notes.add(loc,
                        "checkerboard texture is not supported: the mean of tex1 and tex2 "
                        "stands in (a constant)");
        }
    } else {
        for (const Param& q : p.all()) q.used = true;
        t.value = Vec3(0.5f);
        r.notes.add(loc,
                    fmt::format("texture \"{}\" is not supported: a constant 0.5 stands in", cls));
    }
    t.loc = loc;
    r.notes.unused(p, fmt::format("Texture \"{}\"", cls));
    auto& table = k == "float" ? r.float_textures : r.color_textures;
    if (const auto old = table.find(name); old != table.end())
        r.notes.add(loc, fmt::format("{} texture '{}' is defined again (first at {}): this "
                                     "definition stands from here on (pbrt-v4 refuses the file)",
                                     k, name, old->second.loc.str()));
    table[name] = std::move(t);
}

}  // namespace spangle::pbrt
