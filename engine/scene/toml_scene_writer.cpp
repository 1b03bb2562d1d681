#include "scene/toml_scene_writer.h"

#include <fmt/format.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

#include "core/error.h"
#include "core/map_projection.h"
#include "geometry/ply_writer.h"
#include "scene/frame_sequence.h"
#include "scene/keyed_motion.h"
#include "scene/scene_builder.h"

namespace fs = std::filesystem;

namespace spangle {
std::string toml_basic_string(const std::string& s) {
    std::string out = "\"";
    for (const char c : s) {
        if (c == '"' || c == '\\')
            out += fmt::format("\\{}", c);
        else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
            out += fmt::format("\\u{:04x}", static_cast<unsigned>(static_cast<unsigned char>(c)));
        else
            out += c;
    }
    return out + "\"";
}

namespace {

/** A number as TOML: the shortest decimal that reads back as the same double, always with a
 *  decimal point or an exponent (so that it is a float, not an integer). */
template <typename T>
std::string shortest(T x) {
    std::string s = fmt::format("{}", x);
    if (s.find_first_of(".eEn") == std::string::npos) s += ".0";  // n: inf and nan stay words
    return s;
}
std::string num(double x) {
    return shortest(x);
}
/** A float as the shortest decimal that reads back (as a double, then rounded to a float) as the
 *  same float: 0.8f is written 0.8, not 0.800000011920929. */
std::string num(float x) {
    return shortest(x);
}

std::string str(const std::string& s) {
    return toml_basic_string(s);
}

std::string vec(Vec3 v) {
    return fmt::format("[{}, {}, {}]", num(v.x), num(v.y), num(v.z));
}

/** The 12 numbers of `matrix = [...]`: the rows of the 3x4 object-to-world matrix. */
std::string matrix12(const Affine& m) {
    std::vector<std::string> v;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) v.push_back(num(m.m[r][c]));
        v.push_back(num(r == 0 ? m.t.x : r == 1 ? m.t.y : m.t.z));
    }
    return fmt::format("[{}]", fmt::join(v, ", "));
}

std::string color(const ColorDesc& c) {
    if (!c.space) return vec(c.rgb);
    return fmt::format("{{ rgb = {}, space = {} }}", vec(c.rgb), str(*c.space));
}

const char* filter_name(FilterKind k) {
    switch (k) {
        case FilterKind::Box:
            return "box";
        case FilterKind::BlackmanHarris:
            return "blackman-harris";
        case FilterKind::Gaussian:
            break;
    }
    return "gaussian";
}

std::string key_time(const KeyTime& t) {
    return t.frame ? fmt::format("frame = {}", *t.frame) : fmt::format("time = {}", num(t.seconds));
}

/** Most frames a deforming mesh is written for (a file each). */
constexpr int64_t kMaxWrittenFrames = 10000;

/** Builds the file's text section by section. */
struct Writer {
    fs::path dir;       ///< the TOML file's folder: paths are written relative to it
    fs::path mesh_dir;  ///< where inline meshes go
    std::string out;    ///< the text so far
    std::map<const TriangleMesh*, std::string> meshes;  ///< inline meshes written, by mesh
    std::map<const Cage*, std::string> cages;           ///< inline cages written, by cage
    std::map<const TriangleMesh*, std::string> rests;   ///< rest poses written, by posed mesh
    int sequences = 0;                                  ///< deforming meshes written
    int rest_files = 0;                                 ///< rest poses written
    const RenderDesc* frames = nullptr;  ///< the frame range deforming meshes are written for
    SceneWriteReport report;

    void line(const std::string& key, const std::string& value) {
        out += key + " = " + value + "\n";
    }
    std::string path(const std::string& p) const {
        // Files in the TOML's folder (or below) relative to it; others by absolute path, so that
        // the written scene finds them from wherever it is read.
        std::error_code ec;
        const fs::path abs = fs::absolute(p, ec);
        const fs::path rel = fs::relative(abs, dir, ec);
        if (ec || rel.empty() || rel.string().rfind("..", 0) == 0)
            return str(abs.lexically_normal().string());
        return str(rel.string());
    }

