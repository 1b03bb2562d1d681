// The ray streams (a wave's rays traced in one Embree call) against one ray at a time: the same
// hits, the same occlusion, and the same treatment of non-finite rays.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "accel/embree_scene.h"
#include "core/hash.h"

namespace spangle::test_embree_scene {
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

// A moving instance (motion blur) is where instance_at puts it at the ray's time: Embree and
// shading blend the same steps. Three steps: slide along x from -2 to 0, then lift to y = 1
// while turning 90 degrees about z (a blend of matrices that far apart also shrinks the sphere
// to 0.71 of its size halfway: the loader cuts a turning motion into steps of about 2.5 degrees).
TEST(EmbreeScene, MovingInstancesAreWhereInstanceAtPutsThemAtTheRaysTime) {
    GeometryStore geometry;
    geometry.meshes.push_back(bumpy_sphere());
    Instance inst;
    inst.motion = {Affine::translate({-2, 0, 0}), Affine::translate({0, 0, 0}),
                   Affine::translate({0, 1, 0}).compose(Affine::rotate(90, {0, 0, 1}))};
    inst.to_world = inst.motion[1];
    inst.to_object = inst.to_world.inverse();
    inst.normal_to_world = inst.to_world.normal_matrix();
    Instance still;  // a second instance that stays put, below and behind
    still.to_world = Affine::translate({0, -3, -10});
    still.to_object = still.to_world.inverse();
    still.normal_to_world = still.to_world.normal_matrix();
    EmbreeScene scene;
    scene.build(geometry, {inst, still}, {}, {});

    int checked = 0;
    for (const float time : {0.0f, 0.1f, 0.25f, 0.5f, 0.6f, 0.75f, 0.9f, 1.0f}) {
        const Instance at = instance_at(inst, time);
        // Expected centre: x from -2 to 0 over the first half, y from 0 to 1 over the second.
        const Vec3 centre = at.to_world.apply_point({0, 0, 0});
        EXPECT_NEAR(centre.x, time < 0.5f ? -2.0f + 4.0f * time : 0.0f, 1e-5f) << time;
        EXPECT_NEAR(centre.y, time < 0.5f ? 0.0f : 2.0f * time - 1.0f, 1e-5f) << time;
        // Rays from +z towards the centre and around it: each hit's point, rebuilt from the
        // triangle and instance_at's transform, lies on the ray where Embree found it.
        for (int k = 0; k < 25; ++k) {
            const Vec3 o = centre + Vec3(0.2f * static_cast<float>(k % 5 - 2),
                                         0.2f * static_cast<float>(k / 5 - 2), 5.0f);
            const Vec3 d(0, 0, -1);
            Hit hit;
            ASSERT_TRUE(scene.intersect(o, d, 1e30f, hit, time)) << time << " ray " << k;
            ASSERT_EQ(hit.instance, 0)
                << "the moving sphere is hit, not the one behind it: " << time << " ray " << k;
            const TriangleMesh& m = *geometry.meshes[0];
            const auto vertex = [&](int c) {
                return at.to_world.apply_point(
                    m.position(m.indices[3 * static_cast<std::size_t>(hit.prim) +
                                         static_cast<std::size_t>(c)]));
            };
            const Vec3 p =
                vertex(0) * (1.0f - hit.b1 - hit.b2) + vertex(1) * hit.b1 + vertex(2) * hit.b2;
            EXPECT_LT(length(p - (o + d * hit.t)), 1e-4f) << time << " ray " << k;
            ++checked;
        }
        // A ray through where the sphere is at another time misses it now (it moved away).
        const Vec3 elsewhere = instance_at(inst, time < 0.5f ? 1.0f : 0.0f).to_world.t;
        if (length(elsewhere - centre) > 2.5f) {
            Hit hit;
            const bool found =
                scene.intersect(elsewhere + Vec3(0, 0, 5), {0, 0, -1}, 1e30f, hit, time);
            EXPECT_TRUE(!found || hit.instance != 0) << time;
        }
    }
    EXPECT_EQ(checked, 200);
    // Streams carry each ray's time.
    std::vector<Vec3> o, d;
    std::vector<float> times;
    for (const float time : {0.0f, 1.0f}) {
        o.push_back(instance_at(inst, time).to_world.t + Vec3(0, 0, 5));
        d.emplace_back(0, 0, -1);
        times.push_back(time);
    }
    for (const float time : {1.0f, 0.0f}) {  // the same rays at the other ends: they miss it
        o.push_back(instance_at(inst, 1.0f - time).to_world.t + Vec3(0, 0, 5));
        d.emplace_back(0, 0, -1);
        times.push_back(time);
    }
    std::vector<Hit> hits(4);
    std::vector<uint8_t> found(4);
    scene.intersect_stream(o.data(), d.data(), 4, hits.data(), found.data(), times.data());
    EXPECT_TRUE(found[0] && hits[0].instance == 0);
    EXPECT_TRUE(found[1] && hits[1].instance == 0);
    EXPECT_FALSE(found[2] && hits[2].instance == 0);
    EXPECT_FALSE(found[3] && hits[3].instance == 0);
    std::vector<float> tmax(4, 1e30f);
    std::vector<uint8_t> blocked(4);
    scene.occluded_stream(o.data(), d.data(), tmax.data(), 4, blocked.data(), times.data());
    EXPECT_EQ(blocked, (std::vector<uint8_t>{1, 1, 0, 0}));
}

}  // namespace
}  // namespace spangle::test_embree_scene
