// The pbrt reader's directive loop: transforms, the graphics state, named coordinate systems,
// object definitions and instances, includes; each directive family's handler lives in its own
// file (shapes, materials and textures, lights, camera and render settings).

#include "scene/pbrt/pbrt_reader.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "scene/pbrt/pbrt_state.h"

namespace spangle {
namespace pbrt {
namespace {

/** Files included within files deeper than this are refused (a file that includes itself). */
constexpr int kMaxIncludeDepth = 32;

/** A quoted string argument of `directive`. */
std::string string_arg(Tokenizer& t, std::string_view directive) {
    const Token s = t.next();
    if (s.kind != Token::Kind::String)
        throw_error(t.loc(s), "{} expects a quoted string, got '{}'", directive, s.text);
    return std::string(s.text);
}

/** `n` numbers, bare or in brackets. */
std::vector<double> number_args(Tokenizer& t, std::string_view directive, std::size_t n) {
    std::vector<double> v;
    const bool bracket = t.peek().kind == Token::Kind::Open;
    if (bracket) t.next();
    while (v.size() < n) {
        const Token x = t.next();
        double d = 0.0;
        std::string_view s = x.text;
        if (!s.empty() && s.front() == '+') s.remove_prefix(1);
        const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), d);
        if (x.kind != Token::Kind::Word || ec != std::errc() || end != s.data() + s.size() ||
            !std::isfinite(d))
            throw_error(
                t.loc(x), "{} expects {} numbers, got '{}' as number {}", directive, n,
                x.kind == Token::Kind::End ? std::string_view("the end of the file") : x.text,
                v.size() + 1);
        v.push_back(d);
    }
    if (bracket) {
        const Token c = t.next();
        if (c.kind != Token::Kind::Close)
            throw_error(t.loc(c), "{} expects ']' after its {} numbers", directive, n);
    }
    return v;
}

Mat4 translate(double x, double y, double z) {
    Mat4 m;
    m.m[0][3] = x;
    m.m[1][3] = y;
    m.m[2][3] = z;
    return m;
}

/** Rotation by `deg` degrees about `axis` (normalised here), right-handed (Rodrigues). */
Mat4 rotate(double deg, double x, double y, double z, const FileLoc& at) {
    const double len = std::sqrt(x * x + y * y + z * z);
    if (!(len > 0.0)) throw_error(at, "Rotate needs a non-zero axis");
    x /= len;
    y /= len;
    z /= len;
    const double th = deg * M_PI / 180.0, c = std::cos(th), s = std::sin(th);
    Mat4 m;
    m.m[0][0] = x * x + (1 - x * x) * c;
    m.m[0][1] = x * y * (1 - c) - z * s;
    m.m[0][2] = x * z * (1 - c) + y * s;
    m.m[1][0] = x * y * (1 - c) + z * s;
    m.m[1][1] = y * y + (1 - y * y) * c;
    m.m[1][2] = y * z * (1 - c) - x * s;
    m.m[2][0] = x * z * (1 - c) - y * s;
    m.m[2][1] = y * z * (1 - c) + x * s;
    m.m[2][2] = z * z + (1 - z * z) * c;
    return m;
}

/** pbrt's LookAt: world to a camera at `e` looking at `l` with up `u`, x = up x dir. */
Mat4 look_at(const std::vector<double>& v, const FileLoc& at) {
    const double dx = v[3] - v[0], dy = v[4] - v[1], dz = v[5] - v[2];
    const double dl = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double ul = std::sqrt(v[6] * v[6] + v[7] * v[7] + v[8] * v[8]);
    if (!(dl > 0.0) || !(ul > 0.0))
        throw_error(at, "LookAt: the eye must differ from the point looked at, and up be non-zero");
    const double d[3] = {dx / dl, dy / dl, dz / dl};
    const double u[3] = {v[6] / ul, v[7] / ul, v[8] / ul};
    double r[3] = {u[1] * d[2] - u[2] * d[1], u[2] * d[0] - u[0] * d[2], u[0] * d[1] - u[1] * d[0]};
    const double rl = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    if (!(rl > 1e-12)) throw_error(at, "LookAt: 'up' is parallel to the viewing direction");
    for (double& c : r) c /= rl;
    const double nu[3] = {d[1] * r[2] - d[2] * r[1], d[2] * r[0] - d[0] * r[2],
                          d[0] * r[1] - d[1] * r[0]};
    Mat4 cam_to_world;
    for (int i = 0; i < 3; ++i) {
        cam_to_world.m[i][0] = r[i];
        cam_to_world.m[i][1] = nu[i];
        cam_to_world.m[i][2] = d[i];
        cam_to_world.m[i][3] = v[static_cast<std::size_t>(i)];
    }
    return *cam_to_world.inverse();
}

/** pbrt's 16 numbers of Transform / ConcatTransform, which it reads transposed. */
Mat4 matrix_of(const std::vector<double>& v, Reader& r, const FileLoc& at) {
    Mat4 m;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) m.m[i][j] = v[static_cast<std::size_t>(j * 4 + i)];
    if (m.m[3][0] != 0.0 || m.m[3][1] != 0.0 || m.m[3][2] != 0.0 || m.m[3][3] != 1.0) {
        r.notes.add(at, "a projective transform: its last row is dropped (taken as 0 0 0 1)");
        if (m.m[3][3] != 0.0 && m.m[3][3] != 1.0)
            for (auto& row : m.m)
                for (double& x : row) x /= m.m[3][3];
        m.m[3][0] = m.m[3][1] = m.m[3][2] = 0.0;
        m.m[3][3] = 1.0;
    }
    return m;
}

