// pbrt's shapes: triangle meshes written in the file, PLY meshes (read by mesh_load; here when
// they must turn or emit a given power), bilinear patch meshes, Loop subdivision cages (refined
// by the subdivide system), and spheres, disks and cylinders tessellated finely enough that their
// silhouettes stay within a few ten-thousandths of their radius. Every shape takes the current
// material, area light and orientation.

#include <algorithm>
#include <cmath>
#include <optional>

#include "geometry/mesh_load.h"
#include "scene/pbrt/pbrt_state.h"

namespace spangle::pbrt {

namespace {

/** Segments of a full turn of a tessellated quadric: the chord's sagitta is r (1 - cos(pi /
 *  128)) = 3e-4 r, and the vertex normals are exact, so shading does not facet. */
constexpr int kTurnSegments = 256;

/** What a shape directive made. */
struct Made {
    ShapeDesc shape;                           ///< the shape
    std::shared_ptr<const TriangleMesh> mesh;  ///< its triangles, when the reader made them
    /** A quadric's exact area in its own space, which pbrt's 'power' divides by (0: the
     *  placed triangles' area). */
    double object_area = 0.0;
    /** A scale the shape's placement applies first (a sphere is the shared unit sphere scaled
     *  by its radius). */
    double scale = 1.0;
};

/** Whether the faces must turn: pbrt orients faces by ReverseOrientation and a mirroring
 *  transform, where Spangle orients them by their winding in world space. */
bool flip_faces(const Reader& r) {
    return r.gs.reverse != (r.gs.ctm[0].determinant3() < 0.0);
}

/** Where parameter `name` is written, else `loc` (the shape's): errors in a value are said at
 *  it, as a uv's were (a normal's or an index's were at the line's first column). */
FileLoc param_at(const ParamList& p, std::string_view name, const FileLoc& loc) {
    const Param* param = p.find(name);
    return param ? param->loc : loc;
}

/** Checks the vertex indices of a mesh: `per` per face, each within `n` vertices. */
std::vector<uint32_t> checked_indices(const std::vector<double>& idx, std::size_t per,
                                      std::size_t n, const char* what, const FileLoc& loc) {
    if (idx.empty() || idx.size() % per != 0)
        throw_error(loc, "{}: \"integer indices\" must hold {} per face, got {}", what, per,
                    idx.size());
    std::vector<uint32_t> out(idx.size());
    for (std::size_t i = 0; i < idx.size(); ++i) {
        const double v = idx[i];
        if (!(v >= 0.0 && v < static_cast<double>(n)) || v != std::floor(v))
            throw_error(loc, "{}: index {} (#{}) is not a vertex (the mesh has {})", what, v, i, n);
        out[i] = static_cast<uint32_t>(v);
    }
    return out;
}

/** The positions, normals and uvs common to trianglemesh and bilinearmesh, checked. */
void read_vertices(const Reader& r, const ParamList& p, const char* what, const FileLoc& loc,
                   TriangleMesh& m) {
    const std::vector<double>& P = p.numbers("P", {"point3"});
    if (P.empty() || P.size() % 3 != 0)
        throw_error(param_at(p, "P", loc),
                    "{}: \"point3 P\" must hold x y z per vertex, got {} numbers", what, P.size());
    m.positions.assign(P.begin(), P.end());
    for (std::size_t i = 0; i < P.size(); ++i)
        if (!std::isfinite(m.positions[i]))
            throw_error(param_at(p, "P", loc),
                        "{}: \"point3 P\" value #{} ({}) is beyond a float's range", what, i, P[i]);
    const std::size_t n = P.size() / 3;
    const std::vector<double>& N = p.numbers("N", {"normal3"});
    if (!N.empty()) {
        if (N.size() != P.size())
            throw_error(param_at(p, "N", loc),
                        "{}: \"normal N\" must hold one normal per vertex ({}), got {}", what, n,
                        N.size() / 3);
        m.normals.resize(N.size());
        for (std::size_t v = 0; v < n; ++v) {
            const Vec3 nv(static_cast<float>(N[3 * v]), static_cast<float>(N[3 * v + 1]),
                          static_cast<float>(N[3 * v + 2]));
            const float len = length(nv);
            const Vec3 u = len > 0.0f ? nv / len : Vec3(0, 0, 1);
            m.normals[3 * v] = u.x;
            m.normals[3 * v + 1] = u.y;
            m.normals[3 * v + 2] = u.z;
        }
    }
    const Param* uv = p.find("uv", {"point2", "float"});
    if (!uv) uv = p.find("st", {"point2", "float"});
    if (uv) {
        if (uv->numbers.size() != 2 * n)
            throw_error(uv->loc, "{}: \"{} {}\" must hold one (u, v) per vertex ({}), got {}", what,
                        uv->type, uv->name, n, uv->numbers.size() / 2);
        m.uvs.assign(uv->numbers.begin(), uv->numbers.end());
    }
    m.source = fmt::format("{}:{}", loc.file, loc.line);
    (void)r;
}

/** Turns every face of `m` (winding and normals) when `flip_winding` / `flip_normals`. */
void orient(TriangleMesh& m, bool flip_winding, bool flip_normals) {
    if (flip_winding) m.reverse_winding();
    if (flip_normals)
        for (float& c : m.normals) c = -c;
}

/** How a mesh with authored normals and one without turn, as pbrt orients them: v3 leaves
 *  authored normals alone, v4 turns them under ReverseOrientation. */
void orient_like_pbrt(const Reader& r, TriangleMesh& m) {
    if (m.normals.empty())
        orient(m, flip_faces(r), false);
    else
        orient(m, false, r.v4() && r.gs.reverse);
}

Made trianglemesh(Reader& r, const ParamList& p, const FileLoc& loc) {
    auto m = std::make_shared<TriangleMesh>();
    read_vertices(r, p, "trianglemesh", loc, *m);
    const std::size_t n = m->vertex_count();
    std::vector<double> idx = p.numbers("indices", {"integer"});
    if (idx.empty() && n == 3) idx = {0, 1, 2};  // v4: three vertices need no indices
    m->indices = checked_indices(idx, 3, n, "trianglemesh", param_at(p, "indices", loc));
    orient_like_pbrt(r, *m);
    return {InlineMeshShape{m, loc}, m};
}

/** One bilinear patch p00 p10 p01 p11 as triangles: two when it is planar, else a grid. */
void bilinear_patch(const TriangleMesh& in, const uint32_t c[4], TriangleMesh& out) {
    const Vec3 p00 = in.position(c[0]), p10 = in.position(c[1]), p01 = in.position(c[2]),
               p11 = in.position(c[3]);
    const Vec3 n = cross(p10 - p00, p01 - p00);
    const float off = std::fabs(dot(p11 - p00, length(n) > 0.0f ? normalize(n) : Vec3(0.0f)));
    const float size = length(p11 - p00) + length(p10 - p01);
    const int g = off <= 1e-5f * size ? 1 : 8;
    const auto base = static_cast<uint32_t>(out.vertex_count());
    const bool has_uv = !in.uvs.empty(), has_n = !in.normals.empty();
    for (int j = 0; j <= g; ++j)
        for (int i = 0; i <= g; ++i) {
            const float u = static_cast<float>(i) / static_cast<float>(g),
                        v = static_cast<float>(j) / static_cast<float>(g);
            const float w[4] = {(1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v};
            Vec3 p(0.0f), nn(0.0f);
            float uu = 0, vv = 0;
            for (int k = 0; k < 4; ++k) {
                p += in.position(c[k]) * w[k];
                if (has_n)
                    nn += Vec3(in.normals[3 * c[k]], in.normals[3 * c[k] + 1],
                               in.normals[3 * c[k] + 2]) *
                          w[k];
                if (has_uv) {
                    uu += in.uvs[2 * c[k]] * w[k];
                    vv += in.uvs[2 * c[k] + 1] * w[k];
                }
            }
            out.positions.insert(out.positions.end(), {p.x, p.y, p.z});
            if (has_n) {
                const Vec3 un = length(nn) > 0.0f ? normalize(nn) : Vec3(0, 0, 1);
                out.normals.insert(out.normals.end(), {un.x, un.y, un.z});
            }
            // pbrt's default (u, v) of a patch are its bilinear parameters.
            out.uvs.insert(out.uvs.end(), {has_uv ? uu : u, has_uv ? vv : v});
        }
    for (int j = 0; j < g; ++j)
        for (int i = 0; i < g; ++i) {
            const uint32_t a = base + static_cast<uint32_t>(j * (g + 1) + i);
            const uint32_t b = a + 1, d = a + static_cast<uint32_t>(g + 1), e = d + 1;
            out.indices.insert(out.indices.end(), {a, b, e, a, e, d});
        }
}

Made bilinearmesh(Reader& r, const ParamList& p, const FileLoc& loc) {
    r.sign(true, loc, "Shape \"bilinearmesh\"");
    TriangleMesh in;
    read_vertices(r, p, "bilinearmesh", loc, in);
    std::vector<double> idx = p.numbers("indices", {"integer"});
    if (idx.empty() && in.vertex_count() == 4) idx = {0, 1, 2, 3};
    const std::vector<uint32_t> quads =
        checked_indices(idx, 4, in.vertex_count(), "bilinearmesh", param_at(p, "indices", loc));
    auto m = std::make_shared<TriangleMesh>();
    m->source = in.source;
    for (std::size_t q = 0; q < quads.size(); q += 4) bilinear_patch(in, &quads[q], *m);
    orient_like_pbrt(r, *m);
    return {InlineMeshShape{m, loc}, m};
}

Made plymesh(Reader& r, const ParamList& p, const FileLoc& loc) {
    const std::string file = p.string("filename", "");
    if (file.empty()) throw_error(loc, "plymesh needs \"string filename\"");
    const std::string path = r.find_file(file, "plymesh filename", loc);
    // The file is read here, turned as pbrt turns it, when its faces or normals must turn
    // (ReverseOrientation, a mirroring transform) or an area light's 'power' needs its area;
    // otherwise the mesh system reads it (and caches it between reloads).
    const bool turn = flip_faces(r) || (r.v4() && r.gs.reverse);
    if (!turn && !(r.gs.area && r.gs.area->power))
        return {MeshFileShape{path, loc, false, {}, {}}, nullptr};
    const std::string key =
        fmt::format("ply {} {} {}", path, flip_faces(r), r.v4() && r.gs.reverse);
    auto& cached = r.shape_cache[key];
    if (!cached) {
        auto m = std::make_shared<TriangleMesh>(load_mesh(path, loc));
        for (const std::string& note : m->notes)
            r.notes.add(loc, fmt::format("mesh '{}': {}", path, note));
        orient_like_pbrt(r, *m);
        cached = m;
        r.d.files.push_back(path);  // watched and hashed as the scene's own files are
    }
    return {InlineMeshShape{cached, loc}, cached};
}

Made loopsubdiv(Reader& r, const ParamList& p, const FileLoc& loc) {
    auto cage = std::make_shared<Cage>();
    const std::vector<double>& P = p.numbers("P", {"point3"});
    if (P.empty() || P.size() % 3 != 0)
        throw_error(loc, "loopsubdiv: \"point3 P\" must hold x y z per vertex, got {} numbers",
                    P.size());
    cage->positions.assign(P.begin(), P.end());
    for (std::size_t i = 0; i < P.size(); ++i)
        if (!std::isfinite(cage->positions[i]))
            throw_error(param_at(p, "P", loc),
                        "loopsubdiv: \"point3 P\" value #{} ({}) is beyond a float's range", i,
                        P[i]);
    const std::vector<uint32_t> idx =
        checked_indices(p.numbers("indices", {"integer"}), 3, P.size() / 3, "loopsubdiv",
                        param_at(p, "indices", loc));
    cage->face_vertices.assign(idx.begin(), idx.end());
    cage->face_sizes.assign(idx.size() / 3, 3);
    if (flip_faces(r))
        for (std::size_t f = 0; f < idx.size(); f += 3)
            std::swap(cage->face_vertices[f + 1], cage->face_vertices[f + 2]);
    cage->source = fmt::format("{}:{}", loc.file, loc.line);
    validate_cage(*cage, loc);
    if (const std::size_t turned = orient_cage(*cage))
        r.notes.add(loc, fmt::format("loopsubdiv: {} of its {} faces are wound against their "
                                     "neighbours: turned to agree",
                                     turned, cage->face_count()));
    const Param* levels = p.find("levels", {"integer"});
    if (!levels) levels = p.find("nlevels", {"integer"});
    double level = levels && !levels->numbers.empty() ? levels->numbers[0] : 3.0;
    if (!(level >= 0.0 && level <= 8.0)) {
        r.notes.add(loc, fmt::format("loopsubdiv levels {} is outside 0..8: {} stands in", level,
                                     level < 0 ? 0 : 8));
        level = level < 0 ? 0.0 : 8.0;
    }
    SubdivShape s;
    s.cage = cage;
    s.loc = loc;
    s.options.scheme = SubdivOptions::Scheme::Loop;
    // pbrt's Loop boundary rule keeps boundary edges as creases (the 1/8, 3/4, 1/8 rule).
    s.options.boundary = SubdivOptions::Boundary::EdgeOnly;
    s.options.level = static_cast<int>(level);
    return {std::move(s), nullptr};
}

/** A grid of (nu + 1) x (nv + 1) vertices from `at(u, v, p, n)` (u, v in [0, 1]), two triangles
 *  per cell wound so that dp/du x dp/dv faces out; triangles of no area (at poles) are left out. */
template <class At>
std::shared_ptr<TriangleMesh> grid(int nu, int nv, const At& at, const FileLoc& loc) {
    auto m = std::make_shared<TriangleMesh>();
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i <= nu; ++i) {
            const double u = static_cast<double>(i) / nu, v = static_cast<double>(j) / nv;
            Vec3 p, n;
            at(u, v, p, n);
            m->positions.insert(m->positions.end(), {p.x, p.y, p.z});
            m->normals.insert(m->normals.end(), {n.x, n.y, n.z});
            m->uvs.insert(m->uvs.end(), {static_cast<float>(u), static_cast<float>(v)});
        }
    const auto vid = [&](int i, int j) { return static_cast<uint32_t>(j * (nu + 1) + i); };
    const auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
        if (length(cross(m->position(b) - m->position(a), m->position(c) - m->position(a))) > 0.0f)
            m->indices.insert(m->indices.end(), {a, b, c});
    };
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            add(vid(i, j), vid(i + 1, j), vid(i + 1, j + 1));
            add(vid(i, j), vid(i + 1, j + 1), vid(i, j + 1));
        }
    m->source = fmt::format("{}:{}", loc.file, loc.line);
    return m;
}

