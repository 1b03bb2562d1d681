// The procedural interior of `spangle bench`: see interior_scene.h.

#include "cli/interior_scene.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include "core/error.h"
#include "core/hash.h"
#include "core/math.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** A mesh being generated: positions, normals, uvs and triangles. */
struct GenMesh {
    std::vector<float> p, n, uv;  ///< per vertex: xyz, normal xyz, uv
    std::vector<uint32_t> tri;    ///< three vertex indices per triangle

    /** Appends a vertex; returns its index. */
    uint32_t add(Vec3 pos, Vec3 nrm, float u, float v) {
        const auto i = static_cast<uint32_t>(p.size() / 3);
        p.insert(p.end(), {pos.x, pos.y, pos.z});
        n.insert(n.end(), {nrm.x, nrm.y, nrm.z});
        uv.insert(uv.end(), {u, v});
        return i;
    }
};

/** A (nu x nv)-cell grid of the parametric surface f(u, v), u and v in [0, 1]; normals from
 *  central differences, turned to face away from centre(u, v) (the shape's axis). */
template <class F, class C>
void add_grid(GenMesh& m, uint32_t nu, uint32_t nv, F f, C centre) {
    const auto first = static_cast<uint32_t>(m.p.size() / 3);
    constexpr float kEps = 1e-4f;
    for (uint32_t j = 0; j <= nv; ++j)
        for (uint32_t i = 0; i <= nu; ++i) {
            const float u = static_cast<float>(i) / static_cast<float>(nu);
            const float v = static_cast<float>(j) / static_cast<float>(nv);
            const Vec3 p = f(u, v);
            const Vec3 du = f(u + kEps, v) - f(u - kEps, v);
            const Vec3 dv = f(u, std::min(v + kEps, 1.0f)) - f(u, std::max(v - kEps, 0.0f));
            Vec3 n = cross(du, dv);
            const Vec3 out = p - centre(u, v);
            if (!(length(n) > 1e-12f)) n = out;  // a pole
            n = normalize(n);
            if (dot(n, out) < 0.0f) n = -n;
            m.add(p, n, u, v);
        }
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            const uint32_t a = first + j * (nu + 1) + i, b = a + 1, c = a + nu + 1, d = c + 1;
            m.tri.insert(m.tri.end(), {a, b, d, a, d, c});
        }
}

/** A flat rectangle corner + s a + t b, (s, t) in [0, 1]^2, in nu x nv cells, facing `facing`;
 *  cells for which skip(s, t) holds at their centre are left out (a window). */
template <class S>
void add_rect(GenMesh& m, Vec3 corner, Vec3 a, Vec3 b, uint32_t nu, uint32_t nv, Vec3 facing,
              S skip) {
    Vec3 n = normalize(cross(a, b));
    const bool flip = dot(n, facing) < 0.0f;
    if (flip) n = -n;
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            const float s0 = static_cast<float>(i) / static_cast<float>(nu),
                        s1 = static_cast<float>(i + 1) / static_cast<float>(nu);
            const float t0 = static_cast<float>(j) / static_cast<float>(nv),
                        t1 = static_cast<float>(j + 1) / static_cast<float>(nv);
            if (skip(0.5f * (s0 + s1), 0.5f * (t0 + t1))) continue;
            const float su = length(a), sv = length(b);  // uv in metres
            const uint32_t q0 = m.add(corner + a * s0 + b * t0, n, s0 * su, t0 * sv);
            const uint32_t q1 = m.add(corner + a * s1 + b * t0, n, s1 * su, t0 * sv);
            const uint32_t q2 = m.add(corner + a * s1 + b * t1, n, s1 * su, t1 * sv);
            const uint32_t q3 = m.add(corner + a * s0 + b * t1, n, s0 * su, t1 * sv);
            if (flip)
                m.tri.insert(m.tri.end(), {q0, q2, q1, q0, q3, q2});
            else
                m.tri.insert(m.tri.end(), {q0, q1, q2, q0, q2, q3});
        }
}

