// Shading normals that would reflect the viewer into the surface (interpolated normals at a
// coarse mesh's silhouette, strong normal maps) are bent back: the rule itself, and the black rim
// it removes from a coarse smooth-shaded sphere in a furnace.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <fstream>
#include <random>
#include <string>

#include <fmt/format.h>

#include "pipeline/frame.h"
#include "render/surface.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_shading_normals {
namespace {

Vec3 random_unit(std::mt19937& rng) {
    std::normal_distribution<float> g;
    for (;;) {
        const Vec3 v(g(rng), g(rng), g(rng));
        const float len = length(v);
        if (len > 1e-3f) return v / len;
    }
}

bool same(Vec3 a, Vec3 b) {
    return a.x == b.x && a.y == b.y && a.z == b.z;
}

TEST(ShadingNormals, ReflectionsAreKeptAboveTheSurfaceAndValidNormalsAreLeftAlone) {
    std::mt19937 rng(20261205);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    int bent = 0, kept = 0;
    for (int i = 0; i < 20000; ++i) {
        SurfacePoint sp;
        sp.ng = random_unit(rng);
        // Shading normals anywhere on ng's side, viewers anywhere above the geometric plane
        // (down to grazing).
        Vec3 n = random_unit(rng);
        if (dot(n, sp.ng) < 0.0f) n = -n;
        Vec3 wo = random_unit(rng);
        if (dot(wo, sp.ng) < 0.0f) wo = -wo;
        if (i % 4 == 0) wo = normalize(wo - sp.ng * (dot(wo, sp.ng) * (1.0f - 1e-3f * u01(rng))));
        sp.n = n;
        shading_frame(sp.n, random_unit(rng), sp.s, sp.t);
        const SurfacePoint before = sp;
        const float cos_g = dot(wo, sp.ng);
        if (!(cos_g > 0.0f)) {
            EXPECT_FALSE(keep_reflection_above(sp, wo)) << i << ": nothing to keep";
            continue;
        }
        const float limit = std::min(0.9f * cos_g, 0.01f);
        const float r_before = 2.0f * dot(wo, n) * dot(n, sp.ng) - cos_g;
        const bool did = keep_reflection_above(sp, wo);
        if (!did) {
            ++kept;
            // Left alone only where the reflection was already high enough (up to the
            // rounding of the two ways of computing it), and then bit for bit.
            EXPECT_GE(r_before, limit - 1e-5f) << i;
            EXPECT_TRUE(same(sp.n, before.n) && same(sp.s, before.s) && same(sp.t, before.t)) << i;
            continue;
        }
        ++bent;
        EXPECT_LT(r_before, limit + 1e-5f) << i;
        EXPECT_NEAR(length(sp.n), 1.0f, 1e-5f) << i;
        const Vec3 r = sp.n * (2.0f * dot(wo, sp.n)) - wo;
        EXPECT_NEAR(dot(r, sp.ng), limit, 1e-5f) << i << ": reflection lifted to the limit";
        EXPECT_GT(dot(wo, sp.n), 0.0f) << i << ": the viewer is above the new normal";
        EXPECT_GT(dot(sp.n, sp.ng), 0.0f) << i;
        // An orthonormal right-handed frame around the new normal.
        EXPECT_NEAR(dot(sp.s, sp.n), 0.0f, 1e-5f) << i;
        EXPECT_NEAR(dot(sp.t, sp.n), 0.0f, 1e-5f) << i;
        EXPECT_NEAR(length(sp.s), 1.0f, 1e-5f) << i;
        EXPECT_NEAR(length(cross(sp.n, sp.s) - sp.t), 0.0f, 1e-5f) << i;
        // Bent no further than it must: within the plane of the old reflection and ng, the new
        // reflection is the old one lifted (their horizontal parts point the same way).
        const Vec3 ra = r - sp.ng * dot(r, sp.ng);
        const Vec3 rb = (n * (2.0f * dot(wo, n)) - wo);
        const Vec3 rb_along = rb - sp.ng * dot(rb, sp.ng);
        if (length(rb_along) > 1e-3f) {
            EXPECT_GT(dot(normalize(ra), normalize(rb_along)), 0.999f) << i;
        }
    }
    // Both branches are exercised by the random cases.
    EXPECT_GT(bent, 1000);
    EXPECT_GT(kept, 1000);
}

TEST(ShadingNormals, TheGeometricNormalIsNeverBent) {
    std::mt19937 rng(7);
    for (int i = 0; i < 2000; ++i) {
        SurfacePoint sp;
        sp.ng = random_unit(rng);
        sp.n = sp.ng;
        shading_frame(sp.n, random_unit(rng), sp.s, sp.t);
        Vec3 wo = random_unit(rng);
        if (dot(wo, sp.ng) < 0.0f) wo = -wo;
        EXPECT_FALSE(keep_reflection_above(sp, wo)) << i;
    }
}

/** A UV sphere of kU x kV quads with its vertices' normals (smooth shaded; 8 x 5 is coarse). */
std::string sphere_obj(int kU = 8, int kV = 5) {
    std::string obj;
    for (int j = 0; j <= kV; ++j)
        for (int i = 0; i < kU; ++i) {
            const double th = M_PI * j / kV, ph = 2.0 * M_PI * i / kU;
            const double x = std::sin(th) * std::cos(ph), y = std::cos(th),
                         z = std::sin(th) * std::sin(ph);
            obj += fmt::format("v {} {} {}\nvn {} {} {}\n", x, y, z, x, y, z);
        }
    const auto id = [&](int i, int j) { return j * kU + (i % kU) + 1; };
    for (int j = 0; j < kV; ++j)
        for (int i = 0; i < kU; ++i) {
            const int a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
            obj += fmt::format("f {0}//{0} {1}//{1} {2}//{2}\nf {0}//{0} {3}//{3} {1}//{1}\n", a, c,
                               b, d);
        }
    return obj;
}

TEST(ShadingNormals, ACoarseSmoothSphereInAFurnaceHasNoBlackRim) {
    // White diffuse in a white furnace: every pixel of the sphere is close to 1 (interpolated
    // normals gain or lose a little). Where the interpolated normal turned away from the viewer
    // at the silhouette, the diffuse model reflected nothing: a black rim of pixels near 0.
    test::TempDir dir("coarse_sphere");
    { std::ofstream(dir.file("coarse.obj")) << sphere_obj(); }
    FrameRequest req = test::text_request(dir, "furnace.toml", R"(
[render]
width = 96
height = 96
spp = 64
max_depth = 32
filter = "box"
[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]
fov = 35
[environment]
color = [1, 1, 1]
[[material]]
name = "white"
plugin = "smooth"
model = "diffuse"
params = { albedo = 1.0 }
[[object]]
mesh = "coarse.obj"
material = "white"
)");
    const FrameResult r = render_frame(req);
    ASSERT_EQ(r.width, 96u);
    float lowest = 1e9f;
    double sum = 0.0;
    for (std::size_t i = 0; i < r.image.size(); ++i) {
        lowest = std::min(lowest, r.image[i]);
        sum += r.image[i];
    }
    EXPECT_EQ(r.stats.nonfinite, 0u);
    EXPECT_GT(lowest, 0.6f) << "a pixel of the sphere went dark";
    EXPECT_NEAR(sum / static_cast<double>(r.image.size()), 1.0, 0.03);
}

TEST(ShadingNormals, ACoarseSmoothSphereIsLitWhereItsNormalsFaceTheSun) {
    // A coarse smooth-shaded white sphere lit by a sun from behind on the left, in the dark:
    // each pixel should be what its shading normal says, albedo / pi E max(0, N.L), as the
    // sphere is convex and nothing else can shadow it. Where the interpolated normal faces the
    // sun but the flat triangle does not, the shadow ray from the triangle ran into its
    // neighbours and cut the light off along the triangles' edges (a jagged terminator).
    // Started from the point lifted onto the smooth surface, it escapes.
    test::TempDir dir("sunlit_sphere");
    { std::ofstream(dir.file("coarse.obj")) << sphere_obj(); }
    FrameRequest req = test::text_request(dir, "sun.toml", R"(
[render]
width = 96
height = 96
spp = 16
max_depth = 1
filter = "box"
[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]
fov = 35
[[light]]
type = "distant"
direction = [-1, -0.3, -0.4]
intensity = 3
[[material]]
name = "white"
plugin = "smooth"
model = "diffuse"
params = { albedo = 0.8 }
[[object]]
mesh = "coarse.obj"
material = "white"
)");
    req.options.layers = true;
    const FrameResult r = render_frame(req);
    const auto ch = [&](const std::string& name) {
        const auto it = std::find(r.layer_names.begin(), r.layer_names.end(), name);
        EXPECT_NE(it, r.layer_names.end()) << name;
        return static_cast<std::size_t>(it - r.layer_names.begin());
    };
    const std::size_t lc = r.layer_names.size(), nx = ch("N.X"), alpha = ch("A");
    ASSERT_EQ(r.layers.size(), lc * 96 * 96);
    const float len = std::sqrt(1.0f + 0.09f + 0.16f);
    const Vec3 to_sun(-1.0f / len, -0.3f / len, -0.4f / len);
    const float k = 0.8f * 3.0f / static_cast<float>(M_PI);
    double diff = 0.0, lit = 0.0;
    int dark = 0, n = 0;
    for (std::size_t p = 0; p < 96 * 96; ++p) {
        const float* l = &r.layers[p * lc];
        if (l[alpha] < 1.0f) continue;  // the outline's pixels
        const float expected = k * std::max(0.0f, dot(Vec3(l[nx], l[nx + 1], l[nx + 2]), to_sun));
        if (!(expected > 0.05f)) continue;
        ++n;
        diff += std::fabs(r.image[3 * p] - expected);
        lit += expected;
        dark += r.image[3 * p] < 0.25f * expected ? 1 : 0;
    }
    ASSERT_GT(n, 300) << "the lit side is in view";
    EXPECT_LT(diff / lit, 0.015) << n << " pixels whose normal faces the sun";
    EXPECT_LT(dark, n / 100) << n << " pixels whose normal faces the sun";
}

}  // namespace
}  // namespace spangle::test_shading_normals