/** Applies `f` to each active current transform. */
template <class F>
void each_active(Reader& r, const F& f) {
    for (int i = 0; i < 2; ++i)
        if (r.gs.active[i]) f(r.gs.ctm[i]);
}

/** The directive loop over one file's tokens. */
class Parser {
public:
    Parser(Reader& r) : r_(r) {}

    void file(Tokenizer& t, int depth) {
        for (;;) {
            const Token tok = t.next();
            if (tok.kind == Token::Kind::End) return;
            const FileLoc loc = t.loc(tok);
            if (tok.kind != Token::Kind::Word)
                throw_error(loc, "expected a directive, got {}",
                            tok.kind == Token::Kind::String ? fmt::format("\"{}\"", tok.text)
                                                            : std::string(tok.text));
            const std::string name(tok.text);
            if (!transform(t, name, loc) && !state(t, name, loc) && !scene(t, name, loc) &&
                !include(t, name, loc, depth))
                throw_error(
                    loc, "unknown directive '{}'{}", name,
                    name == "SurfaceIntegrator" || name == "VolumeIntegrator" || name == "Renderer"
                        ? " (a pbrt-v2 directive: Spangle reads pbrt-v3 and pbrt-v4 "
                          "files)"
                        : "");
        }
    }

private:
    /** The transform directives. */
    bool transform(Tokenizer& t, const std::string& name, const FileLoc& loc) {
        if (name == "Identity") {
            each_active(r_, [](Mat4& m) { m = Mat4(); });
        } else if (name == "Translate") {
            const auto v = number_args(t, name, 3);
            each_active(r_, [&](Mat4& m) { m = m * translate(v[0], v[1], v[2]); });
        } else if (name == "Scale") {
            const auto v = number_args(t, name, 3);
            each_active(r_, [&](Mat4& m) { m = m * Mat4::scale(v[0], v[1], v[2]); });
        } else if (name == "Rotate") {
            const auto v = number_args(t, name, 4);
            const Mat4 rot = rotate(v[0], v[1], v[2], v[3], loc);
            each_active(r_, [&](Mat4& m) { m = m * rot; });
        } else if (name == "LookAt") {
            const Mat4 l = look_at(number_args(t, name, 9), loc);
            each_active(r_, [&](Mat4& m) { m = m * l; });
        } else if (name == "Transform" || name == "ConcatTransform") {
            const Mat4 x = matrix_of(number_args(t, name, 16), r_, loc);
            const bool concat = name == "ConcatTransform";
            each_active(r_, [&](Mat4& m) { m = concat ? m * x : x; });
        } else if (name == "CoordinateSystem") {
            r_.coord_systems[string_arg(t, name)] = {r_.gs.ctm[0], r_.gs.ctm[1]};
        } else if (name == "CoordSysTransform") {
            const std::string sys = string_arg(t, name);
            const auto it = r_.coord_systems.find(sys);
            if (it == r_.coord_systems.end()) {
                r_.notes.add(loc, fmt::format("CoordSysTransform: no coordinate system '{}' "
                                              "(yet): the transform is left as it is",
                                              sys));
            } else {
                r_.gs.ctm[0] = it->second[0];
                r_.gs.ctm[1] = it->second[1];
            }
        } else if (name == "TransformTimes") {
            const auto v = number_args(t, name, 2);
            if (!(v[0] <= v[1])) throw_error(loc, "TransformTimes: the start comes after the end");
            r_.time_start = v[0];
            r_.time_end = v[1];
        } else if (name == "ActiveTransform") {
            const Token w = t.next();
            if (w.text == "StartTime") {
                r_.gs.active[0] = true;
                r_.gs.active[1] = false;
            } else if (w.text == "EndTime") {
                r_.gs.active[0] = false;
                r_.gs.active[1] = true;
            } else if (w.text == "All") {
                r_.gs.active[0] = r_.gs.active[1] = true;
            } else {
                throw_error(t.loc(w), "ActiveTransform takes StartTime, EndTime or All, got '{}'",
                            w.text);
            }
        } else if (name == "ReverseOrientation") {
            r_.gs.reverse = !r_.gs.reverse;
        } else {
            return false;
        }
        return true;
    }

