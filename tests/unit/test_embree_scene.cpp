// The ray streams (a wave's rays traced in one Embree call) against one ray at a time: the same
// hits, the same occlusion, and the same treatment of non-finite rays.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "accel/embree_scene.h"
#include "core/hash.h"

namespace spangle {
namespace {

/** A bumpy closed sphere of about 20,000 triangles. */
std::shared_ptr<TriangleMesh> bumpy_sphere() {
    auto m = std::make_shared<TriangleMesh>();
    const uint32_t nu = 160, nv = 64;
    for (uint32_t j = 0; j <= nv; ++j)
        for (uint32_t i = 0; i <= nu; ++i) {
            const float th = kPi * static_cast<float>(j) / nv,
                        ph = 2 * kPi * static_cast<float>(i) / nu;
            const float r = 1.0f + 0.05f * std::sin(7 * ph) * std::sin(5 * th);
            m->positions.insert(m->positions.end(),
                                {r * std::sin(th) * std::cos(ph), r * std::cos(th),
                                 r * std::sin(th) * std::sin(ph)});
        }
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            const uint32_t a = j * (nu + 1) + i, b = a + 1, c = a + nu + 1, d = c + 1;
            m->indices.insert(m->indices.end(), {a, b, d, a, d, c});
        }
    return m;
}

struct Fixture {
    GeometryStore geometry;
    std::vector<Instance> instances;
    EmbreeScene scene;

    Fixture() {
        geometry.meshes.push_back(bumpy_sphere());
        for (int k = 0; k < 3; ++k) {
            Instance inst;
            inst.mesh = 0;
            inst.material = static_cast<uint32_t>(k);
            inst.to_world = Affine::translate(Vec3(2.5f * static_cast<float>(k - 1), 0.0f, 0.0f));
            inst.to_object = inst.to_world.inverse();
            inst.normal_to_world = inst.to_world.normal_matrix();
            instances.push_back(inst);
        }
        const std::vector<Vec3> quad = {{-4, 3, -4}, {4, 3, -4}, {4, 3, 4}, {-4, 3, 4}};
        const std::vector<float> spheres = {0.0f, -3.0f, 0.0f, 0.5f};
        scene.build(geometry, instances, quad, spheres);
    }
};

/** Rays from a box around the scene in random directions; every 97th is non-finite. */
void make_rays(std::vector<Vec3>& o, std::vector<Vec3>& d, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
        const float u[5] = {to_unit_float(hash2(i, 1)), to_unit_float(hash2(i, 2)),
                            to_unit_float(hash2(i, 3)), to_unit_float(hash2(i, 4)),
                            to_unit_float(hash2(i, 5))};
        o.emplace_back(8 * u[0] - 4, 8 * u[1] - 4, 8 * u[2] - 4);
        const float z = 2 * u[3] - 1, r = std::sqrt(std::max(0.0f, 1 - z * z)), ph = 2 * kPi * u[4];
        d.emplace_back(r * std::cos(ph), r * std::sin(ph), z);
        if (i % 97 == 0) o.back().x = std::numeric_limits<float>::quiet_NaN();
        if (i % 97 == 50) d.back().y = std::numeric_limits<float>::infinity();
    }
}

// A stream finds the hits single rays find, and each of its hits is the same bit for bit
// whatever else is in the stream: crop windows, progressive passes and MPI bands trace the same
// ray in streams of other sizes, and their images must be the whole render's (Embree's coherent
// packets were not: one beetle pixel in 230,400 differed between a one-pass and a progressive
// render).
TEST(EmbreeScene, StreamsFindTheSameHitsAsSingleRaysBitForBit) {
    Fixture f;
    std::vector<Vec3> o, d;
    const std::size_t n = 5000;
    make_rays(o, d, n);
    std::vector<Hit> hits(n);
    std::vector<uint8_t> found(n, 7);
    f.scene.intersect_stream(o.data(), d.data(), n, hits.data(), found.data());
    // The same rays again in streams of 1, 3, 8 and 61 rays.
    std::vector<Hit> parts(n);
    std::vector<uint8_t> parts_found(n, 7);
    for (std::size_t at = 0, size = 1; at < n; size = size == 61 ? 1 : size * 3 - size / 2) {
        const std::size_t count = std::min(size, n - at);
        f.scene.intersect_stream(o.data() + at, d.data() + at, count, parts.data() + at,
                                 parts_found.data() + at);
        at += count;
    }
    std::size_t hit_count = 0, kinds[3] = {0, 0, 0};
    for (std::size_t i = 0; i < n; ++i) {
        Hit one;
        const bool single = f.scene.intersect(o[i], d[i], 1e30f, one);
        ASSERT_EQ(found[i] != 0, single) << "ray " << i;
        ASSERT_EQ(parts_found[i] != 0, single) << "ray " << i;
        if (i % 97 == 0 || i % 97 == 50) {
            EXPECT_FALSE(single) << "a non-finite ray misses";
        }
        if (!single) continue;
        ++hit_count;
        ++kinds[static_cast<int>(one.kind)];
        EXPECT_EQ(hits[i].kind, one.kind) << "ray " << i;
        EXPECT_EQ(hits[i].instance, one.instance) << "ray " << i;
        EXPECT_EQ(hits[i].prim, one.prim) << "ray " << i;
        EXPECT_NEAR(hits[i].t, one.t, 1e-5f * std::max(1.0f, one.t)) << "ray " << i;
        EXPECT_NEAR(hits[i].b1, one.b1, 1e-4f) << "ray " << i;
        EXPECT_NEAR(hits[i].b2, one.b2, 1e-4f) << "ray " << i;
        // The stream's own hits in streams of other sizes: identical.
        EXPECT_EQ(parts[i].kind, hits[i].kind) << "ray " << i;
        EXPECT_EQ(parts[i].instance, hits[i].instance) << "ray " << i;
        EXPECT_EQ(parts[i].prim, hits[i].prim) << "ray " << i;
        EXPECT_EQ(parts[i].t, hits[i].t) << "ray " << i;
        EXPECT_EQ(parts[i].b1, hits[i].b1) << "ray " << i;
        EXPECT_EQ(parts[i].b2, hits[i].b2) << "ray " << i;
    }
    // The comparison covers many hits (about a quarter of these rays hit something) on all
    // three kinds of geometry: instanced meshes, quad lights, sphere lights.
    EXPECT_GT(hit_count, n / 5);
    for (const std::size_t k : kinds) EXPECT_GT(k, 10u);
}

TEST(EmbreeScene, ShadowStreamsAgreeWithSingleRays) {
    Fixture f;
    std::vector<Vec3> o, d;
    const std::size_t n = 5000;
    make_rays(o, d, n);
    std::vector<float> tmax(n);
    for (std::size_t i = 0; i < n; ++i) tmax[i] = 0.5f + 6.0f * to_unit_float(hash2(i, 9));
    tmax[3] = std::numeric_limits<float>::quiet_NaN();
    std::vector<uint8_t> blocked(n, 7);
    f.scene.occluded_stream(o.data(), d.data(), tmax.data(), n, blocked.data());
    std::size_t count = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const bool single = f.scene.occluded(o[i], d[i], tmax[i]);
        ASSERT_EQ(blocked[i] != 0, single) << "ray " << i;
        count += single;
    }
    EXPECT_TRUE(blocked[0]) << "a non-finite ray lets no light through";
    EXPECT_TRUE(blocked[3]) << "so does a NaN distance";
    EXPECT_GT(count, n / 10);
    EXPECT_LT(count, n - n / 10);
}

}  // namespace
}  // namespace spangle