/** phimax of a quadric, degrees in (0, 360], as radians. */
double phi_max(Reader& r, const ParamList& p, const FileLoc& loc) {
    double phimax = p.number("phimax", 360.0);
    if (!(phimax > 0.0 && phimax <= 360.0)) {
        r.notes.add(loc, fmt::format("phimax {} is outside (0, 360]: 360 stands in", phimax));
        phimax = 360.0;
    }
    return phimax * M_PI / 180.0;
}

/** Segments for an angle of `radians`. */
int segments(double radians, int full) {
    return std::max(4, static_cast<int>(std::ceil(full * radians / (2.0 * M_PI))));
}

/** A tessellated quadric; none (said) when it has no surface: pbrt draws nothing for a disk
 *  whose inner radius reaches its radius or a cylinder of no height, and Spangle failed the
 *  whole scene on one such shape among thousands. */
std::optional<Made> quadric(Reader& r, const std::string& type, const ParamList& p,
                            const FileLoc& loc) {
    const double radius = p.number("radius", 1.0);
    if (!(radius > 0.0)) {
        r.notes.add(loc, fmt::format("{}: 'radius' {} is not positive: the shape has no surface "
                                     "and is dropped",
                                     type, radius));
        return std::nullopt;
    }
    const double phimax = phi_max(r, p, loc);
    // Quadrics turn with ReverseOrientation (and a mirror) in both versions: their normals are
    // pbrt's computed ones.
    const bool flip = flip_faces(r);
    const std::string turned = flip ? " turned" : "";
    std::string key;
    std::shared_ptr<TriangleMesh> m;
    double area = 0.0, scale = 1.0;
    if (type == "sphere") {
        const double z0 = std::clamp(p.number("zmin", -radius), -radius, radius),
                     z1 = std::clamp(p.number("zmax", radius), -radius, radius);
        const double t0 = std::acos(std::min(z0, z1) / radius),
                     t1 = std::acos(std::max(z0, z1) / radius);
        // Every sphere is the unit sphere of its cut scaled by its radius: 2000 spheres of as
        // many radii made 2000 meshes of 65 280 triangles (13 GB).
        key = fmt::format("sphere {} {} {}{}", t0, t1, phimax, turned);
        area = phimax * radius * std::fabs(z1 - z0);
        scale = radius;
        if (!r.shape_cache.count(key))
            m = grid(
                segments(phimax, kTurnSegments),
                std::max(2, static_cast<int>(std::ceil(kTurnSegments / 2 * (t0 - t1) / M_PI))),
                [&](double u, double v, Vec3& pos, Vec3& n) {
                    const double phi = u * phimax, th = t0 + v * (t1 - t0);
                    n = Vec3(static_cast<float>(std::sin(th) * std::cos(phi)),
                             static_cast<float>(std::sin(th) * std::sin(phi)),
                             static_cast<float>(std::cos(th)));
                    pos = n;
                },
                loc);
    } else if (type == "disk") {
        const double h = p.number("height", 0.0), ri = p.number("innerradius", 0.0);
        if (!(ri >= 0.0 && ri < radius)) {
            r.notes.add(loc, fmt::format("disk: 'innerradius' {} is not in [0, radius {}): the "
                                         "disk has no surface and is dropped",
                                         ri, radius));
            return std::nullopt;
        }
        key = fmt::format("disk {} {} {} {}{}", radius, h, ri, phimax, turned);
        area = 0.5 * phimax * (radius * radius - ri * ri);
        if (!r.shape_cache.count(key))
            m = grid(
                segments(phimax, kTurnSegments), 4,
                [&](double u, double v, Vec3& pos, Vec3& n) {
                    const double phi = u * phimax, rr = radius + v * (ri - radius);
                    pos = Vec3(static_cast<float>(rr * std::cos(phi)),
                               static_cast<float>(rr * std::sin(phi)), static_cast<float>(h));
                    n = Vec3(0, 0, 1);
                },
                loc);
    } else {
        const double z0 = p.number("zmin", -1.0), z1 = p.number("zmax", 1.0);
        if (!(z0 != z1)) {
            r.notes.add(loc,
                        "cylinder: 'zmin' and 'zmax' are equal: the cylinder has no "
                        "surface and is dropped");
            return std::nullopt;
        }
        key = fmt::format("cylinder {} {} {} {}{}", radius, std::min(z0, z1), std::max(z0, z1),
                          phimax, turned);
        area = phimax * radius * std::fabs(z1 - z0);
        if (!r.shape_cache.count(key))
            m = grid(
                segments(phimax, kTurnSegments), 1,
                [&](double u, double v, Vec3& pos, Vec3& n) {
                    const double phi = u * phimax;
                    const double z = std::min(z0, z1) + v * std::fabs(z1 - z0);
                    n = Vec3(static_cast<float>(std::cos(phi)), static_cast<float>(std::sin(phi)),
                             0.0f);
                    pos = Vec3(static_cast<float>(radius * std::cos(phi)),
                               static_cast<float>(radius * std::sin(phi)), static_cast<float>(z));
                },
                loc);
    }
    auto& cached = r.shape_cache[key];
    if (!cached) {
        orient(*m, flip, flip);
        cached = m;
    }
    return Made{InlineMeshShape{cached, loc}, cached, area, scale};
}