    /** Attribute and transform blocks, object definitions. */
    bool state(Tokenizer& t, const std::string& name, const FileLoc& loc) {
        if (name == "AttributeBegin" || name == "TransformBegin") {
            if (name == "TransformBegin") r_.sign(false, loc, "TransformBegin");
            r_.stack.push_back({name == "AttributeBegin" ? 'a' : 't', r_.gs, loc});
        } else if (name == "AttributeEnd" || name == "TransformEnd") {
            pop(name == "AttributeEnd" ? 'a' : 't', name, loc);
        } else if (name == "Attribute") {
            const std::string cat = string_arg(t, name);
            ParamList p;
            p.parse(t);
            if (cat != "shape" && cat != "light" && cat != "material" && cat != "medium" &&
                cat != "texture")
                throw_error(loc,
                            "Attribute: unknown category '{}' (valid: shape, light, material, "
                            "medium, texture)",
                            cat);
            r_.sign(true, loc, "Attribute");
            ParamList& into = r_.gs.attributes[cat];
            for (const Param& q : p.all()) into.add(q);
        } else if (name == "ObjectBegin") {
            const std::string obj = string_arg(t, name);
            if (!r_.defining.empty())
                throw_error(loc, "ObjectBegin '{}' inside the definition of '{}'", obj,
                            r_.defining);
            r_.stack.push_back({'o', r_.gs, loc});
            r_.defining = obj;
            if (!r_.definitions.emplace(obj, std::vector<InstancedShape>{}).second)
                r_.notes.add(loc, fmt::format("object '{}' is defined again: the new "
                                              "definition replaces the old one",
                                              obj));
            r_.definitions[obj].clear();
        } else if (name == "ObjectEnd") {
            if (r_.defining.empty()) {
                r_.notes.add(loc, "ObjectEnd outside an object definition: ignored");
                return true;
            }
            pop('o', name, loc);
            r_.defining.clear();
        } else if (name == "ObjectInstance") {
            instance(string_arg(t, name), loc);
        } else if (name == "WorldBegin") {
            // pbrt refuses a second WorldBegin (v4: "WorldBegin called twice"): so does Spangle,
            // which read on as if it were the first.
            if (r_.world) throw_error(loc, "WorldBegin again: a scene has one world block");
            r_.world = true;
            r_.gs.ctm[0] = r_.gs.ctm[1] = Mat4();
            // As in pbrt (v3 and v4): both transforms active again.
            r_.gs.active[0] = r_.gs.active[1] = true;
            r_.coord_systems["world"] = {Mat4(), Mat4()};
        } else if (name == "WorldEnd") {
            r_.sign(false, loc, "WorldEnd");
        } else {
            return false;
        }
        return true;
    }

