// Subdivision surfaces: limit normals (unit, continuous, identical across uv seams), face-varying
// uv seams kept, uv derivatives finite at extraordinary vertices, camera-chosen levels, and cages
// that are odd but valid (non-manifold, zero-area faces, unreferenced vertices).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>

#include "core/error.h"
#include "geometry/cage.h"
#include "geometry/subdivision.h"
#include "pipeline/frame.h"
#include "render/surface.h"
#include "test_support.h"

namespace spangle::test_subdivision {
namespace {

/** A unit cube cage: 8 vertices, 6 quads, each face its own uv tile (u in [f, f + 1]). */
Cage cube_cage() {
    Cage c;
    c.source = "cube";
    for (int i = 0; i < 8; ++i)
        c.positions.insert(c.positions.end(), {(i & 1) ? 1.0f : -1.0f, (i & 2) ? 1.0f : -1.0f,
                                               (i & 4) ? 1.0f : -1.0f});
    const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                             {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int f = 0; f < 6; ++f) {
        c.face_sizes.push_back(4);
        const float corners[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
        for (int k = 0; k < 4; ++k) {
            c.face_vertices.push_back(faces[f][k]);
            c.face_uvs.push_back(static_cast<int>(c.uvs.size() / 2));
            c.uvs.insert(c.uvs.end(), {static_cast<float>(f) + corners[k][0], corners[k][1]});
        }
    }
    return c;
}

SubdivOptions level(int l) {
    SubdivOptions o;
    o.level = l;
    return o;
}

Vec3 pos(const TriangleMesh& m, uint32_t i) {
    return m.position(i);
}
Vec3 nrm(const TriangleMesh& m, uint32_t i) {
    return {m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2]};
}

TEST(Subdivision, LimitNormalsAreUnitOutwardAndContinuous) {
    const TriangleMesh m = subdivide(cube_cage(), level(4), {});
    ASSERT_EQ(m.triangle_count(), 6u * 256u * 2u);
    double worst = 0.0;
    for (std::size_t t = 0; t < m.triangle_count(); ++t) {
        const uint32_t a = m.indices[3 * t], b = m.indices[3 * t + 1], c = m.indices[3 * t + 2];
        for (uint32_t v : {a, b, c}) {
            ASSERT_NEAR(length(nrm(m, v)), 1.0f, 1e-5f);
            ASSERT_GT(dot(nrm(m, v), normalize(pos(m, v))), 0.5f)
                << "limit normals point out of the closed surface";
        }
        // Neighbouring limit normals differ by no more than the surface turns between them: at
        // level 4 an edge spans about 1/16 of a cube side, about 6 degrees of turning.
        for (auto [p, q] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}})
            worst = std::max(
                worst,
                std::acos(std::clamp(static_cast<double>(dot(nrm(m, p), nrm(m, q))), -1.0, 1.0)));
    }
    EXPECT_LT(worst * 180.0 / M_PI, 10.0);
}

TEST(Subdivision, UvSeamsAreKeptAndSplitVerticesShareGeometry) {
    const TriangleMesh m = subdivide(cube_cage(), level(3), {});
    // Every triangle lies inside one uv tile: no triangle stretches across a seam.
    for (std::size_t t = 0; t < m.triangle_count(); ++t) {
        float lo = 1e9f, hi = -1e9f;
        for (int k = 0; k < 3; ++k) {
            const float u = m.uvs[2 * m.indices[3 * t + static_cast<std::size_t>(k)]];
            lo = std::min(lo, u);
            hi = std::max(hi, u);
        }
        ASSERT_EQ(std::floor(lo + 1e-4f), std::floor(hi - 1e-4f))
            << "triangle " << t << " spans a seam";
    }
    // Vertices split by a seam have one position and one normal.
    std::map<std::tuple<long, long, long>, std::vector<uint32_t>> at;
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
        const Vec3 p = pos(m, v);
        at[{std::lround(p.x * 1e5), std::lround(p.y * 1e5), std::lround(p.z * 1e5)}].push_back(v);
    }
    std::size_t split = 0;
    for (const auto& [key, vs] : at) {
        if (vs.size() < 2) continue;
        ++split;
        for (uint32_t v : vs) {
            EXPECT_EQ(nrm(m, v), nrm(m, vs[0]));
            EXPECT_EQ(pos(m, v), pos(m, vs[0]));
        }
    }
    EXPECT_GT(split, 0u) << "a cube with a uv tile per face has seams";
}

