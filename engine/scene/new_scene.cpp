#include "scene/new_scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <variant>

#include "color/image_io.h"
#include "core/error.h"
#include "core/text.h"
#include "geometry/mesh_load.h"
#include "geometry/ply_writer.h"
#include "scene/object_placement.h"
#include "scene/scene_loader.h"
#include "scene/scene_paths.h"
#include "scene/toml_scene_writer.h"

namespace fs = std::filesystem;

namespace spangle {

void Box::add(Vec3 p) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
}

namespace {

constexpr double kPiD = 3.14159265358979323846;
constexpr double kFovDeg = 30.0;  ///< the camera's vertical field of view
/** Flakes a pixel of the written image sees at the look_at distance: few enough that each pixel
 *  holds separate glints (the discrete lobe is used below the flake material's min_flakes, 500),
 *  many enough that the paint reads as a paint and not as scattered points. */
constexpr double kFlakesPerPixel = 30.0;

std::string lower_extension(const std::string& path) {
    return ascii_lower(fs::path(path).extension().string());
}

bool is_gltf(const std::string& path) {
    const std::string e = lower_extension(path);
    return e == ".gltf" || e == ".glb";
}

void add_mesh(Box& box, const TriangleMesh& mesh, const Affine& to_world) {
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v)
        box.add(to_world.apply_point(mesh.position(static_cast<uint32_t>(v))));
}

/** The area of triangle (a, b, c), in double (a large model's products overflow a float). */
double triangle_area(Vec3 a, Vec3 b, Vec3 c) {
    const double ux = double(b.x) - double(a.x), uy = double(b.y) - double(a.y),
                 uz = double(b.z) - double(a.z);
    const double vx = double(c.x) - double(a.x), vy = double(c.y) - double(a.y),
                 vz = double(c.z) - double(a.z);
    const double x = uy * vz - uz * vy, y = uz * vx - ux * vz, z = ux * vy - uy * vx;
    return 0.5 * std::sqrt(x * x + y * y + z * z);
}

/** Adds the mesh's surface area in its own coordinates to `own` and as placed to `placed`. */
void add_areas(const TriangleMesh& mesh, const Affine& to_world, double& own, double& placed) {
    for (std::size_t t = 0; 3 * t + 2 < mesh.indices.size(); ++t) {
        const Vec3 p0 = mesh.position(mesh.indices[3 * t]),
                   p1 = mesh.position(mesh.indices[3 * t + 1]),
                   p2 = mesh.position(mesh.indices[3 * t + 2]);
        own += triangle_area(p0, p1, p2);
        placed += triangle_area(to_world.apply_point(p0), to_world.apply_point(p1),
                                to_world.apply_point(p2));
    }
}

/** `path` as a scene file at `dir` should name it: relative when it lies in `dir` or below,
 *  else absolute (as `spangle convert` names files). */
std::string scene_relative(const fs::path& path, const fs::path& dir) {
    const fs::path rel = path.lexically_relative(dir);
    if (!rel.empty() && *rel.begin() != "..") return rel.generic_string();
    return path.generic_string();
}

/** `s` inside a TOML comment: a control character (a newline in a file or material name)
 *  would end the comment and leave the rest to be read as TOML. */
std::string comment_safe(std::string s) {
    for (char& c : s)
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
    return s;
}

std::string vec4g(Vec3 v) {
    // + 0.0f: a negated zero reads 0, not -0.
    return fmt::format("[{:.4g}, {:.4g}, {:.4g}]", v.x + 0.0f, v.y + 0.0f, v.z + 0.0f);
}

/** Rounds to two significant digits, so the written density reads as a chosen number. */
double two_digits(double x) {
    const double p = std::pow(10.0, std::floor(std::log10(x)) - 1.0);
    return std::round(x / p) * p;
}

/** The camera distance along `dir` from `look_at` at which every corner of `box` lies inside
 *  85% of the image (so the model fills the frame with a margin). */