    /** Ends a block of kind `kind`; an unmatched end is a warning, as pbrt makes it. */
    void pop(char kind, const std::string& name, const FileLoc& loc) {
        if (r_.stack.size() <= r_.stack_floor ||
            (r_.stack.back().kind != kind && !(kind == 'a' && r_.stack.back().kind == 'o'))) {
            r_.notes.add(loc, fmt::format("{} without its begin: ignored", name));
            return;
        }
        if (kind == 't') {
            // TransformEnd restores the transforms only.
            r_.gs.ctm[0] = r_.stack.back().gs.ctm[0];
            r_.gs.ctm[1] = r_.stack.back().gs.ctm[1];
            r_.gs.active[0] = r_.stack.back().gs.active[0];
            r_.gs.active[1] = r_.stack.back().gs.active[1];
        } else {
            if (r_.stack.back().kind == 'o' && kind != 'o') r_.defining.clear();
            r_.gs = r_.stack.back().gs;
        }
        r_.stack.pop_back();
    }

    /** ObjectInstance: every shape of the definition, placed by the current transform. */
    void instance(const std::string& obj, const FileLoc& loc) {
        const auto it = r_.definitions.find(obj);
        if (it == r_.definitions.end()) {
            r_.notes.add(loc,
                         fmt::format("ObjectInstance of '{}', which is not defined: dropped", obj));
            return;
        }
        if (!r_.defining.empty()) {
            r_.notes.add(loc,
                         "ObjectInstance inside an object definition: dropped (pbrt "
                         "refuses nested instances too; write the inner definition's "
                         "shapes into the outer one)");
            return;
        }
        ++r_.info.instances;
        for (const InstancedShape& s : it->second) {
            ObjectDesc o = s.object;
            o.loc = loc;
            const Mat4 xf[2] = {r_.gs.ctm[0] * s.placement[0], r_.gs.ctm[1] * s.placement[1]};
            place_object(r_, std::move(o), xf);
        }
    }

    /** The scene-wide and scene-content directives. */
    bool scene(Tokenizer& t, const std::string& name, const FileLoc& loc) {
        if (name == "Shape" || name == "LightSource" || name == "AreaLightSource" ||
            name == "Material" || name == "MakeNamedMaterial" || name == "Camera" ||
            name == "Film" || name == "Sampler" || name == "Integrator" || name == "PixelFilter" ||
            name == "Accelerator" || name == "MakeNamedMedium") {
            const std::string type = string_arg(t, name);
            ParamList p;
            p.parse(t);
            typed(name, type, p, loc);
        } else if (name == "Texture") {
            const std::string tex = string_arg(t, name);
            const std::string kind = string_arg(t, name);
            const std::string cls = string_arg(t, name);
            ParamList p;
            p.parse(t);
            add_attributes(p, "texture");
            read_texture(r_, tex, kind, cls, p, loc);
        } else if (name == "NamedMaterial") {
            const std::string m = string_arg(t, name);
            const auto it = r_.materials.find(m);
            if (it == r_.materials.end()) {
                // Maybe defined further on: pbrt-v4 resolves names once the scene is read.
                r_.pending_materials.emplace(m, loc);
                r_.gs.material = std::string(kPendingMaterial) + m;
            } else {
                r_.gs.material = it->second;
            }
            r_.gs.no_surface = it != r_.materials.end() && it->second.empty();
        } else if (name == "ColorSpace") {
            const std::string cs = string_arg(t, name);
            r_.sign(true, loc, "ColorSpace");
            color_space(cs, loc);
        } else if (name == "Option") {
            ParamList p;
            p.parse(t);
            r_.sign(true, loc, "Option");
            if (const Param* seed = p.find("seed", {"integer"}); seed && !seed->numbers.empty())
                r_.d.render.seed = static_cast<uint64_t>(std::fabs(seed->numbers[0]));
            r_.notes.unused(p, "Option");
        } else if (name == "MediumInterface") {
            string_arg(t, name);
            if (t.peek().kind == Token::Kind::String) t.next();
            r_.notes.add(loc,
                         "MediumInterface: participating media are not supported: "
                         "dropped (surfaces render in vacuum)");
        } else {
            return false;
        }
        return true;
    }