TEST(Subdivision, UvDerivativesFiniteAtExtraordinaryVertices) {
    const TriangleMesh m = subdivide(cube_cage(), level(3), {});
    // The cube's corners are valence-3 extraordinary vertices; check every triangle (they
    // include those around the corners) through the renderer's own surface code.
    Instance inst;
    int near_corner = 0;
    for (std::size_t t = 0; t < m.triangle_count(); ++t) {
        Hit h;
        h.prim = static_cast<uint32_t>(t);
        h.b1 = h.b2 = 1.0f / 3.0f;
        const SurfacePoint sp = surface_at(m, inst, h, {0, 0, 5}, {0, 0, -1});
        ASSERT_TRUE(is_finite(sp.dpdu) && is_finite(sp.dpdv)) << "triangle " << t;
        ASSERT_GT(sp.uv_area, 0.0f) << "triangle " << t;
        const Vec3 p = pos(m, m.indices[3 * t]);
        near_corner += std::fabs(std::fabs(p.x) - std::fabs(p.y)) < 0.05f &&
                       std::fabs(std::fabs(p.y) - std::fabs(p.z)) < 0.05f;
        bool diff = true;
        SurfacePoint with_fp = sp;
        RayDifferential r{};
        r.o = sp.p + sp.n * 2.0f;
        r.d = -sp.n;
        r.dx_o = r.o + sp.s * 0.01f;
        r.dx_d = r.d;
        r.dy_o = r.o + sp.t * 0.01f;
        r.dy_d = r.d;
        footprint_at(with_fp, r, diff, 0.0f);
        ASSERT_TRUE(std::isfinite(with_fp.dudx) && std::isfinite(with_fp.dvdy)) << "triangle " << t;
    }
    EXPECT_GT(near_corner, 0) << "the check reached the extraordinary vertices";
}

TEST(Subdivision, LevelFollowsTheCamera) {
    // A 1 m edge, 1 mrad pixels: 1000 px at 1 m -> 2^9 > 1000 / 2 needs level 9, clamped to 6;
    // at 100 m: 10 px -> level 3; at 1 km: 1 px -> level 0.
    EXPECT_EQ(level_for_camera(1.0, 1.0, 1e-3, 2.0, 6), 6);
    EXPECT_EQ(level_for_camera(1.0, 100.0, 1e-3, 2.0, 6), 3);
    EXPECT_EQ(level_for_camera(1.0, 1000.0, 1e-3, 2.0, 6), 0);
    // In a scene: two snowballs, one near and one far, both "auto".
    FrameRequest req;
    req.scene = test::test_dir() + "/scenes/subdiv_near_far.toml";
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    const FrameResult r = render_frame(req);
    ASSERT_EQ(r.subdiv.size(), 2u);
    EXPECT_TRUE(r.subdiv[0].from_camera);
    EXPECT_GT(r.subdiv[0].level, r.subdiv[1].level) << "the near object is refined more";
    EXPECT_GT(r.subdiv[0].triangles, r.subdiv[1].triangles);
}

TEST(Subdivision, OddButValidCagesRefine) {
    // Three quads sharing one edge (non-manifold), a zero-area face, an unreferenced vertex.
    Cage c;
    c.source = "odd";
    c.positions = {0, 0,  0, 1, 0,  0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 1, 0, 1,
                   0, -1, 0, 1, -1, 0, 5, 5, 5, 2, 0, 0, 2, 0, 0, 2, 0, 0};
    c.face_sizes = {4, 4, 4, 3};
    c.face_vertices = {0, 1, 3, 2, 1, 0, 4, 5, 0, 1, 7, 6, 9, 10, 11};
    ASSERT_NO_THROW(validate_cage(c, {}));
    const TriangleMesh m = subdivide(c, level(2), {});
    EXPECT_GT(m.triangle_count(), 0u);
    for (float x : m.positions) ASSERT_TRUE(std::isfinite(x));
    for (float x : m.normals) ASSERT_TRUE(std::isfinite(x));
}