/** Writes m as a binary little-endian PLY with normals and uvs. */
void write_ply(const GenMesh& m, const std::string& path) {
    std::ofstream out(path, std::ios::binary);
    const std::size_t nv = m.p.size() / 3, nf = m.tri.size() / 3;
    out << "ply\nformat binary_little_endian 1.0\ncomment made by spangle bench\n"
        << "element vertex " << nv
        << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n"
           "property float ny\nproperty float nz\nproperty float u\nproperty float v\n"
        << "element face " << nf << "\nproperty list uchar uint vertex_indices\nend_header\n";
    std::vector<char> buf;
    buf.reserve(nv * 32 + nf * 13);
    const auto put = [&](const void* data, std::size_t bytes) {
        const auto* c = static_cast<const char*>(data);
        buf.insert(buf.end(), c, c + bytes);
    };
    for (std::size_t i = 0; i < nv; ++i) {
        put(&m.p[3 * i], 12);
        put(&m.n[3 * i], 12);
        put(&m.uv[2 * i], 8);
    }
    for (std::size_t f = 0; f < nf; ++f) {
        const uint8_t three = 3;
        put(&three, 1);
        put(&m.tri[3 * f], 12);
    }
    out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    if (!out) throw_error("cannot write '{}'", path);
}

constexpr float kPi = 3.14159265358979f;

/** A ball of radius 0.38..0.5 standing on the floor. */
GenMesh ball_mesh(float r1) {
    GenMesh m;
    const float rad = 0.38f + 0.12f * r1;
    add_grid(
        m, 120, 45,
        [=](float u, float v) {
            const float th = v * kPi, ph = 2 * kPi * u;
            return Vec3(rad * std::sin(th) * std::cos(ph), rad + rad * std::cos(th),
                        rad * std::sin(th) * std::sin(ph));
        },
        [=](float, float) { return Vec3(0, rad, 0); });
    return m;
}

/** A standing ring (a torus on its edge). */
GenMesh ring_mesh(float r1, float r2) {
    GenMesh m;
    const float big = 0.35f + 0.1f * r1, small = 0.08f + 0.06f * r2;
    add_grid(
        m, 120, 45,
        [=](float u, float v) {
            const float a = 2 * kPi * u, b = 2 * kPi * v;
            const float rr = big + small * std::cos(b);
            return Vec3(rr * std::cos(a), big + small + rr * std::sin(a), small * std::sin(b));
        },
        [=](float u, float) {
            const float a = 2 * kPi * u;
            return Vec3(big * std::cos(a), big + small + big * std::sin(a), 0.0f);
        });
    return m;
}

/** A twisted, tapering column of rounded-square section. */
GenMesh column_mesh(float r1, float r2) {
    GenMesh m;
    const float h = 1.0f + 0.8f * r1, w = 0.22f + 0.06f * r2, twist = kPi * (0.5f + r1);
    add_grid(
        m, 90, 60,
        [=](float u, float v) {
            const float a = 2 * kPi * u, c = std::cos(a), s = std::sin(a);
            // A superellipse of exponent 4: |x|^4 + |z|^4 = w^4.
            const float x = w * std::copysign(std::sqrt(std::fabs(c)), c);
            const float z = w * std::copysign(std::sqrt(std::fabs(s)), s);
            const float t = twist * v, ct = std::cos(t), st = std::sin(t);
            const float taper = 1.0f - 0.3f * v;
            return Vec3((x * ct - z * st) * taper, h * v, (x * st + z * ct) * taper);
        },
        [=](float, float v) { return Vec3(0, h * v, 0); });
    return m;
}