    /** Adds the v4 Attribute defaults of `category` to `p`. */
    void add_attributes(ParamList& p, const char* category) {
        const auto it = r_.gs.attributes.find(category);
        if (it != r_.gs.attributes.end()) p.add_defaults(it->second);
    }

    /** The directives of the form Name "type" params. */
    void typed(const std::string& name, const std::string& type, ParamList& p, const FileLoc& loc) {
        // pbrt refuses the image's options inside the world block and the world's contents
        // before it; both were taken without a word (a shape before WorldBegin is placed by the
        // camera's transform, behind the camera).
        const bool option =
            name == "Film" || name == "Sampler" || name == "Integrator" || name == "PixelFilter";
        if (r_.world && option)
            r_.notes.add(loc, fmt::format("{} inside the world block (after WorldBegin): pbrt "
                                          "does not allow it; taken all the same",
                                          name));
        if (!r_.world && (name == "Shape" || name == "LightSource" || name == "AreaLightSource"))
            r_.notes.add(loc, fmt::format("{} before WorldBegin: pbrt does not allow it (the "
                                          "world block starts at WorldBegin); placed by the "
                                          "transform in effect, the camera's",
                                          name));
        if (name == "Shape") {
            add_attributes(p, "shape");
            read_shape(r_, type, p, loc);
        } else if (name == "LightSource") {
            add_attributes(p, "light");
            read_light(r_, type, p, loc);
        } else if (name == "AreaLightSource") {
            add_attributes(p, "light");
            read_area_light(r_, type, p, loc);
        } else if (name == "Material") {
            add_attributes(p, "material");
            r_.gs.material = read_material(r_, type, "", p, loc);
            r_.gs.no_surface = r_.gs.material.empty();
        } else if (name == "MakeNamedMaterial") {
            add_attributes(p, "material");
            const Param* ty = p.find("type", {"string"});
            const std::string mtype = ty && !ty->strings.empty() ? ty->strings[0] : "";
            if (mtype.empty())
                r_.notes.add(loc, fmt::format("MakeNamedMaterial '{}' has no \"string type\": "
                                              "the default material stands in",
                                              type));
            r_.materials[type] =
                mtype.empty() ? default_material(r_, loc) : read_material(r_, mtype, type, p, loc);
        } else if (name == "Camera" && r_.world) {
            // pbrt-v4 refuses a camera inside the world block and pbrt-v3 ignores it (with an
            // error): it would otherwise replace the scene's camera silently.
            r_.notes.add(loc,
                         "Camera inside the world block (after WorldBegin): pbrt does not "
                         "allow it; ignored");
        } else if (name == "Camera") {
            r_.camera.type = type;
            r_.camera.params = std::move(p);
            r_.camera.loc = loc;
            r_.camera.given = true;
            for (int i = 0; i < 2; ++i) {
                const auto inv = r_.gs.ctm[i].inverse();
                if (!inv) throw_error(loc, "Camera: the current transform is singular");
                r_.camera.to_world[i] = *inv;
            }
            r_.coord_systems["camera"] = {r_.camera.to_world[0], r_.camera.to_world[1]};
        } else if (name == "MakeNamedMedium") {
            r_.notes.add(loc, "MakeNamedMedium: participating media are not supported: dropped");
        } else if (name == "Accelerator") {
            r_.notes.add(loc, fmt::format("Accelerator \"{}\": Spangle builds its own BVHs "
                                          "(Embree): dropped",
                                          type));
        } else {
            ParamList* into = name == "Film"         ? &r_.film
                              : name == "Sampler"    ? &r_.sampler
                              : name == "Integrator" ? &r_.integrator
                                                     : &r_.filter;
            std::string* ty = name == "Film"         ? &r_.film_type
                              : name == "Sampler"    ? &r_.sampler_type
                              : name == "Integrator" ? &r_.integrator_type
                                                     : &r_.filter_type;
            FileLoc* at = name == "Film"         ? &r_.film_loc
                          : name == "Sampler"    ? &r_.sampler_loc
                          : name == "Integrator" ? &r_.integrator_loc
                                                 : &r_.filter_loc;
            *into = std::move(p);
            *ty = type;
            *at = loc;
            if (name == "Film") {
                if (type == "image") r_.sign(false, loc, "Film \"image\"");
                if (type == "rgb" || type == "gbuffer" || type == "spectral")
                    r_.sign(true, loc, "Film \"rgb\"");
            }
        }
    }

