// The flicker measurement on synthetic frames whose geometry is known: the same sparkles on the
// same surface points persist and do not flicker; sparkles moved to other points do.

#include <gtest/gtest.h>

#include "color/flicker.h"
#include "color/image_output.h"
#include "core/error.h"
#include "core/hash.h"
#include "test_support.h"

namespace spangle {
namespace {

/** A 32 x 32 frame seeing the plane z = 0 straight on (worldToNDC the identity: P = (ndc x,
 *  ndc y, 0)), a dim glint layer with sparkles where hash(seed, pixel) says. */
void write_frame(const std::string& path, uint64_t seed) {
    constexpr int kN = 32;
    const std::vector<std::string> names = {"A",   "Z",        "P.X",      "P.Y",
                                            "P.Z", "glints.R", "glints.G", "glints.B"};
    std::vector<float> layers(kN * kN * names.size(), 0.0f);
    for (int y = 0; y < kN; ++y)
        for (int x = 0; x < kN; ++x) {
            float* v = &layers[static_cast<std::size_t>(y * kN + x) * names.size()];
            v[0] = 1.0f;
            v[1] = 1.0f;
            v[2] = (static_cast<float>(x) + 0.5f) / kN;
            v[3] = (static_cast<float>(y) + 0.5f) / kN;
            const bool sparkle =
                to_unit_float(hash2(seed, static_cast<uint64_t>(y * kN + x))) < 0.05f;
            v[5] = v[6] = v[7] = sparkle ? 5.0f : 0.1f;
        }
    ExrOptions o;
    o.half = false;
    o.layers = &layers;
    o.layer_names = names;
    o.matrices = {{"worldToNDC", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}};
    const ColorConfig color = test::shipped_config();
    write_exr(path, std::vector<float>(kN * kN * 3, 0.1f), kN, kN, color, o);
}

TEST(Flicker, FixedSparklesPersistAndMovedOnesFlicker) {
    test::TempDir dir("flicker");
    write_frame(dir.file("a.exr"), 1);
    write_frame(dir.file("b.exr"), 1);
    write_frame(dir.file("c.exr"), 2);
    const FlickerReport same = measure_flicker({dir.file("a.exr"), dir.file("b.exr")}, 1.0);
    EXPECT_EQ(same.pairs, 1u);
    EXPECT_EQ(same.pixels, 32.0 * 32.0);
    EXPECT_DOUBLE_EQ(same.mask_persistence, 1.0);
    EXPECT_DOUBLE_EQ(same.mask_flicker, 0.0);
    EXPECT_GT(same.mask_fraction, 0.02);
    const FlickerReport moved = measure_flicker({dir.file("b.exr"), dir.file("c.exr")}, 1.0);
    EXPECT_LT(moved.mask_persistence, 0.3) << "independent sparkles coincide about 5% of the time";
    EXPECT_GT(moved.mask_flicker, 0.05);
    try {
        measure_flicker({dir.file("a.exr")});
        FAIL() << "one frame was measured";
    } catch (const SpangleError&) {
    }
}

}  // namespace
}  // namespace spangle