    void render(const RenderDesc& r) {
        out += "[render]\n";
        line("width", fmt::to_string(r.width));
        line("height", fmt::to_string(r.height));
        line("spp", fmt::to_string(r.spp));
        line("max_depth", fmt::to_string(r.max_depth));
        line("rr_depth", fmt::to_string(r.rr_depth));
        line("seed", fmt::to_string(r.seed));
        line("filter", str(filter_name(r.filter)));
        if (r.filter_radius > 0.0f) line("filter_radius", num(r.filter_radius));
        if (r.filter_shared) line("filter_samples", str("shared"));
        line("clamp_indirect", num(r.clamp_indirect));
        if (r.filter_glossy > 0.0f) line("filter_glossy", num(r.filter_glossy));
        if (r.noise_threshold > 0.0f) line("noise_threshold", num(r.noise_threshold));
        if (r.min_spp > 0) line("min_spp", fmt::to_string(r.min_spp));
        if (r.max_spp > 0) line("max_spp", fmt::to_string(r.max_spp));
        if (r.transparent_background) line("transparent_background", "true");
        if (r.working_space) line("working_space", str(*r.working_space));
        if (r.color_space) line("color_space", str(*r.color_space));
        line("frame_start", fmt::to_string(r.frame_start));
        line("frame_end", fmt::to_string(r.frame_end));
        line("fps", num(r.fps));
        line("shutter", fmt::format("[{}, {}]", num(r.shutter_open), num(r.shutter_close)));
        if (r.crop) line("crop_window", window(*r.crop));
        if (r.output) line("output", str(*r.output));
    }

    static std::string window(const std::array<double, 4>& w) {
        return fmt::format("[{}, {}, {}, {}]", num(w[0]), num(w[1]), num(w[2]), num(w[3]));
    }

    void camera(const CameraDesc& c) {
        out += "\n[camera]\n";
        line("position", vec(c.position));
        line("look_at", vec(c.look_at));
        line("up", vec(c.up));
        if (c.equirect)
            line("projection", str("equirectangular"));
        else if (c.ortho_height > 0.0)
            line("ortho_height", num(c.ortho_height));
        else
            line("fov", num(c.fov_deg));
        if (c.fov_shorter && !c.equirect) line("fov_axis", str("shorter"));
        if (!c.equirect) line("aperture", num(c.aperture));
        if (c.focus_distance) line("focus_distance", num(*c.focus_distance));
        if (c.mirror) line("mirror", "true");
        if (c.screen) line("screen_window", window(*c.screen));
        if (c.keys.keys.empty()) return;
        line("interpolation", str(c.keys.smooth ? "smooth" : "linear"));
        for (const CameraKey& k : c.keys.keys) {
            out += "\n[[camera.keys]]\n" + key_time(k.time) + "\n";
            if (k.position) line("position", vec(*k.position));
            if (k.look_at) line("look_at", vec(*k.look_at));
            if (k.up) line("up", vec(*k.up));
            if (k.fov_deg) line("fov", num(*k.fov_deg));
        }
    }

    void group(const LightGroupDesc& g, const char* key = "light_group") {
        if (g.name != LightGroupDesc{}.name) line(key, str(g.name));
    }

    void environment(const EnvironmentDesc& e) {
        out += "\n[environment]\n";
        if (e.map) {
            line("map", path(e.map->path));
            if (e.map->color_space) line("color_space", str(*e.map->color_space));
            line("rotation", num(e.map->rotation_deg));
            if (e.map->projection != MapProjection::LatLongYUp) {
                line("projection",
                     str(e.map->projection == MapProjection::LatLongZUp ? "latlong_z_up"
                                                                        : "equal_area"));
                line("frame", matrix12(e.map->to_world));
            }
        } else if (e.color) {
            line("color", color(*e.color));
        }
        line("intensity", num(e.intensity));
        group(e.group);
    }

    std::string texture(const TextureDesc& t, const char* use) {
        static const char* wraps[] = {"periodic", "clamp", "black", "mirror"};
        if (t.path.empty())  // the vertex colours alone
            return fmt::format("{{ vertex_color = true, scale = [{}, {}, {}] }}", num(t.scale[0]),
                               num(t.scale[1]), num(t.scale[2]));
        std::string s = "{ texture = " + path(t.path);
        if (t.vertex_color) s += ", vertex_color = true";
        if (t.space) s += ", space = " + str(*t.space);
        if (std::string(use) == "param") {
            s += fmt::format(", scale = [{}, {}, {}]", num(t.scale[0]), num(t.scale[1]),
                             num(t.scale[2]));
            if (t.channel == kLuminance)
                s += ", channel = " + str("luminance");
            else if (t.channel >= 0 && t.channel <= 2)
                s += ", channel = " + str(std::string(1, "rgb"[t.channel]));
        }
        if (std::string(use) == "alpha") {
            if (t.scale[0] != 1.0f) s += ", scale = " + num(t.scale[0]);
            // kAlphaOrOpaque (glTF's base colour) is "a": an image without alpha reads 1.
            if (t.channel == kAlphaPbrt)
                s += ", channel = " + str("pbrt");
            else if (t.channel >= 0)
                s += ", channel = " + str(std::string(1, "rgba"[std::min(t.channel, 3)]));
        }
        if (std::string(use) == "normal_map") s += ", strength = " + num(t.amount);
        if (std::string(use) == "bump_map") {
            s += ", height = " + num(t.amount);
            if (t.blend != 1.0f) s += ", strength = " + num(t.blend);
        }
        std::vector<std::string> uv;
        for (float x : t.uv) uv.push_back(num(x));
        s += fmt::format(", uv_transform = {{ matrix = [{}] }}", fmt::join(uv, ", "));
        const std::string wrap =
            t.wrap_t >= 0 && t.wrap_t != t.wrap
                ? fmt::format("[{}, {}]", str(wraps[t.wrap & 3]), str(wraps[t.wrap_t & 3]))
                : str(wraps[t.wrap & 3]);
        s += fmt::format(", wrap = {}, filter = {} }}", wrap,
                         str(t.filter == 1   ? "anisotropic"
                             : t.filter == 2 ? "closest"
                                             : "trilinear"));
        return s;
    }