    /** v4's ColorSpace: the space of the colours that follow. */
    void color_space(const std::string& cs, const FileLoc& loc) {
        if (cs == "srgb") {
            r_.gs.space.reset();
        } else if (cs == "aces2065-1") {
            r_.gs.space = "ACES2065-1";
        } else if (cs == "rec2020" || cs == "dci-p3") {
            r_.notes.add(loc, fmt::format("ColorSpace \"{}\" is not in Spangle's OCIO config: "
                                          "its colours are read as sRGB",
                                          cs));
            r_.gs.space.reset();
        } else {
            throw_error(loc, "unknown ColorSpace '{}' (valid: srgb, aces2065-1, rec2020, dci-p3)",
                        cs);
        }
    }

    /** Include: the file's directives, in the same graphics state. Import (pbrt-v4): in the
     *  world block only, the file read from a copy of the graphics state (as pbrt-v4 parses it
     *  with a copy of its builder): its shapes, lights, named materials, textures and object
     *  definitions join the scene, but its transforms, current material, area light, colour
     *  space, attributes and named coordinate systems stay its own. */
    bool include(Tokenizer& t, const std::string& name, const FileLoc& loc, int depth) {
        if (name != "Include" && name != "Import") return false;
        const bool import = name == "Import";
        if (import) {
            r_.sign(true, loc, "Import");
            if (!r_.world)
                throw_error(loc,
                            "Import is only allowed in the world block (after WorldBegin), "
                            "as in pbrt-v4; Include reads a file anywhere");
        }
        const std::string given = string_arg(t, name);
        if (depth + 1 > kMaxIncludeDepth)
            throw_error(loc, "{} nested more than {} deep (does a file include itself?)", name,
                        kMaxIncludeDepth);
        const std::string path = r_.find_file(given, name == "Include" ? "Include" : "Import", loc);
        r_.d.files.push_back(path);
        Tokenizer inner(path, loc);
        const std::filesystem::path saved = r_.current_dir;
        r_.current_dir = std::filesystem::path(path).parent_path();
        if (!import) {
            file(inner, depth + 1);
            r_.current_dir = saved;
            return true;
        }
        const GraphicsState gs = r_.gs;
        const auto coord_systems = r_.coord_systems;
        const std::size_t stack = r_.stack.size(), floor = r_.stack_floor;
        const std::string defining = r_.defining;
        r_.stack_floor = stack;
        file(inner, depth + 1);
        r_.current_dir = saved;
        r_.stack_floor = floor;
        if (r_.stack.size() > stack) {
            r_.notes.add(r_.stack[stack].loc,
                         fmt::format("'{}' leaves {} AttributeBegin / TransformBegin / "
                                     "ObjectBegin open (the first here): closed where its Import "
                                     "ends",
                                     given, r_.stack.size() - stack));
            r_.stack.resize(stack);
        }
        r_.gs = gs;
        r_.coord_systems = coord_systems;
        r_.defining = defining;
        return true;
    }

    Reader& r_;
};

/** Reads the tokens of the main file and finishes the description. */
/** Objects that named a material before its MakeNamedMaterial get it now (a red sphere whose
 *  material came after it rendered grey); a name never defined is said at its first use and the
 *  default material stands in; an object of a material found to be "interface" (a medium's
 *  boundary) is not drawn. */
