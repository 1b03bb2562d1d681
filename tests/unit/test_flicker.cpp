// The flicker measurement on synthetic frames whose geometry is known: the same sparkles on the
// same surface points persist and do not flicker; sparkles moved to other points do.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <utility>
#include <vector>

#include "color/flicker.h"
#include "color/image_output.h"
#include "core/error.h"
#include "core/hash.h"
#include "test_support.h"

namespace spangle::test_flicker {
namespace {

/** A 32 x 32 frame seeing the plane z = 0 straight on (worldToNDC the identity: P = (ndc x,
 *  ndc y, 0)), a dim glint layer with sparkles where hash(seed, point) says. The plane is an
 *  object moved `shift` pixels to the right of its own space (shift / 32 in x): a sparkle stays
 *  on its object-space point. `objects`: write the Pobj and object layers and the placements. */
void write_frame(const std::string& path, uint64_t seed, int shift = 0, bool objects = false,
                 const std::string& scene = "", const std::string& time = "",
                 float sparkle_value = 5.0f) {
    constexpr int kN = 32;
    std::vector<std::string> names = {"A",   "Z",        "P.X",      "P.Y",
                                      "P.Z", "glints.R", "glints.G", "glints.B"};
    if (objects) names.insert(names.end(), {"Pobj.X", "Pobj.Y", "Pobj.Z", "object"});
    std::vector<float> layers(kN * kN * names.size(), 0.0f);
    for (int y = 0; y < kN; ++y)
        for (int x = 0; x < kN; ++x) {
            float* v = &layers[static_cast<std::size_t>(y * kN + x) * names.size()];
            v[0] = 1.0f;
            v[1] = 1.0f;
            v[2] = (static_cast<float>(x) + 0.5f) / kN;
            v[3] = (static_cast<float>(y) + 0.5f) / kN;
            const int ox = x - shift;  // the object-space column
            const bool sparkle =
                to_unit_float(hash2(seed, static_cast<uint64_t>(y * kN + ox + kN))) < 0.05f;
            v[5] = v[6] = v[7] = sparkle ? sparkle_value : 0.1f;
            if (objects) {
                v[8] = (static_cast<float>(ox) + 0.5f) / kN;
                v[9] = v[3];
                v[11] = 1.0f;
            }
        }
    ExrOptions o;
    o.half = false;
    o.layers = &layers;
    o.layer_names = names;
    o.matrices = {{"worldToNDC", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}};
    if (objects)
        o.float_vectors = {{"spangle:objectToWorld",
                            {1, 0, 0, static_cast<float>(shift) / kN, 0, 1, 0, 0, 0, 0, 1, 0}}};
    if (!scene.empty()) o.metadata = {{"spangle:scene", scene}, {"spangle:time", time}};
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
    // Frames of other scenes, and one moment twice, are refused (they were measured as a
    // sequence); frames of one scene written from another folder are one scene.
    write_frame(dir.file("s1.exr"), 1, 0, false, "shots/bend.toml", "0");
    write_frame(dir.file("s2.exr"), 1, 0, false, "/farm/shots/bend.toml", "0.0416667");
    write_frame(dir.file("t2.exr"), 1, 0, false, "turn.toml", "0.0416667");
    EXPECT_EQ(measure_flicker({dir.file("s1.exr"), dir.file("s2.exr")}, 1.0).pairs, 1u);
    const auto refused = [&](std::vector<std::string> frames, const char* why) {
        try {
            measure_flicker(frames, 1.0);
            ADD_FAILURE() << "measured: " << why;
        } catch (const SpangleError& e) {
            EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
        }
    };
    refused({dir.file("s1.exr"), dir.file("t2.exr")}, "frames of one sequence are of one scene");
    refused({dir.file("s1.exr"), dir.file("s2.exr"), dir.file("s1.exr")}, "the same moment");
    // Frames given out of time order (a shell's glob of frames -3..0 gives -001 -002 -003 0000)
    // are measured in the order of their times, and the report says so.
    write_frame(dir.file("o1.exr"), 1, 0, false, "turn.toml", "-0.125");
    write_frame(dir.file("o2.exr"), 1, 0, false, "turn.toml", "-0.0833333");
    write_frame(dir.file("o3.exr"), 2, 0, false, "turn.toml", "-0.0416667");
    const FlickerReport in_order =
        measure_flicker({dir.file("o1.exr"), dir.file("o2.exr"), dir.file("o3.exr")}, 1.0);
    const FlickerReport shuffled =
        measure_flicker({dir.file("o3.exr"), dir.file("o1.exr"), dir.file("o2.exr")}, 1.0);
    EXPECT_FALSE(in_order.reordered);
    EXPECT_TRUE(shuffled.reordered);
    EXPECT_EQ(shuffled.mask_persistence, in_order.mask_persistence);
    EXPECT_EQ(shuffled.mask_flicker, in_order.mask_flicker);
    EXPECT_EQ(in_order.blurred, 0u);
}

TEST(Flicker, GlintsStoredAsInfinityAndAMissingFrameAreSaid) {
    // Glints brighter than a half float holds were stored as infinity: every figure left them
    // out without a word (persistence read 0). The report counts them (the command warns).
    test::TempDir dir("flicker_said");
    const float inf = std::numeric_limits<float>::infinity();
    write_frame(dir.file("h1.exr"), 1, 0, false, "turn.toml", "0", inf);
    write_frame(dir.file("h2.exr"), 1, 0, false, "turn.toml", "0.0416667", inf);
    write_frame(dir.file("f1.exr"), 1, 0, false, "turn.toml", "0");
    write_frame(dir.file("f2.exr"), 1, 0, false, "turn.toml", "0.0416667");
    write_frame(dir.file("f3.exr"), 1, 0, false, "turn.toml", "0.0833333");
    write_frame(dir.file("f5.exr"), 1, 0, false, "turn.toml", "0.166667");
    const FlickerReport hot = measure_flicker({dir.file("h1.exr"), dir.file("h2.exr")}, 1.0);
    EXPECT_GT(hot.nonfinite_glints, 2u * 20u);  // 5% of 1024 pixels per frame are sparkles
    EXPECT_EQ(measure_flicker({dir.file("f1.exr"), dir.file("f2.exr")}, 1.0).nonfinite_glints, 0u);
    // Frames 1, 2, 3 step evenly; 1, 2, 3, 5 miss frame 4: the steps say so.
    const FlickerReport even =
        measure_flicker({dir.file("f1.exr"), dir.file("f2.exr"), dir.file("f3.exr")}, 1.0);
    EXPECT_LE(even.step_max, 1.01 * even.step_min);
    EXPECT_GT(even.step_min, 0.04);
    const FlickerReport gap = measure_flicker(
        {dir.file("f1.exr"), dir.file("f2.exr"), dir.file("f3.exr"), dir.file("f5.exr")}, 1.0);
    EXPECT_NEAR(gap.step_min, 0.0416667, 1e-5);
    EXPECT_NEAR(gap.step_max, 0.0833333, 1e-5);
}

TEST(Flicker, FramesRenderedWithMotionBlurAreCounted) {
    // A blurred frame's glints are streaks: its spangle:shutter header (written when the motion
    // was blurred) is counted, and the command says what the figures are then worth (blurred
    // frames measured persistence 0 without a word).
    test::TempDir dir("flicker_blurred");
    const auto write = [&](const std::string& name, uint64_t seed, const char* time, bool blurred) {
        constexpr int kN = 8;
        const std::vector<std::string> names = {"A",   "Z",        "P.X",      "P.Y",
                                                "P.Z", "glints.R", "glints.G", "glints.B"};
        std::vector<float> layers(kN * kN * names.size(), 0.0f);
        for (int i = 0; i < kN * kN; ++i) {
            float* v = &layers[static_cast<std::size_t>(i) * names.size()];
            v[0] = v[1] = 1.0f;
            v[2] = (static_cast<float>(i % kN) + 0.5f) / kN;
            v[3] = (static_cast<float>(i / kN) + 0.5f) / kN;
            v[5] = v[6] = v[7] =
                to_unit_float(hash2(seed, static_cast<uint64_t>(i))) < 0.1f ? 5.0f : 0.1f;
        }
        ExrOptions o;
        o.half = false;
        o.layers = &layers;
        o.layer_names = names;
        o.matrices = {{"worldToNDC", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}};
        o.metadata = {{"spangle:scene", "spin.toml"}, {"spangle:time", time}};
        if (blurred) o.metadata.push_back({"spangle:shutter", "0 1"});
        write_exr(dir.file(name), std::vector<float>(kN * kN * 3, 0.1f), kN, kN,
                  test::shipped_config(), o);
    };
    write("a.exr", 1, "0", true);
    write("b.exr", 1, "0.0416667", true);
    write("c.exr", 1, "0.0833333", false);
    EXPECT_EQ(
        measure_flicker({dir.file("a.exr"), dir.file("b.exr"), dir.file("c.exr")}, 1.0).blurred,
        2u);
}

// A turning (here: sliding) object: its sparkles stay on its points, which the frames' object
// layers and placements follow; the world positions alone (frames without them) lose them.
TEST(Flicker, SparklesOnAMovingObjectAreFollowedByTheirObject) {
    test::TempDir dir("flicker_objects");
    write_frame(dir.file("a.exr"), 1, 0, true);
    write_frame(dir.file("b.exr"), 1, 8, true);
    write_frame(dir.file("c.exr"), 2, 8, true);
    write_frame(dir.file("a_world.exr"), 1, 0, false);
    write_frame(dir.file("b_world.exr"), 1, 8, false);
    const FlickerReport followed = measure_flicker({dir.file("a.exr"), dir.file("b.exr")}, 1.0);
    EXPECT_TRUE(followed.by_objects);
    EXPECT_EQ(followed.pixels, 24.0 * 32.0) << "the columns that stay in the frame";
    EXPECT_DOUBLE_EQ(followed.mask_persistence, 1.0);
    EXPECT_DOUBLE_EQ(followed.mask_flicker, 0.0);
    const FlickerReport reseeded = measure_flicker({dir.file("a.exr"), dir.file("c.exr")}, 1.0);
    EXPECT_LT(reseeded.mask_persistence, 0.3);
    const FlickerReport world =
        measure_flicker({dir.file("a_world.exr"), dir.file("b_world.exr")}, 1.0);
    EXPECT_FALSE(world.by_objects);
    EXPECT_LT(world.mask_persistence, 0.3) << "world positions do not follow the object";
}

/** A 32 x 32 frame seeing the plane z = 0 straight on, as write_frame, where a deforming object
 *  is stretched `stretch` times along x about x = 0: pixel x shows the rest point x_w / stretch
 *  (Pobj), and sparkles sit on the rest cells (32 across the rest width) that hash(seed, cell)
 *  picks. `rest_pose`: the header says the object deforms (spangle:restPose). */
void write_stretched_frame(const std::string& path, uint64_t seed, float stretch, bool rest_pose) {
    constexpr int kN = 32;
    const std::vector<std::string> names = {"A",      "Z",        "P.X",      "P.Y",
                                            "P.Z",    "glints.R", "glints.G", "glints.B",
                                            "Pobj.X", "Pobj.Y",   "Pobj.Z",   "object"};
    std::vector<float> layers(kN * kN * names.size(), 0.0f);
    for (int y = 0; y < kN; ++y)
        for (int x = 0; x < kN; ++x) {
            float* v = &layers[static_cast<std::size_t>(y * kN + x) * names.size()];
            v[0] = v[1] = 1.0f;
            v[2] = (static_cast<float>(x) + 0.5f) / kN;
            v[3] = (static_cast<float>(y) + 0.5f) / kN;
            v[8] = v[2] / stretch;
            v[9] = v[3];
            v[11] = 1.0f;
            const auto cell = static_cast<int>(std::floor(v[8] * kN));
            const bool sparkle =
                to_unit_float(hash2(seed, static_cast<uint64_t>(y * kN + cell))) < 0.05f;
            v[5] = v[6] = v[7] = sparkle ? 5.0f : 0.1f;
        }
    ExrOptions o;
    o.half = false;
    o.layers = &layers;
    o.layer_names = names;
    o.matrices = {{"worldToNDC", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}};
    o.float_vectors = {{"spangle:objectToWorld", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}}};
    if (rest_pose) o.float_vectors.push_back({"spangle:restPose", {1.0f}});
    const ColorConfig color = test::shipped_config();
    write_exr(path, std::vector<float>(kN * kN * 3, 0.1f), kN, kN, color, o);
}

// A deforming object (here: one stretched by a quarter): its points slide over its own space, so
// its placement cannot carry them; with a rest pose the frames' Pobj is the rest position, and a
// point is found in the next frame where the same rest position is. Rest points the next frame
// does not show (the stretch pushed them out of the image) are not compared.
TEST(Flicker, SparklesOnADeformingObjectAreFoundByTheirRestPosition) {
    test::TempDir dir("flicker_deforming");
    write_stretched_frame(dir.file("a.exr"), 1, 1.0f, true);
    write_stretched_frame(dir.file("b.exr"), 1, 1.25f, true);
    write_stretched_frame(dir.file("c.exr"), 2, 1.25f, true);
    write_stretched_frame(dir.file("a_rigid.exr"), 1, 1.0f, false);
    write_stretched_frame(dir.file("b_rigid.exr"), 1, 1.25f, false);
    const FlickerReport found = measure_flicker({dir.file("a.exr"), dir.file("b.exr")}, 1.0);
    // The rest width the stretched frame shows, 0.8 of it, is 25.6 of frame a's 32 columns.
    EXPECT_GE(found.pixels, 25.0 * 32.0);
    EXPECT_LE(found.pixels, 27.0 * 32.0);
    EXPECT_DOUBLE_EQ(found.mask_persistence, 1.0);
    EXPECT_TRUE(found.by_objects && found.by_rest) << "said as carried by their rest position";
    const FlickerReport reseeded = measure_flicker({dir.file("a.exr"), dir.file("c.exr")}, 1.0);
    EXPECT_LT(reseeded.mask_persistence, 0.3);
    // Carried as a rigid object (no rest pose said), the points land where they were, on other
    // rest cells.
    const FlickerReport rigid =
        measure_flicker({dir.file("a_rigid.exr"), dir.file("b_rigid.exr")}, 1.0);
    EXPECT_EQ(rigid.pixels, 32.0 * 32.0);
    EXPECT_FALSE(rigid.by_rest);
    EXPECT_LT(rigid.mask_persistence, 0.5);
}

/** A width x height luminance image of `base` with `value` at the given pixels. */
std::vector<float> image_with(int width, int height, float base,
                              std::initializer_list<std::pair<int, int>> at, float value) {
    std::vector<float> img(static_cast<std::size_t>(width * height), base);
    for (const auto& [x, y] : at) img[static_cast<std::size_t>(y * width + x)] = value;
    return img;
}

TEST(GlintDetector, FindsSparklesNotBroadHighlights) {
    constexpr int kW = 24, kH = 16;
    std::vector<float> glint = image_with(kW, kH, 0.1f, {{3, 3}, {20, 12}}, 4.0f);
    // A broad highlight: a 5x5 block, bright but no brighter than its own neighbourhood x 3.
    for (int y = 6; y < 11; ++y)
        for (int x = 10; x < 15; ++x) glint[static_cast<std::size_t>(y * kW + x)] = 4.0f;
    GlintMean mean;
    mean.add(glint, std::vector<float>(glint.size(), 1.0f));
    const double threshold = mean.threshold();
    EXPECT_NEAR(threshold, 4.0 * (0.1 * (kW * kH - 27) + 4.0 * 27) / (kW * kH), 1e-6);
    const std::vector<uint8_t> m = glint_pixels(glint, kW, kH, threshold);
    std::vector<std::size_t> found;
    for (std::size_t i = 0; i < m.size(); ++i)
        if (m[i]) found.push_back(i);
    EXPECT_EQ(found, (std::vector<std::size_t>{3 * kW + 3, 12 * kW + 20}));
    // Uncovered pixels do not set the threshold; a higher threshold than the sparkles, none.
    std::vector<float> alpha(glint.size(), 1.0f);
    alpha[3 * kW + 3] = 0.5f;
    GlintMean covered;
    covered.add(glint, alpha);
    EXPECT_EQ(covered.count, static_cast<double>(kW * kH - 1));
    const std::vector<uint8_t> none = glint_pixels(glint, kW, kH, 5.0);
    EXPECT_EQ(std::count(none.begin(), none.end(), uint8_t{1}), 0);
}

TEST(GlintDetector, CountsTheGlintsAnImageKeeps) {
    constexpr int kW = 16, kH = 12;
    // Reference: glints at (4, 4), (10, 6), (12, 9) and on the border at (0, 5); a faint one at
    // (7, 2) that stands out of its neighbours by less than a tenth of itself.
    std::vector<float> ref = image_with(kW, kH, 0.2f, {{4, 4}, {10, 6}, {12, 9}, {0, 5}}, 2.0f);
    for (int y = 1; y <= 3; ++y)
        for (int x = 6; x <= 8; ++x) ref[static_cast<std::size_t>(y * kW + x)] = 1.0f;
    ref[2 * kW + 7] = 1.05f;
    std::vector<uint8_t> glints(ref.size(), 0);
    for (const auto& [x, y] : {std::pair{4, 4}, {10, 6}, {12, 9}, {0, 5}, {7, 2}})
        glints[static_cast<std::size_t>(y * kW + x)] = 1;
    const GlintsKept same = glints_kept(ref, ref, glints, kW, kH);
    EXPECT_EQ(same.found, 5u);
    EXPECT_EQ(same.border, 1u);
    EXPECT_EQ(same.faint, 1u);
    EXPECT_EQ(same.measured, 3u);
    EXPECT_EQ(same.kept, 3u);
    EXPECT_DOUBLE_EQ(same.median_ratio, 1.0);
    // The image: (4, 4) at 60% of its contrast (kept), (10, 6) flattened into its neighbours at
    // 40% (lost), (12, 9) not a number (lost).
    std::vector<float> img = ref;
    img[4 * kW + 4] = 0.2f + 0.6f * 1.8f;
    img[6 * kW + 10] = 0.2f + 0.4f * 1.8f;
    img[9 * kW + 12] = std::numeric_limits<float>::quiet_NaN();
    const GlintsKept k = glints_kept(img, ref, glints, kW, kH);
    EXPECT_EQ(k.measured, 3u);
    EXPECT_EQ(k.kept, 1u);
    EXPECT_NEAR(k.median_ratio, 0.4, 1e-5);
    // A brighter glint over brighter neighbours keeps its contrast: kept.
    std::vector<float> lifted = ref;
    for (float& v : lifted) v += 0.5f;
    EXPECT_EQ(glints_kept(lifted, ref, glints, kW, kH).kept, 3u);
    // An even count: the median is the mean of the middle two (0.4 and 0.6 of 0, 0.4, 0.6, 1).
    std::vector<uint8_t> four = glints;
    four[1 * kW + 2] = 1;
    std::vector<float> ref4 = ref, img4 = img;
    ref4[1 * kW + 2] = img4[1 * kW + 2] = 2.0f;
    const GlintsKept k4 = glints_kept(img4, ref4, four, kW, kH);
    EXPECT_EQ(k4.measured, 4u);
    EXPECT_EQ(k4.kept, 2u);
    EXPECT_NEAR(k4.median_ratio, 0.5, 1e-5);
    // Vectors of another size than the image's are refused.
    EXPECT_THROW(glints_kept(img, ref, glints, kW, kH - 1), SpangleError);
}

TEST(GlintDetector, TheThresholdLeavesOutNonFiniteAndUncoveredPixels) {
    const std::vector<float> glint = {1.0f, std::numeric_limits<float>::infinity(),
                                      std::numeric_limits<float>::quiet_NaN(), 3.0f, 5.0f};
    const std::vector<float> alpha = {1.0f, 1.0f, 1.0f, 1.0f, 0.0f};
    GlintMean mean;
    mean.add(glint, alpha);
    EXPECT_EQ(mean.count, 2.0);
    EXPECT_DOUBLE_EQ(mean.threshold(), 8.0);
    EXPECT_DOUBLE_EQ(GlintMean{}.threshold(), 1.0);
}

}  // namespace
}  // namespace spangle::test_flicker