    std::string param(const ParamDesc& p) {
        switch (p.kind) {
            case ParamDesc::Kind::Number:
                return p.is_integer ? fmt::format("{}", static_cast<int64_t>(p.number))
                                    : num(p.number);
            case ParamDesc::Kind::Bool:
                return p.number != 0 ? "true" : "false";
            case ParamDesc::Kind::String:
                return str(p.text);
            case ParamDesc::Kind::Color:
                return color(p.color);
            case ParamDesc::Kind::Texture:
                break;
        }
        return texture(p.texture, "param");
    }

    void material(const MaterialDesc& m) {
        out += "\n[[material]]\n";
        line("name", str(m.name));
        line("plugin", str(m.plugin));
        if (!m.model.empty()) line("model", str(m.model));
        std::vector<std::string> params;
        for (const ParamDesc& p : m.params) params.push_back(str(p.name) + " = " + param(p));
        line("params", fmt::format("{{ {} }}", fmt::join(params, ", ")));
        for (const ParamDesc& p : m.maps) line(p.name, texture(p.texture, p.name.c_str()));
        if (m.alpha)
            line("alpha", m.alpha->kind == ParamDesc::Kind::Texture
                              ? texture(m.alpha->texture, "alpha")
                              : num(m.alpha->number));
        if (m.alpha_cutoff) line("alpha_cutoff", num(*m.alpha_cutoff));
        if (m.shadow_catcher) line("shadow_catcher", "true");
    }

    std::string inline_mesh(const TriangleMesh& mesh) {
        auto it = meshes.find(&mesh);
        if (it != meshes.end()) return it->second;
        std::error_code ec;
        fs::create_directories(mesh_dir, ec);
        const fs::path file = mesh_dir / fmt::format("mesh_{:03}.ply", meshes.size());
        write_ply(mesh, file.string(), "written by spangle convert from " + mesh.source);
        report.meshes.push_back(file.string());
        return meshes.emplace(&mesh, path(file.string())).first->second;
    }

    /** A rest pose (`rest`, positions for `mesh`'s vertices) as a PLY file of its own (positions
     *  and triangles: all a rest pose gives). Written once per mesh the scene holds (`shared`),
     *  else every time. */
    std::string rest_mesh(const TriangleMesh& mesh, const std::vector<float>& rest, bool shared) {
        if (shared)
            if (auto it = rests.find(&mesh); it != rests.end()) return it->second;
        TriangleMesh r;
        r.positions = rest;
        r.indices = mesh.indices;
        const fs::path file = mesh_dir / fmt::format("rest_{:03}.ply", rest_files++);
        write_ply(r, file.string(), "rest pose, written by spangle convert from " + mesh.source);
        report.meshes.push_back(file.string());
        if (!shared) return path(file.string());
        return rests.emplace(&mesh, path(file.string())).first->second;
    }