/** A lumpy blob: a sphere with a sinusoidal bump pattern. */
GenMesh blob_mesh(float r1, float r2) {
    GenMesh m;
    const float rad = 0.42f, fa = 3.0f + std::floor(4.0f * r1), fb = 2.0f + std::floor(3.0f * r2);
    add_grid(
        m, 120, 45,
        [=](float u, float v) {
            const float th = v * kPi, ph = 2 * kPi * u;
            const float r = rad * (1.0f + 0.12f * std::sin(fa * ph) * std::sin(fb * th));
            return Vec3(r * std::sin(th) * std::cos(ph), rad * 1.15f + r * std::cos(th),
                        r * std::sin(th) * std::sin(ph));
        },
        [=](float, float) { return Vec3(0, rad * 1.15f, 0); });
    return m;
}

/** Object k of the interior: one of four shapes, its proportions varied by k so that every
 *  mesh is distinct (no instancing: 30 separate BVHs' worth of triangles). About 10,800
 *  triangles each. */
GenMesh make_object(uint32_t k) {
    const float r1 = to_unit_float(hash2(k, 1)), r2 = to_unit_float(hash2(k, 2));
    switch (k % 4) {
        case 0:
            return ball_mesh(r1);
        case 1:
            return ring_mesh(r1, r2);
        case 2:
            return column_mesh(r1, r2);
        default:
            return blob_mesh(r1, r2);
    }
}

/** The interior's materials, as TOML: walls, floor and m0..m11 for the objects. */
constexpr const char* kInteriorMaterials = R"(
[[material]]
name = "walls"
plugin = "smooth"
model = "diffuse"
params = { albedo = 0.72 }

[[material]]
name = "floor"
plugin = "smooth"
model = "plastic"
params = { albedo = [0.36, 0.2, 0.1], roughness = 0.25 }

[[material]]
name = "m0"
plugin = "smooth"
model = "diffuse"
params = { albedo = [0.7, 0.1, 0.08] }

[[material]]
name = "m1"
plugin = "smooth"
model = "conductor"
params = { preset = "gold", roughness = 0.2 }

[[material]]
name = "m2"
plugin = "smooth"
model = "plastic"
params = { albedo = [0.1, 0.45, 0.15], roughness = 0.05 }

[[material]]
name = "m3"
plugin = "flake"
params = { base_color = [0.02, 0.05, 0.3], flake_weight = 0.5, density = 2000000, gamma = 3, coat = true }

[[material]]
name = "m4"
plugin = "smooth"
model = "dielectric"
params = { ior = 1.5, roughness = 0.0 }

[[material]]
name = "m5"
plugin = "smooth"
model = "conductor"
params = { preset = "copper", roughness = 0.35 }

[[material]]
name = "m6"
plugin = "smooth"
model = "diffuse"
params = { albedo = [0.15, 0.25, 0.6] }

[[material]]
name = "m7"
plugin = "flake"
params = { base_color = [0.3, 0.3, 0.32], flake_weight = 0.7, density = 500000, gamma = 5, color_table = true }

[[material]]
name = "m8"
plugin = "smooth"
model = "conductor"
params = { preset = "silver", roughness = 0.04 }

[[material]]
name = "m9"
plugin = "smooth"
model = "dielectric"
params = { ior = 1.45, roughness = 0.15 }

[[material]]
name = "m10"
plugin = "smooth"
model = "plastic"
params = { albedo = [0.8, 0.6, 0.1], roughness = 0.4 }

[[material]]
name = "m11"
plugin = "smooth"
model = "plastic"
params = { albedo = 0.02, roughness = 0.1 }
)";

constexpr uint32_t kInteriorObjects = 30, kInteriorMaterialCount = 12;