/** The shape's emission from the current area light; v4 "power" needs its area. */
EmissionDesc emission_of(Reader& r, const AreaLight& a, const Made& made, const FileLoc& loc) {
    EmissionDesc e;
    e.color = a.L;
    e.intensity = a.scale;
    e.two_sided = a.two_sided;
    e.texture = a.image;
    if (a.power) {
        // pbrt-v4: the radiance that makes the shape emit `power` watts, pi A per side, with A
        // a quadric's area in its own space (pbrt's Sphere::Area() and the like: a scaled
        // sphere keeps the radiance of the unscaled one) and a mesh's as placed.
        const Mat4& xf = r.gs.ctm[0];
        const double area = made.object_area > 0.0 ? made.object_area
                            : made.mesh
                                ? placed_area(*made.mesh, [&](Vec3 p) { return xf.point(p); })
                                : 0.0;
        if (area > 0.0)
            e.intensity = a.scale * *a.power / (M_PI * area * (a.two_sided ? 2.0 : 1.0));
        else
            r.notes.add(loc,
                        "area light 'power' on a shape whose area is not known here (a "
                        "subdivision surface): 'L' x 'scale' stands in");
    }
    return e;
}

/** A shape's `alpha` as the host's alpha (pbrt-v4: the chance a ray meets the surface, 1
 *  opaque, 0 none): a number, or a float texture's image read as pbrt reads it (kAlphaPbrt);
 *  none when the shape is opaque. */