    /** A mesh the scene held itself: one PLY file, with its rest pose beside it when it has one;
     *  a deforming one as a numbered sequence of PLY files, one per frame of the scene's range,
     *  at each frame's time, and its rest pose. */
    void inline_shape(const InlineMeshShape& s) {
        if (!s.deformation || !s.deformation->animated()) {
            line("mesh", inline_mesh(*s.mesh));
            if (!s.mesh->rest_positions.empty())
                line("rest_mesh", rest_mesh(*s.mesh, s.mesh->rest_positions, true));
            return;
        }
        const int64_t first = frames->frame_start, last = frames->frame_end;
        if (last - first >= kMaxWrittenFrames)
            throw_error(s.loc,
                        "a deforming mesh would be written as {} files, one per frame (at most "
                        "{}): shorten the frame range",
                        last - first + 1, kMaxWrittenFrames);
        std::error_code ec;
        fs::create_directories(mesh_dir, ec);
        const std::string pattern =
            (mesh_dir / fmt::format("deform_{:03}.####.ply", sequences++)).string();
        std::shared_ptr<const TriangleMesh> shape;
        for (int64_t f = first; f <= last; ++f) {
            // Where the builder evaluates it: at the middle of the frame's shutter.
            const double time = static_cast<double>(f - first) / frames->fps;
            shape = s.deformation->at(
                frame_shutter(time, frames->fps, frames->shutter_open, frames->shutter_close)
                    .middle);
            const std::string file = expand_frame_pattern(pattern, f);
            write_ply(*shape, file,
                      "frame " + std::to_string(f) + ", written by spangle convert from " +
                          shape->source);
            report.meshes.push_back(file);
        }
        line("mesh", path(pattern));
        // The rest pose: the shape the deformation starts from (every frame that has one carries
        // the same; a frame without one is in it).
        line("rest_mesh",
             rest_mesh(*shape,
                       shape->rest_positions.empty() ? shape->positions : shape->rest_positions,
                       false));
    }

    /** A cage the scene held itself (pbrt's loopsubdiv), written once as an OBJ file. */
    std::string inline_cage(const Cage& cage) {
        auto it = cages.find(&cage);
        if (it != cages.end()) return it->second;
        std::error_code ec;
        fs::create_directories(mesh_dir, ec);
        const fs::path file = mesh_dir / fmt::format("cage_{:03}.obj", cages.size());
        write_obj_cage(cage, file.string(), "written by spangle convert from " + cage.source);
        report.meshes.push_back(file.string());
        return cages.emplace(&cage, path(file.string())).first->second;
    }

    void subdiv(const SubdivShape& s) {
        static const char* schemes[] = {"catmull-clark", "loop"};
        static const char* boundaries[] = {"none", "edge_only", "edge_and_corner"};
        static const char* uvs[] = {"smooth", "corners_only", "boundaries", "all"};
        const SubdivOptions& o = s.options;
        std::string t = fmt::format(
            "{{ scheme = {}, level = {}, max_level = {}, pixel_budget = {}, boundary = {}, "
            "uv_interpolation = {}",
            str(schemes[static_cast<int>(o.scheme)]),
            o.level < 0 ? str("auto") : fmt::to_string(o.level), s.max_level, num(s.pixel_budget),
            str(boundaries[static_cast<int>(o.boundary)]),
            str(uvs[static_cast<int>(o.uv_interpolation)]));
        std::vector<std::string> creases, corners;
        for (std::size_t i = 0; i < o.crease_sharpness.size(); ++i)
            creases.push_back(fmt::format("[{}, {}, {}]", o.crease_vertices[2 * i],
                                          o.crease_vertices[2 * i + 1],
                                          num(o.crease_sharpness[i])));
        for (std::size_t i = 0; i < o.corner_sharpness.size(); ++i)
            corners.push_back(
                fmt::format("[{}, {}]", o.corner_vertices[i], num(o.corner_sharpness[i])));
        if (!creases.empty()) t += fmt::format(", creases = [{}]", fmt::join(creases, ", "));
        if (!corners.empty()) t += fmt::format(", corners = [{}]", fmt::join(corners, ", "));
        line("mesh", s.cage ? inline_cage(*s.cage) : path(s.path));
        if (!s.rest_path.empty()) line("rest_mesh", path(s.rest_path));
        line("subdiv", t + " }");
    }