TEST(Subdivision, FacesWoundAgainstTheirNeighboursAreTurned) {
    // A cube cage with one face written the other way round (mirrored or merged parts in real
    // cages): OpenSubdiv took its edges as seams, a flat sharp-edged panel on a rounded body.
    // Turned to agree with its neighbours, the cage refines as the consistent one does; the
    // majority's winding is kept however many faces are turned.
    const Cage good = cube_cage();
    Cage bad = good;
    std::reverse(bad.face_vertices.begin() + 9, bad.face_vertices.begin() + 12);  // face 2
    std::reverse(bad.face_uvs.begin() + 9, bad.face_uvs.begin() + 12);
    Cage fixed = bad;
    EXPECT_EQ(orient_cage(fixed), 1u);
    EXPECT_EQ(fixed.face_vertices, good.face_vertices);
    EXPECT_EQ(fixed.face_uvs, good.face_uvs);
    Cage same = good;
    EXPECT_EQ(orient_cage(same), 0u) << "a consistent cage is left alone";
    // Five of six turned: the one face that disagrees is the one turned back.
    Cage mostly = good;
    for (std::size_t f = 1; f < 6; ++f)
        std::reverse(mostly.face_vertices.begin() + static_cast<std::ptrdiff_t>(4 * f + 1),
                     mostly.face_vertices.begin() + static_cast<std::ptrdiff_t>(4 * f + 4));
    Cage flipped_good = mostly;
    EXPECT_EQ(orient_cage(flipped_good), 1u);
    const TriangleMesh a = subdivide(good, level(3), {});
    const TriangleMesh b = subdivide(fixed, level(3), {});
    ASSERT_EQ(a.positions.size(), b.positions.size());
    for (std::size_t i = 0; i < a.positions.size(); ++i)
        ASSERT_NEAR(a.positions[i], b.positions[i], 1e-6f);
}