std::optional<ParamDesc> alpha_of(Reader& r, ParamList& p) {
    const Param* q = p.find("alpha", {"float", "texture"});
    if (!q) return std::nullopt;
    ParamDesc d;
    d.name = "alpha";
    d.loc = d.key_loc = q->loc;
    d.kind = ParamDesc::Kind::Number;
    if (q->type == "float") {
        if (q->numbers.empty()) return std::nullopt;
        d.number = std::clamp(q->numbers[0], 0.0, 1.0);
        if (!(d.number < 1.0)) return std::nullopt;
        return d;
    }
    const std::string& name = q->strings.empty() ? std::string() : q->strings[0];
    const auto it = r.float_textures.find(name);
    if (it == r.float_textures.end()) {
        r.notes.add(q->loc,
                    fmt::format("alpha texture '{}' is not defined: the shape is opaque", name));
        return std::nullopt;
    }
    if (!it->second.image) {
        d.number = std::clamp(static_cast<double>(it->second.value.x), 0.0, 1.0);
        if (!(d.number < 1.0)) return std::nullopt;
        return d;
    }
    d.kind = ParamDesc::Kind::Texture;
    d.texture = it->second.tex;
    d.texture.channel = kAlphaPbrt;
    return d;
}

/** An emitting sphere as a sphere light, where one stands for it exactly: a whole sphere
 *  (no zmin, zmax or phimax cut) placed by a transform without motion that keeps it a sphere
 *  (a rotation, a uniform scale and a move), emitting outward (not two-sided, not turned by
 *  ReverseOrientation or a mirror), uniformly (no image), opaque and brightly (radiance of
 *  luminance at least 0.5). Spangle samples a sphere
 *  light by the cone of directions it subtends, as pbrt samples its spheres; the tessellated
 *  sphere's triangles were picked by area, and a small sphere lit a floor with 3 times the
 *  noise of the point light of its power. False (nothing made) otherwise. */
