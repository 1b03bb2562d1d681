#include <gtest/gtest.h>

#include <set>

#include "core/hash.h"
#include "core/math.h"
#include "render/arena.h"
#include "render/distribution.h"

namespace spangle::test_math {
namespace {

TEST(Hash, IsAPureFunctionAndSpreadsBits) {
    EXPECT_EQ(hash4(1, 2, 3, 4), hash4(1, 2, 3, 4));
    EXPECT_NE(hash4(1, 2, 3, 4), hash4(1, 2, 4, 3)) << "argument order matters";
    // Neighbouring counters must give unrelated numbers: the mean of many should be near 1/2.
    double sum = 0.0;
    constexpr int kN = 100000;
    for (int i = 0; i < kN; ++i)
        sum += static_cast<double>(sample_1d(9, static_cast<uint64_t>(i), 0, 0));
    // Standard error of the mean of U(0,1) is sqrt(1/12/N) ~ 0.0009; allow 5 sigma.
    EXPECT_NEAR(sum / kN, 0.5, 5 * 0.0009);
}

TEST(Hash, UnitFloatNeverReachesOne) {
    EXPECT_LT(to_unit_float(~0ull), 1.0f);
    EXPECT_EQ(to_unit_float(0), 0.0f);
}

TEST(Affine, InverseAndNormalTransform) {
    const Affine m = Affine::translate({1, 2, 3})
                         .compose(Affine::rotate(30, {0, 1, 0}))
                         .compose(Affine::scale({2, 1, 0.5f}));
    const Affine inv = m.inverse();
    const Vec3 p(0.3f, -1.0f, 2.0f);
    const Vec3 q = inv.apply_point(m.apply_point(p));
    EXPECT_NEAR(q.x, p.x, 1e-5f);
    EXPECT_NEAR(q.y, p.y, 1e-5f);
    EXPECT_NEAR(q.z, p.z, 1e-5f);
    // A normal stays perpendicular to a transformed tangent.
    const Vec3 n(0, 0, 1), t(1, 0, 0);
    EXPECT_NEAR(dot(m.apply_normal(n), m.apply_vector(t)), 0.0f, 1e-5f);
}

TEST(Distribution1D, PicksInProportionAndNeverZeroWeights) {
    const Distribution1D d({1.0, 0.0, 3.0});
    EXPECT_FLOAT_EQ(d.pmf(0), 0.25f);
    EXPECT_FLOAT_EQ(d.pmf(1), 0.0f);
    int counts[3] = {0, 0, 0};
    for (int i = 0; i < 1000; ++i) ++counts[d.sample((static_cast<float>(i) + 0.5f) / 1000.0f)];
    EXPECT_EQ(counts[1], 0);
    EXPECT_EQ(counts[0], 250);
    EXPECT_EQ(counts[2], 750);
    EXPECT_LT(d.sample(0.0f), 3u);
    EXPECT_LT(d.sample(0.99999994f), 3u);
    EXPECT_TRUE(Distribution1D({0.0, 0.0}).empty());
}

TEST(ScratchArena, AlignsAndReuses) {
    ScratchArena a;
    auto* p = static_cast<char*>(a.allocate(10, 64));
    ASSERT_NE(p, nullptr);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(p) % 64, 0u);
    void* big = a.allocate(3u << 20, 16);  // larger than a block
    ASSERT_NE(big, nullptr);
    EXPECT_EQ(a.allocate(8, 3), nullptr) << "alignment must be a power of two";
    a.reset();
    EXPECT_EQ(a.allocate(10, 64), p) << "reset reuses the first block";
}

}  // namespace
}  // namespace spangle::test_math