void resolve_pending_materials(Reader& r) {
    if (r.pending_materials.empty()) return;
    const std::string marker = kPendingMaterial;
    std::set<std::string> undefined;
    std::vector<ObjectDesc> kept;
    kept.reserve(r.d.objects.size());
    for (ObjectDesc& o : r.d.objects) {
        if (o.material.rfind(marker, 0) == 0) {
            // A shape's alpha after the name (kAlphaMark) stays after the material found.
            const std::size_t cut = o.material.find(kAlphaMark);
            const std::string alpha =
                cut == std::string::npos ? std::string() : o.material.substr(cut);
            std::string name = o.material.substr(
                marker.size(), cut == std::string::npos ? std::string::npos : cut - marker.size());
            auto it = r.materials.find(name);
            // A named mix whose operand was pending is itself pending: followed to the end (a
            // cycle of mixes ends at the default material).
            for (int hops = 0; it != r.materials.end() && it->second.rfind(marker, 0) == 0;
                 ++hops) {
                name = it->second.substr(marker.size());
                it = hops < 64 ? r.materials.find(name) : r.materials.end();
            }
            if (it == r.materials.end()) {
                const FileLoc& at = r.pending_materials.at(name);
                if (undefined.insert(name).second)
                    r.notes.add(at, r.pending_from_mix.count(name) != 0
                                        ? fmt::format("Material \"mix\": its material '{}' is not "
                                                      "defined: the default material stands in",
                                                      name)
                                        : fmt::format("NamedMaterial '{}' is not defined: the "
                                                      "default material stands in",
                                                      name));
                o.material = default_material(r, at) + alpha;
            } else if (it->second.empty() && r.pending_from_mix.count(name) != 0) {
                // A mix's operand that is an interface: the default material stands in, as for
                // one defined before the mix.
                o.material = default_material(r, r.pending_materials.at(name)) + alpha;
            } else if (it->second.empty()) {
                continue;  // a medium boundary: nothing to render (pbrt ignores its area light)
            } else {
                o.material = it->second + alpha;
            }
        }
        kept.push_back(std::move(o));
    }
    r.d.objects = std::move(kept);
}

/** Objects of shapes with an alpha get their material with that alpha: a copy of it per
 *  (material, alpha), named after it (pbrt gives alpha to shapes, Spangle to materials). */
void alpha_materials(Reader& r) {
    if (r.alphas.empty()) return;
    const std::string mark = kAlphaMark;
    std::map<std::string, std::string> made;  // material + mark + index -> the copy's name
    for (ObjectDesc& o : r.d.objects) {
        const std::size_t cut = o.material.find(mark);
        if (cut == std::string::npos) continue;
        if (const auto it = made.find(o.material); it != made.end()) {
            o.material = it->second;
            continue;
        }
        const std::string base = o.material.substr(0, cut);
        const std::size_t index = std::stoul(o.material.substr(cut + mark.size()));
        const auto m = std::find_if(r.d.materials.begin(), r.d.materials.end(),
                                    [&](const MaterialDesc& x) { return x.name == base; });
        if (m == r.d.materials.end() || index >= r.alphas.size()) {
            o.material = base;
            continue;
        }
        MaterialDesc copy = *m;
        std::string name = base + "_alpha";
        for (int k = 2; r.material_names.count(name); ++k)
            name = fmt::format("{}_alpha{}", base, k);
        r.material_names.insert(name);
        copy.name = name;
        copy.alpha = r.alphas[index];
        // pbrt-v3 cuts only where alpha is 0 (v4 by chance): a cutoff just above 0.
        if (!r.v4()) {
            copy.alpha_cutoff = 1.0 / 65536.0;
            copy.alpha_cutoff_loc = copy.alpha->loc;
        }
        copy.quiet_unused = true;
        made.emplace(o.material, name);
        o.material = name;
        r.d.materials.push_back(std::move(copy));
    }
    // A material every shape of which had an alpha is used only through its copies: dropped
    // (a converted scene warned that it was unused).
    std::set<std::string> used, copied;
    for (const ObjectDesc& o : r.d.objects) used.insert(o.material);
    for (const auto& [from, name] : made) copied.insert(from.substr(0, from.find(mark)));
    std::erase_if(r.d.materials, [&](const MaterialDesc& m) {
        return copied.count(m.name) && !used.count(m.name);
    });
}