TEST(Subdivision, CagesAreReadWithTheMeshReadersSyntax) {
    // The cage reader is the OBJ mesh reader keeping faces whole (it was tinyobjloader): a byte
    // order mark no longer hides the first vertex (every face index moved by one, a sheet of
    // random triangles and no word), a backslash continues a line, a face of two corners and
    // a repeated vertex are errors at the file's line in its own numbering.
    const test::TempDir dir("cage_syntax");
    const std::string cube =
        "v -1 -1 -1\nv 1 -1 -1\nv -1 1 -1\nv 1 1 -1\nv -1 -1 1\nv 1 -1 1\nv -1 1 1\n"
        "v 1 1 1\nf 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 \\\n6\n";
    std::ofstream(dir.file("bom.obj")) << "\xEF\xBB\xBF" << cube;
    const Cage c = load_cage(dir.file("bom.obj"), {});
    EXPECT_EQ(c.vertex_count(), 8u);
    ASSERT_EQ(c.face_count(), 6u);
    EXPECT_EQ(c.positions[0], -1.0f);
    EXPECT_EQ(std::vector<int>(c.face_vertices.end() - 4, c.face_vertices.end()),
              (std::vector<int>{1, 3, 7, 5}))
        << "the continued line";
    const auto error = [&](const std::string& text) {
        std::ofstream(dir.file("bad.obj")) << text;
        try {
            load_cage(dir.file("bad.obj"), {});
        } catch (const SpangleError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    EXPECT_NE(error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n")
                  .find("line 5: face has 2 corners; a face needs at least 3"),
              std::string::npos);
    EXPECT_NE(error("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 2 4\n")
                  .find("line 5: the face uses vertex 2 twice"),
              std::string::npos);
}

TEST(Subdivision, SceneWithoutSubdivisionNeverRunsIt) {
    FrameRequest req;
    req.scene = test::test_dir() + "/scenes/furnace_sphere.toml";
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.spp_override = 1;
    const FrameResult r = render_frame(req);
    for (const auto& s : r.systems)
        if (s.name == "subdivide") {
            EXPECT_FALSE(s.ran);
            EXPECT_EQ(s.reason, "no SubdivSurface");
        }
    EXPECT_TRUE(r.subdiv.empty());
}

TEST(Subdivision, TriangleEstimateIsExact) {
    // The estimate the memory check uses, against what subdivide() makes: quads (the cube), an
    // n-gon and triangles under both schemes.
    Cage mixed = cube_cage();
    mixed.uvs.clear();
    mixed.face_uvs.clear();
    mixed.positions.insert(mixed.positions.end(), {3, 0, 0, 4, 0, 0, 4, 1, 0, 3.5f, 2, 0, 3, 1, 0});
    mixed.face_sizes.push_back(5);
    for (int v = 8; v < 13; ++v) mixed.face_vertices.push_back(v);
    Cage tris;
    tris.source = "tetra";
    tris.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    tris.face_sizes = {3, 3, 3, 3};
    tris.face_vertices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    for (int l = 0; l <= 3; ++l) {
        EXPECT_EQ(subdivided_triangles(mixed, level(l)),
                  static_cast<double>(subdivide(mixed, level(l), {}).triangle_count()))
            << "level " << l;
        SubdivOptions loop = level(l);
        loop.scheme = SubdivOptions::Scheme::Loop;
        EXPECT_EQ(subdivided_triangles(tris, loop),
                  static_cast<double>(subdivide(tris, loop, {}).triangle_count()))
            << "loop level " << l;
    }
}

/** Sets $SPANGLE_MEMORY_LIMIT for one scope. */
class MemoryLimit {
public:
    explicit MemoryLimit(const char* value) { setenv("SPANGLE_MEMORY_LIMIT", value, 1); }
    ~MemoryLimit() { unsetenv("SPANGLE_MEMORY_LIMIT"); }
    MemoryLimit(const MemoryLimit&) = delete;
    MemoryLimit& operator=(const MemoryLimit&) = delete;
};

std::string render_error(const std::string& scene, uint32_t width = 0) {
    FrameRequest req;
    req.scene = scene;
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.spp_override = 1;
    req.options.width_override = width;
    req.options.height_override = width;
    try {
        render_frame(req);
        return "";
    } catch (const SpangleError& e) {
        return e.what();
    }
}

TEST(Subdivision, LevelsThatWouldNotFitMemoryAreRefusedUpFront) {
    // Two snowman bodies at "auto" levels up to 6; at 2048 pixels the near one is refined to
    // level 6 (1.3 million triangles): about 380 MiB.
    const std::string scene = test::test_dir() + "/scenes/subdiv_near_far.toml";
    {
        const MemoryLimit limit("64M");
        const std::string msg = render_error(scene, 2048);
        EXPECT_NE(msg.find("subdiv_near_far.toml:19:8: error: subdividing"), std::string::npos)
            << msg;
        EXPECT_NE(msg.find("at level 6 would make 1327104 triangles and need about 380 MiB, but "
                           "only 64 MiB of memory is available: lower subdiv.max_level or raise "
                           "subdiv.pixel_budget"),
                  std::string::npos)
            << msg;
    }
    {
        // The film: 8192^2 pixels of exact sums (48 bytes) and the image (12) need 3.8 GiB.
        const MemoryLimit limit("600M");
        const std::string msg = render_error(test::test_dir() + "/scenes/small_lit.toml", 8192);
        EXPECT_NE(msg.find("a 8192x8192 image needs about 3.8 GiB to render (60 bytes per pixel), "
                           "but only 600 MiB of memory is available: lower the resolution"),
                  std::string::npos)
            << msg;
    }
    {
        const MemoryLimit limit("plenty");
        EXPECT_NE(
            render_error(scene).find("SPANGLE_MEMORY_LIMIT='plenty' is not a size such as 8G"),
            std::string::npos);
    }
    EXPECT_EQ(render_error(scene), "") << "renders without a limit";
}

TEST(MemoryLimits, BvhAndEnvironmentMapsAreRefusedUpFront) {
    {
        // Two spheres sharing one mesh of 9024 triangles and a plane: 1.3 MiB of BVH.
        const MemoryLimit limit("1M");
        const std::string msg = render_error(test::test_dir() + "/scenes/delta_hard_cases.toml");
        EXPECT_NE(msg.find("the scene's 9026 triangles need about 1.3 MiB more for the ray-tracing "
                           "structure, but only 1.0 MiB of memory is available"),
                  std::string::npos)
            << msg;
    }
    {
        // A 512x256 environment map: 4 MiB while loading.
        const MemoryLimit limit("3M");
        const std::string msg = render_error(test::asset_dir() + "/scenes/materials.toml");
        EXPECT_NE(msg.find("materials.toml:28:7: error: environment map"), std::string::npos)
            << msg;
        EXPECT_NE(msg.find("(512x256) needs about 4.0 MiB to load, but only 3.0 MiB of memory is "
                           "available: use a smaller map"),
                  std::string::npos)
            << msg;
    }
}

}  // namespace
}  // namespace spangle::test_subdivision