bool sphere_light(Reader& r, const ParamList& p, const Made& made, bool alpha, const FileLoc& loc) {
    const AreaLight* a = r.gs.area ? &*r.gs.area : nullptr;
    if (!a || a->two_sided || a->image || alpha || flip_faces(r) || !r.defining.empty() ||
        !(r.gs.ctm[0] == r.gs.ctm[1]))
        return false;
    const double radius = p.number("radius", 1.0);
    if (p.number("zmin", -radius) > -radius || p.number("zmax", radius) < radius ||
        p.number("phimax", 360.0) < 360.0)
        return false;
    // The linear part's columns: orthogonal and of one length.
    const Mat4& m = r.gs.ctm[0];
    const Vec3 c[3] = {m.vector({1, 0, 0}), m.vector({0, 1, 0}), m.vector({0, 0, 1})};
    const double s = static_cast<double>(length(c[0]));
    if (!(s > 0.0) || !std::isfinite(s)) return false;
    for (int i = 0; i < 3; ++i) {
        if (std::fabs(static_cast<double>(length(c[i])) - s) > 1e-5 * s) return false;
        for (int j = i + 1; j < 3; ++j)
            if (std::fabs(static_cast<double>(dot(c[i], c[j]))) > 1e-5 * s * s) return false;
    }
    const EmissionDesc e = emission_of(r, *a, made, loc);
    // A dim emitter (a glowing ball of radiance below 0.5) may look mostly by what its material
    // reflects, which a sphere light does not: it stays an emitting object.
    const Vec3 rgb = e.color.rgb;
    const double lum = kRec709YDouble[0] * static_cast<double>(rgb.x) +
                       kRec709YDouble[1] * static_cast<double>(rgb.y) +
                       kRec709YDouble[2] * static_cast<double>(rgb.z);
    if (!(e.intensity * lum >= 0.5)) return false;
    LightDesc l;
    l.shape = SphereLightDesc{m.point({0, 0, 0}), radius * s};
    l.color = e.color;
    l.intensity = e.intensity;
    l.loc = loc;
    l.group = e.group;
    l.group.loc = loc;
    r.d.lights.push_back(std::move(l));
    r.notes.add(loc,
                "an emitting sphere is a sphere light (sampled by the cone it subtends, as pbrt "
                "does): its material is dropped (it reflects no other light)");
    return true;
}

}  // namespace