SceneDescription read_all(Reader& r, Tokenizer& t) {
    r.d.path = t.path();
    r.d.render.width = 640;
    r.d.render.height = 480;
    // pbrt renders RGB colours as linear sRGB (Rec.709 primaries): so does its scene here.
    r.d.render.working_space = "lin_rec709";
    r.d.render.color_space = "lin_rec709";
    Parser(r).file(t, 0);
    if (!r.stack.empty())
        r.notes.add(r.stack.front().loc,
                    fmt::format("{} AttributeBegin / TransformBegin / ObjectBegin never ended (the "
                                "first here)",
                                r.stack.size()));
    if (!r.info.v3_sign.empty() && !r.info.v4_sign.empty())
        r.notes.add(FileLoc{t.path(), 0, 0},
                    fmt::format("the file mixes pbrt-v3 ({}) and pbrt-v4 ({}) spellings: read as "
                                "pbrt-v4",
                                r.info.v3_sign, r.info.v4_sign));
    resolve_pending_materials(r);
    alpha_materials(r);
    finish_camera_and_render(r);
    // pbrt-v3 fades a spot light's edge as t^4 (its Falloff()), v4 by smoothstep: decided by the
    // whole file, whose v3 sign may come after its lights (WorldEnd).
    if (r.info.version == PbrtVersion::V3)
        for (LightDesc& l : r.d.lights)
            if (auto* s = std::get_if<SpotLightDesc>(&l.shape)) s->quartic = true;
    // A pbrt scene's named materials are a library (pbrt says nothing of those no shape uses),
    // and a mix's operands stay defined after Spangle picked one of them.
    for (MaterialDesc& m : r.d.materials) m.quiet_unused = true;
    r.d.notes = r.notes.take();
    return std::move(r.d);
}

}  // namespace

void place_object(Reader& r, ObjectDesc o, const Mat4 xf[2]) {
    for (int i = 0; i < 2; ++i) {
        // Rays are carried into object space in floats: a transform they cannot invert there
        // (a zero scale, or one beyond 1e8 either way) would send non-finite rays.
        const Affine a = xf[i].affine();
        const float det = a.determinant();
        bool finite = std::isfinite(det);
        for (const auto& row : a.m)
            for (float v : row) finite = finite && std::isfinite(v);
        finite = finite && is_finite(a.t);
        if (!finite || !(std::fabs(det) > 1e-24f && std::fabs(det) < 1e24f)) {
            r.notes.add(o.loc, fmt::format("{} is placed by a singular or extreme transform "
                                           "(a scale of 0, or beyond 1e8): dropped",
                                           o.what));
            return;
        }
    }
    o.placement.matrix = xf[0].affine();
    if (!(xf[0] == xf[1])) {
        o.matrix_keys.smooth = false;
        o.matrix_keys.loc = o.loc;
        const double times[2] = {r.time_start, r.time_end};
        for (int i = 0; i < 2; ++i) {
            MatrixKey k;
            k.time.seconds = times[i];
            k.matrix = xf[i].affine();
            k.loc = o.loc;
            k.what = fmt::format("{} at time {}", o.what, times[i]);
            o.matrix_keys.keys.push_back(std::move(k));
        }
    }
    r.d.objects.push_back(std::move(o));
}

}  // namespace pbrt

namespace {

SceneDescription read_with(pbrt::Reader& r, pbrt::Tokenizer& t, const std::string& path,
                           PbrtReadInfo& info) {
    r.dir = std::filesystem::path(path).parent_path();
    r.current_dir = r.dir;
    SceneDescription d = pbrt::read_all(r, t);
    info = r.info;
    return d;
}

}  // namespace

SceneDescription read_pbrt_scene(const std::string& path, const SceneReadOptions& options,
                                 PbrtReadInfo& info) {
    (void)options;
    pbrt::Reader r;
    pbrt::Tokenizer t(path, FileLoc{path, 0, 0});
    return read_with(r, t, path, info);
}

SceneDescription read_pbrt_scene(const std::string& path, const SceneReadOptions& options) {
    PbrtReadInfo info;
    return read_pbrt_scene(path, options, info);
}

SceneDescription read_pbrt_text(const std::string& name, std::string text, PbrtReadInfo& info) {
    pbrt::Reader r;
    pbrt::Tokenizer t(name, std::move(text));
    return read_with(r, t, name, info);
}

}  // namespace spangle