double framing_distance(const Box& box, Vec3 look_at, Vec3 dir, double aspect) {
    const Vec3 fwd = -dir;
    const Vec3 right = normalize(cross(fwd, Vec3{0, 1, 0}));
    const Vec3 up = cross(right, fwd);
    const double ty = std::tan(kFovDeg * kPiD / 360.0) * 0.85, tx = ty * aspect;
    double d = 0.0;
    for (int i = 0; i < 8; ++i) {
        const Vec3 c{(i & 1) ? box.hi.x : box.lo.x, (i & 2) ? box.hi.y : box.lo.y,
                     (i & 4) ? box.hi.z : box.lo.z};
        const Vec3 r = c - look_at;
        const double along = double(dot(r, dir));
        const double x = double(std::abs(dot(r, right))), y = double(std::abs(dot(r, up)));
        d = std::max({d, along + x / tx, along + y / ty});
    }
    return d;
}

}  // namespace

std::string shell_word(const std::string& s) {
    const bool plain = !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || std::strchr("_./+-,:=@%", c);
    });
    if (plain) return s;
    std::string out = "'";
    for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

Vec3 up_rotation(const std::string& up) {
    // R_x(-90) takes +z to +y, R_x(90) -z; R_z(90) takes +x to +y, R_z(-90) -x; R_x(180) -y.
    if (up == "y" || up == "+y") return {0, 0, 0};
    if (up == "z" || up == "+z") return {-90, 0, 0};
    if (up == "-z") return {90, 0, 0};
    if (up == "x" || up == "+x") return {0, 0, 90};
    if (up == "-x") return {0, 0, -90};
    if (up == "-y") return {180, 0, 0};
    throw_error("up axis '{}': expected x, y, z, -x, -y or -z", up);
}

Box model_bounds(const std::string& model, std::vector<std::string>* notes, double* area_ratio,
                 const Affine& orient) {
    if (area_ratio) *area_ratio = 1.0;
    std::error_code ec;
    const fs::path abs = fs::absolute(model, ec).lexically_normal();
    if (!fs::is_regular_file(abs, ec))
        throw_error("model file '{}' not found (looked for {})", model, abs.string());
    const std::string e = lower_extension(model);
    Box box;
    if (e == ".obj" || e == ".ply") {
        const TriangleMesh mesh = load_mesh(abs.string(), FileLoc{});
        add_mesh(box, mesh, orient);
        if (notes)
            for (const std::string& n : mesh.notes)
                notes->push_back(fmt::format("mesh '{}': {}", model, n));
    } else if (is_gltf(model)) {
        const SceneDescription scene = read_scene(abs.string());
        if (notes) notes->insert(notes->end(), scene.notes.begin(), scene.notes.end());
        // The area ratio of the objects the paint goes on (the first material's: `new` paints
        // that one), or of all where none names it.
        const std::string paint = scene.materials.empty() ? "" : scene.materials.front().name;
        const bool any_painted =
            std::any_of(scene.objects.begin(), scene.objects.end(),
                        [&](const ObjectDesc& o) { return o.material == paint; });
        double own = 0.0, placed = 0.0;
        for (const ObjectDesc& o : scene.objects) {
            // Where it stands at the first frame (an animated node's keys place it; its
            // placement alone stood it at the origin, and the model floated).
            Affine m =
                placement_motion(o, scene.render.frame_start, scene.render.fps, Shutter{}).middle;
            if (o.parent) m = o.parent->compose(m);
            m = orient.compose(m);  // the import's rotate turns the whole scene
            if (const auto* s = std::get_if<InlineMeshShape>(&o.shape)) {
                add_mesh(box, *s->mesh, m);
                if (!any_painted || o.material == paint) add_areas(*s->mesh, m, own, placed);
            } else if (const auto* f = std::get_if<MeshFileShape>(&o.shape); f && !f->sequence) {
                const TriangleMesh mesh = load_mesh(f->path, f->loc);
                add_mesh(box, mesh, m);
                if (!any_painted || o.material == paint) add_areas(mesh, m, own, placed);
            }
        }
        if (area_ratio && own > 0.0 && placed > 0.0 && std::isfinite(placed / own))
            *area_ratio = placed / own;
    } else {
        throw_error("model file '{}': unknown kind '{}' (expected .obj, .ply, .gltf or .glb)",
                    model, e);
    }
    if (box.empty()) throw_error("model file '{}' has no triangles", abs.string());
    return box;
}