void read_shape(Reader& r, const std::string& type, ParamList& p, const FileLoc& loc) {
    ++r.info.shapes;
    const std::string what = fmt::format("Shape \"{}\"", type);
    if (r.gs.no_surface) {
        for (const Param& q : p.all()) q.used = true;  // a medium boundary: nothing to render
        // pbrt ignores an area light there too (it emitted here).
        if (r.gs.area)
            r.notes.add(loc,
                        "an area light on a shape of material \"interface\" (a medium's "
                        "boundary): pbrt ignores it, and so does Spangle");
        return;
    }
    Made made;
    if (type == "trianglemesh")
        made = trianglemesh(r, p, loc);
    else if (type == "plymesh")
        made = plymesh(r, p, loc);
    else if (type == "bilinearmesh")
        made = bilinearmesh(r, p, loc);
    else if (type == "loopsubdiv")
        made = loopsubdiv(r, p, loc);
    else if (type == "sphere" || type == "disk" || type == "cylinder") {
        std::optional<Made> q = quadric(r, type, p, loc);
        if (!q) {
            for (const Param& x : p.all()) x.used = true;
            return;
        }
        made = std::move(*q);
    } else {
        for (const Param& q : p.all()) q.used = true;
        r.notes.add(loc, fmt::format("{} is not supported: dropped", what));
        return;
    }
    const std::optional<ParamDesc> alpha = alpha_of(r, p);
    r.notes.unused(p, what);
    if (type == "sphere" && sphere_light(r, p, made, alpha.has_value(), loc)) return;
    ObjectDesc o;
    o.shape = std::move(made.shape);
    o.loc = loc;
    o.what = fmt::format("{} at {}:{}", what, loc.file, loc.line);
    o.material = r.gs.material.empty() ? default_material(r, loc) : r.gs.material;
    o.material_loc = loc;
    if (alpha) {
        // One entry per different alpha, so that equal ones share one material.
        const auto same = [&](const ParamDesc& a) {
            const TextureDesc &x = a.texture, &y = alpha->texture;
            return a.kind == alpha->kind && a.number == alpha->number && x.path == y.path &&
                   x.channel == y.channel && x.scale[0] == y.scale[0] &&
                   std::equal(std::begin(x.uv), std::end(x.uv), std::begin(y.uv)) &&
                   x.wrap == y.wrap && x.space == y.space;
        };
        auto it = std::find_if(r.alphas.begin(), r.alphas.end(), same);
        if (it == r.alphas.end()) it = r.alphas.insert(it, *alpha);
        o.material += fmt::format("{}{}", kAlphaMark, it - r.alphas.begin());
    }
    if (r.gs.area) {
        if (!r.defining.empty())
            r.notes.add(loc,
                        "an area light inside an object definition: its shapes do not emit "
                        "(pbrt refuses it too)");
        else
            o.emission = emission_of(r, *r.gs.area, made, loc);
    }
    Mat4 xf[2] = {r.gs.ctm[0], r.gs.ctm[1]};
    if (made.scale != 1.0)
        for (Mat4& m : xf) m = m * Mat4::scale(made.scale, made.scale, made.scale);
    if (!r.defining.empty()) {
        r.definitions[r.defining].push_back({std::move(o), {xf[0], xf[1]}});
        return;
    }
    place_object(r, std::move(o), xf);
}

}  // namespace spangle::pbrt