    void object(const ObjectDesc& o, uint32_t index) {
        out += "\n[[object]]\n";
        // Named as it was: the name a render gave an unnamed object ("object3", its mesh file's)
        // is its Cryptomatte id, and an inline mesh written to mesh_002.ply would go by that.
        line("name", str(object_name(o, index)));
        if (o.shadow_catcher) line("shadow_catcher", "true");
        if (const auto* m = std::get_if<MeshFileShape>(&o.shape)) {
            line("mesh", path(m->path));  // a sequence's pattern as it is
            if (!m->rest_path.empty()) line("rest_mesh", path(m->rest_path));
        } else if (const auto* s = std::get_if<SubdivShape>(&o.shape))
            subdiv(*s);
        else
            inline_shape(std::get<InlineMeshShape>(o.shape));
        line("material", str(o.material));
        if (o.placement.matrix || !o.matrix_keys.keys.empty()) {
            // Matrix keys need a matrix placement in TOML; with keys it is not used (the keys
            // give the placement at every time), so the first key's stands in.
            line("matrix", matrix12(o.placement.matrix ? *o.placement.matrix
                                                       : o.matrix_keys.keys.front().matrix));
        } else {
            line("translate", vec(o.placement.parts.translate));
            line("rotate", vec(o.placement.parts.rotate));
            line("scale", vec(o.placement.parts.scale));
        }
        if (o.parent) line("import_matrix", matrix12(*o.parent));
        if (o.emission) {
            line("emission", o.emission->texture ? texture(*o.emission->texture, "param")
                                                 : color(o.emission->color));
            line("emission_intensity", num(o.emission->intensity));
            if (o.emission->two_sided) line("emission_two_sided", "true");
            group(o.emission->group);
        }
        keys(o);
    }

    void keys(const ObjectDesc& o) {
        if (!o.matrix_keys.keys.empty()) {
            line("interpolation", str("linear"));
            for (const MatrixKey& k : o.matrix_keys.keys)
                out += "\n[[object.keys]]\n" + key_time(k.time) +
                       "\nmatrix = " + matrix12(k.matrix) + "\n";
            return;
        }
        if (o.keys.keys.empty()) return;
        line("interpolation", str(o.keys.smooth ? "smooth" : "linear"));
        for (const ObjectKey& k : o.keys.keys) {
            out += "\n[[object.keys]]\n" + key_time(k.time) + "\n";
            if (k.scale) line("scale", vec(*k.scale));
            if (k.rotate) line("rotate", vec(*k.rotate));
            if (k.translate) line("translate", vec(*k.translate));
        }
    }

    void light(const LightDesc& l) {
        out += "\n[[light]]\n";
        struct Shape {
            Writer& w;
            void operator()(const QuadLightDesc& q) const {
                w.line("type", str("quad"));
                w.line("corner", vec(q.corner));
                w.line("edge1", vec(q.edge1));
                w.line("edge2", vec(q.edge2));
                w.line("two_sided", q.two_sided ? "true" : "false");
                if (q.transparent) w.line("transparent", "true");
            }
            void operator()(const SphereLightDesc& s) const {
                w.line("type", str("sphere"));
                w.line("center", vec(s.center));
                w.line("radius", num(s.radius));
            }
            void operator()(const PointLightDesc& p) const {
                w.line("type", str("point"));
                w.line("position", vec(p.position));
            }
            void operator()(const SpotLightDesc& s) const {
                w.line("type", str("spot"));
                w.line("position", vec(s.position));
                w.line("look_at", vec(s.look_at));
                w.line("cone_angle", num(s.cone_angle));
                w.line("cone_falloff", num(s.cone_falloff));
                if (s.quartic) w.line("falloff", str("quartic"));
            }
            void operator()(const DistantLightDesc& d) const {
                w.line("type", str("distant"));
                w.line("direction", vec(d.direction));
                w.line("angular_radius", num(d.angular_radius_deg));
            }
        };
        std::visit(Shape{*this}, l.shape);
        if (l.color) line("color", color(*l.color));
        line("intensity", num(l.intensity));
        group(l.group);
    }
};

}  // namespace

SceneWriteReport write_toml_scene(const SceneDescription& scene, const std::string& path,
                                  const std::string& mesh_dir) {
    if (!scene.imports.empty() || !scene.has_camera)
        throw_error("{}: the scene's imports must be resolved before it is written", scene.path);
    Writer w;
    w.frames = &scene.render;
    w.dir = fs::absolute(path).parent_path();
    w.mesh_dir = fs::absolute(mesh_dir);
    w.out = fmt::format("# Written by spangle convert from {}\n\n", scene.path);
    w.render(scene.render);
    w.camera(scene.camera);
    if (scene.environment) w.environment(*scene.environment);
    for (const MaterialDesc& m : scene.materials) w.material(m);
    for (std::size_t i = 0; i < scene.objects.size(); ++i)
        w.object(scene.objects[i], static_cast<uint32_t>(i));
    for (const LightDesc& l : scene.lights) w.light(l);
    const std::string tmp = fmt::format("{}.tmp{}", path, ::getpid());
    {
        std::ofstream out(tmp, std::ios::binary);
        out << w.out;
        if (!out) {
            std::remove(tmp.c_str());
            throw_error("cannot write '{}'", path);
        }
    }
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) {
        std::remove(tmp.c_str());
        throw_error("cannot write '{}': {}", path, ec.message());
    }
    return w.report;
}

}  // namespace spangle