NewSceneReport write_new_scene(const NewSceneRequest& r) {
    std::error_code ec;
    const fs::path out = fs::absolute(r.output, ec).lexically_normal();
    const fs::path folder = out.parent_path();
    const fs::path model = fs::absolute(r.model, ec).lexically_normal();
    const fs::path env = fs::absolute(r.env_map, ec).lexically_normal();
    if (!fs::is_regular_file(env, ec))
        throw_error("environment map '{}' not found (looked for {})", r.env_map, env.string());
    // Read now, so that a map that is not an image, or is cut short, is said here rather than
    // when the scene written around it first renders: whole up to 256 MiB on disk, its header
    // beyond (a 16k map's pixels are gigabytes).
    {
        const uintmax_t bytes = fs::file_size(env, ec);
        ImageHeader header;
        if (!ec && bytes <= (uintmax_t{256} << 20))
            read_image(env.string(), 3, header, "environment map");
        else
            read_image_header(env.string(), "environment map");
    }
    NewSceneReport rep;
    double area_ratio = 1.0;
    rep.rotate = up_rotation(r.up);
    TransformParts turn;
    turn.rotate = rep.rotate;
    rep.model_bounds = model_bounds(r.model, &rep.notes, &area_ratio, compose_parts(turn));
    const Box& b = rep.model_bounds;
    // Stand the model on the ground (y = 0), centred over the origin.
    rep.offset = {-b.centre().x, -b.lo.y, -b.centre().z};
    // A flat model (a leaf, a card, a decal lying in y = const) would lie in the ground's plane
    // and fight it for every pixel: it is lifted by a thousandth of its size.
    const Vec3 model_size = b.hi - b.lo;
    if (model_size.y < 1e-3f * std::max(model_size.x, model_size.z))
        rep.offset.y += 1e-3f * std::max(model_size.x, model_size.z);
    Box placed;
    placed.add(b.lo + rep.offset);
    placed.add(b.hi + rep.offset);
    const Vec3 size = placed.hi - placed.lo;
    // In double: the squares of a 1e20 model's extent overflow a float.
    const double extent = std::hypot(double(size.x), double(size.y), double(size.z));
    // Everything the scene writes lies within about 40 model sizes of the origin; a scene's
    // coordinates are at most 1e30.
    if (!(extent < 1e27))
        throw_error(
            "model '{}' is {:.3g} units across: too large for a scene (coordinates are at "
            "most 1e30); scale it down",
            r.model, extent);
    const float radius = std::max(0.5f * static_cast<float>(extent), 1e-6f);
    rep.look_at = placed.centre();
    rep.fov_deg = kFovDeg;
    // A three-quarter view from slightly above, as a product shot is taken.
    const Vec3 view = normalize(Vec3{0.75f, 0.38f, 1.0f});
    const double aspect = double(r.width) / double(r.height);
    double dist = framing_distance(placed, rep.look_at, view, aspect);
    // A model with no extent (one point, or all its vertices alike) is framed as a tiny one.
    if (!(dist > 0.5 * double(radius))) dist = 4.0 * double(radius);
    rep.camera = rep.look_at + view * static_cast<float>(dist);
    // Flakes per square unit such that a pixel at the look_at distance sees kFlakesPerPixel.
    const double pixel = 2.0 * dist * std::tan(kFovDeg * kPiD / 360.0) / r.height;
    // The paint's density counts flakes per square unit of the meshes' own coordinates (object
    // space): a glTF whose nodes scale its meshes (centimetres under a scale of 0.01, as
    // converters write) has area_ratio square units of the scene per square unit of its meshes.
    const double per_area = kFlakesPerPixel / (pixel * pixel) * area_ratio;
    rep.density = std::isfinite(per_area) ? std::clamp(two_digits(per_area), 1e-6, 2.0e9) : 2.0e9;
    rep.flakes_per_pixel = rep.density / area_ratio * pixel * pixel;
    // A model small in its own units wants more flakes per square unit than the paint takes:
    // said, and the scene's comment says so (it read "raise density" at the largest one).
    const bool capped = rep.flakes_per_pixel < 0.5 * kFlakesPerPixel;
    if (capped)
        rep.notes.push_back(fmt::format(
            "the model is {:.3g} units across: at the paint's largest density (2e9 flakes per "
            "square unit) a pixel sees about {:.2g} flakes, not {:.0f}, so its glitter is sparse; "
            "for the usual look, model it in smaller units (millimetres instead of metres)",
            extent, rep.flakes_per_pixel, kFlakesPerPixel));

    // The ground: a square 40 model sizes wide, written beside the scene.
    rep.ground = r.ground.empty() ? (folder / (out.stem().string() + "_ground.ply")).string()
                                  : fs::absolute(r.ground, ec).lexically_normal().string();
    TriangleMesh ground;
    const float g = 20.0f * radius;
    ground.positions = {-g, 0, -g, g, 0, -g, g, 0, g, -g, 0, g};
    ground.normals = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    ground.uvs = {0, 0, 1, 0, 1, 1, 0, 1};
    ground.indices = {0, 2, 1, 0, 3, 2};
    write_ply(ground, rep.ground, "ground plane written by spangle new");

    // The key light: a small sphere above the camera's shoulder, 4 radii from the model, whose
    // irradiance there is 2.5 (E = L pi a^2 / D^2 for a sphere of radius a at distance D).
    const Vec3 key = rep.look_at + normalize(Vec3{0.25f, 1.0f, 0.7f}) * (4.0f * radius);
    const double key_radius = 0.15 * double(radius);
    const double key_radiance = 2.5 * 16.0 / (kPiD * 0.15 * 0.15);

    std::string paint = "paint";
    std::vector<std::string> other_materials;
    if (is_gltf(r.model)) {
        const SceneDescription scene = read_scene(model.string());
        for (const MaterialDesc& m : scene.materials) other_materials.push_back(m.name);
        if (!other_materials.empty()) {
            paint = other_materials.front();
            other_materials.erase(other_materials.begin());
        }
    }
    rep.paint = paint;
    std::vector<std::string> quoted_others;
    for (const std::string& m : other_materials) quoted_others.push_back(toml_basic_string(m));

    // The turn that stands the model up (--up), applied before its offset (rotate, then
    // translate), as its bounds above were taken.
    const std::string rotate_line =
        rep.rotate.x == 0.0f && rep.rotate.y == 0.0f && rep.rotate.z == 0.0f
            ? std::string()
            : fmt::format("rotate = [{:g}, {:g}, {:g}]      # the model's {} axis up\n",
                          rep.rotate.x, rep.rotate.y, rep.rotate.z, comment_safe(r.up));
    std::string t;
    t += fmt::format(
        "# A scene around {} written by `spangle new`: the model on a ground plane, lit by an\n"
        "# environment map and a key light, the camera framed on the model's bounds, and a flake\n"
        "# paint to start from. Render it with\n"
        "#     spangle render {} -o {}\n"
        "# Paths are relative to this file. The model's bounds: {} to {} (its own units{}).\n\n",
        comment_safe(model.filename().string()), comment_safe(shell_word(out.filename().string())),
        comment_safe(shell_word(out.stem().string() + ".exr")), vec4g(b.lo), vec4g(b.hi),
        r.up == "y" || r.up == "+y" ? std::string()
                                    : fmt::format(", turned so that its {} axis points up", r.up));
    t += fmt::format(
        "[render]\nwidth = {}\nheight = {}\nspp = 64\nmax_depth = 6\nfilter = \"blackman-harris\"\n"
        "clamp_indirect = 20            # a firefly guard for caustics; biased, 0 = off\n"
        "filter_glossy = 1              # caustics through mirrors and coats blurred, not "
        "fireflies; biased, 0 = off\n"
        "working_space = \"ACEScg\"\ncolor_space = \"srgb_texture\"\n\n",
        r.width, r.height);
    t += fmt::format("[camera]\nposition = {}\nlook_at = {}\nfov = {:g}\n\n", vec4g(rep.camera),
                     vec4g(rep.look_at), kFovDeg);
    // The map's own colour space (the one its EXR header names, else its file type's usual
    // one): "lin_rec709" was written for every map, and an 8-bit sRGB PNG was read as linear.
    t += fmt::format(
        "[environment]\nmap = {}\n# color_space: left to the map (its EXR header's space, else "
        "lin_rec709 for EXR and HDR,\n# srgb_texture for 8- and 16-bit files)\nrotation = "
        "0\nintensity = 1.0\n\n",
        toml_basic_string(scene_relative(env, folder)));
    t += fmt::format(
        "[[light]]                      # the key light: small, so that flakes flash\n"
        "type = \"sphere\"\ncenter = {}\nradius = {:.4g}\ncolor = [1.0, 0.97, 0.92]\n"
        "intensity = {:.4g}\n\n",
        vec4g(key), key_radius, key_radiance);
    t += fmt::format(
        "[[material]]\nname = {}\nplugin = \"flake\"\n"
        "# Red glitter paint under a clear coat. density counts flakes per square unit of the\n"
        "# model (density_space = \"object\": no uvs needed); at this camera a pixel sees about\n"
        "# {} flakes, {}\n"
        "# lower it for sparser, bigger-looking sparkle; flake_roughness spreads\n"
        "# the glints over the surface, gamma makes each flake's cone (and glint) wider.\n"
        "params = {{ base_color = [0.55, 0.03, 0.04], flake_weight = 0.5, density = {:.6g}, "
        "density_space = \"object\", flake_roughness = 0.2, gamma = 2, color_table = true, "
        "hue_spread = 30, table_l = 0.6, coat = true, coat_ior = 1.5 }}\n\n",
        toml_basic_string(paint),
        rep.flakes_per_pixel >= 10.0 ? fmt::format("{:.0f}", rep.flakes_per_pixel)
                                     : fmt::format("{:.2g}", rep.flakes_per_pixel),
        capped ? "as many as the largest density gives (the model is small in its own\n# units: "
                 "model it in smaller ones for more);"
               : "so each pixel holds a few separate glints. Raise density for a finer\n# "
                 "metallic look,",
        rep.density);
    t += "[[material]]\nname = \"spangle_new_ground\"\nplugin = \"smooth\"\nmodel = \"plastic\"\n"
         "params = { albedo = 0.3, roughness = 0.35 }\n\n";
    t += fmt::format(
        "[[object]]\nname = \"ground\"\nmesh = {}\nmaterial = \"spangle_new_ground\"\n\n",
        toml_basic_string(scene_relative(rep.ground, folder)));
    if (is_gltf(r.model)) {
        t += fmt::format(
            "[[import]]                     # the model, with its own materials; the flake paint\n"
            "                               # above replaces its material {}{}\n"
            "file = {}\n{}translate = {}\ncamera = false\nenvironment = false\nlights = false\n",
            toml_basic_string(paint),
            other_materials.empty()
                ? std::string()
                : fmt::format(" (its others: {})", fmt::join(quoted_others, ", ")),
            toml_basic_string(scene_relative(model, folder)), rotate_line, vec4g(rep.offset));
    } else {
        t += fmt::format(
            "[[object]]\nname = \"model\"\nmesh = {}\nmaterial = {}\n{}translate = {}\n",
            toml_basic_string(scene_relative(model, folder)), toml_basic_string(paint), rotate_line,
            vec4g(rep.offset));
    }

    const fs::path tmp = out.string() + ".tmp";
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    if (!f) throw_error("cannot write the scene '{}'", out.string());
    const bool ok = std::fwrite(t.data(), 1, t.size(), f) == t.size();
    if (std::fclose(f) != 0 || !ok) {
        fs::remove(tmp, ec);
        throw_error("cannot write the scene '{}'", out.string());
    }
    fs::rename(tmp, out, ec);
    if (ec) throw_error("cannot write the scene '{}': {}", out.string(), ec.message());
    return rep;
}

}  // namespace spangle