/** The room: 12 x 4 x 10 m, a window in the left wall; writes floor.ply and walls.ply. */
void write_room(const std::string& dir) {
    GenMesh floor, walls;
    const auto none = [](float, float) { return false; };
    add_rect(floor, {-6, 0, -5}, {12, 0, 0}, {0, 0, 10}, 24, 20, {0, 1, 0}, none);
    add_rect(walls, {-6, 4, -5}, {12, 0, 0}, {0, 0, 10}, 24, 20, {0, -1, 0}, none);  // ceiling
    add_rect(walls, {-6, 0, -5}, {12, 0, 0}, {0, 4, 0}, 24, 8, {0, 0, 1}, none);     // back
    add_rect(walls, {-6, 0, 5}, {12, 0, 0}, {0, 4, 0}, 24, 8, {0, 0, -1}, none);     // front
    add_rect(walls, {6, 0, -5}, {0, 0, 10}, {0, 4, 0}, 20, 8, {-1, 0, 0}, none);     // right
    add_rect(walls, {-6, 0, -5}, {0, 0, 10}, {0, 4, 0}, 20, 8, {1, 0, 0},            // left
             [](float s, float t) { return s > 0.2f && s < 0.6f && t > 0.25f && t < 0.8f; });
    write_ply(floor, (fs::path(dir) / "floor.ply").string());
    write_ply(walls, (fs::path(dir) / "walls.ply").string());
}

/** Writes the objects' meshes (object_NN.ply) into dir; returns their [[object]] tables, placed
 *  on a grid of six columns with a turn each. */
std::string write_objects(const std::string& dir) {
    std::string objects;
    for (uint32_t k = 0; k < kInteriorObjects; ++k) {
        const std::string name = fmt::format("object_{:02}.ply", k);
        write_ply(make_object(k), (fs::path(dir) / name).string());
        const uint32_t col = k % 6, row = k / 6;
        const float x = -4.5f + 1.8f * static_cast<float>(col) + 0.3f * static_cast<float>(row % 2);
        const float z = -3.8f + 1.5f * static_cast<float>(row);
        const float turn = 360.0f * to_unit_float(hash2(k, 3));
        objects += fmt::format(
            "\n[[object]]\nmesh = \"{}\"\nmaterial = \"m{}\"\ntranslate = [{:.3f}, 0, {:.3f}]\n"
            "rotate = [0, {:.1f}, 0]\n",
            name, (k * 7) % kInteriorMaterialCount, x, z, turn);
    }
    return objects;
}

/** The scene file: render settings, the camera inside looking at -z, a ceiling panel and the
 *  sun, then the materials ({0}) and the objects ({1}). */
constexpr const char* kInteriorScene =
    R"(# A procedural interior for `spangle bench`: a closed room lit by a ceiling panel and by the
# sun through a window, with 30 distinct meshes (about 330,000 triangles) in 14 materials of
# both plugins. Paths bounce many times before they leave. Written by spangle bench; rewritten
# when missing.

[render]
width = 640
height = 360
spp = 16
max_depth = 12
rr_depth = 4
filter = "gaussian"
working_space = "ACEScg"
color_space = "srgb_texture"

[camera]
position = [0.5, 1.7, 4.6]
look_at = [-0.3, 0.6, -1.0]
fov = 62

[environment]
color = {{ rgb = [0.5, 0.65, 1.0], space = "lin_rec709" }}

[[light]]
type = "quad"
corner = [-1.0, 3.98, -1.0]
edge1 = [2.0, 0.0, 0.0]
edge2 = [0.0, 0.0, 1.0]
intensity = 12

[[light]]
type = "distant"
direction = [-1.0, 0.8, 0.35]
intensity = 4
angular_radius = 0.3
{}
[[object]]
mesh = "floor.ply"
material = "floor"

[[object]]
mesh = "walls.ply"
material = "walls"
{})";

}  // namespace

std::string write_interior_scene(const std::string& dir) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw_error("cannot create '{}': {}", dir, ec.message());
    write_room(dir);
    const std::string objects = write_objects(dir);
    const std::string scene = fmt::format(kInteriorScene, kInteriorMaterials, objects);
    const std::string path = (fs::path(dir) / "interior.toml").string();
    std::ofstream out(path, std::ios::binary);
    out << scene;
    if (!out) throw_error("cannot write '{}'", path);
    return path;
}

}  // namespace spangle
