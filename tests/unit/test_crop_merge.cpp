// Crop windows and merges: a frame rendered as crop windows (not aligned to the 16-pixel tiles,
// one pair overlapping) and merged by merge_exr_parts equals the whole render bit for bit,
// beauty and layers, on a glittering, textured scene; bad part sets are refused.

#include <gtest/gtest.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <cstring>
#include <fstream>
#include <limits>

#include "color/image_merge.h"
#include "color/image_output.h"
#include "pipeline/frame.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_crop_merge {
namespace {

/** A render of tests/scenes/textured.toml (absolute paths) at 72 x 40, `spp` samples. */
FrameRequest textured_request(const test::TempDir& dir, uint32_t spp) {
    return test::scene_request(dir, "textured.toml", 72, 40, spp);
}

/** The textured scene at 4 spp with layers, in a crop window. */
FrameResult render(const test::TempDir& dir, CropWindow crop) {
    FrameRequest req = textured_request(dir, 4);
    req.options.layers = true;
    req.options.crop = crop;
    return render_frame(req);
}

/** Writes r as a 32-bit EXR with its layers, its data window where its crop lies (marked as a
 *  render a stop signal cut short with `partial`). */
void write(const FrameResult& r, const std::string& path, bool partial = false) {
    ExrOptions o;
    o.half = false;
    o.layers = &r.layers;
    o.layer_names = r.layer_names;
    o.metadata = {{"spangle:spp", "4"}};
    if (partial) o.metadata.emplace_back("spangle:partial", "1");
    o.origin_x = static_cast<int>(r.window.x0);
    o.origin_y = static_cast<int>(r.window.y0);
    o.display_width = static_cast<int>(r.window.full_width);
    o.display_height = static_cast<int>(r.window.full_height);
    write_exr(path, r.image, static_cast<int>(r.width), static_cast<int>(r.height), r.color, o);
}

/** Every channel of an EXR (display window = data window), interleaved, and the names. */
std::vector<float> read_all(const std::string& path, std::vector<std::string>& names) {
    Imf::InputFile in(path.c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    const auto w = static_cast<std::size_t>(dw.max.x - dw.min.x + 1);
    const auto h = static_cast<std::size_t>(dw.max.y - dw.min.y + 1);
    names.clear();
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it)
        names.emplace_back(it.name());
    std::vector<float> px(w * h * names.size());
    Imf::FrameBuffer fb;
    for (std::size_t c = 0; c < names.size(); ++c)
        fb.insert(names[c],
                  Imf::Slice::Make(Imf::FLOAT, px.data() + c, dw, names.size() * sizeof(float),
                                   w * names.size() * sizeof(float)));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    return px;
}

TEST(CropMerge, CropsMergeIntoTheWholeRenderBitForBit) {
    test::TempDir dir("crop_merge");
    const FrameResult whole = render(dir, {});
    write(whole, dir.file("whole.exr"));
    // Three windows across the tile grid: the left 37 columns, the rest of the top, the rest of
    // the bottom, overlapping the first along x = 30..36.
    const CropWindow windows[] = {{0, 0, 37, 40}, {30, 0, 72, 23}, {37, 23, 72, 40}};
    std::vector<std::string> parts;
    for (std::size_t i = 0; i < 3; ++i) {
        const FrameResult r = render(dir, windows[i]);
        EXPECT_EQ(r.width, windows[i].x1 - windows[i].x0);
        EXPECT_EQ(r.height, windows[i].y1 - windows[i].y0);
        EXPECT_EQ(r.stats.samples, static_cast<uint64_t>(r.width) * r.height * 4)
            << "only the window";
        parts.push_back(dir.file("part" + std::to_string(i) + ".exr"));
        write(r, parts.back());
    }
    const MergeReport rep = merge_exr_parts(parts, dir.file("merged.exr"));
    EXPECT_EQ(rep.width, 72);
    EXPECT_EQ(rep.height, 40);
    EXPECT_EQ(rep.overlap_pixels, 7u * 23u);
    EXPECT_TRUE(rep.partial_parts.empty());
    {
        // A part a stop signal cut short makes a partial whole: named (merge warns with it).
        const FrameResult r = render(dir, windows[2]);
        write(r, dir.file("stopped.exr"), true);
        const MergeReport p =
            merge_exr_parts({parts[0], parts[1], dir.file("stopped.exr")}, dir.file("p.exr"));
        EXPECT_EQ(p.partial_parts, std::vector<std::string>{dir.file("stopped.exr")});
    }
    std::vector<std::string> names_whole, names_merged;
    const std::vector<float> a = read_all(dir.file("whole.exr"), names_whole);
    const std::vector<float> b = read_all(dir.file("merged.exr"), names_merged);
    EXPECT_EQ(names_merged, names_whole);
    EXPECT_GT(names_whole.size(), 20u) << "beauty and layers";
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0)
        << "the merged frame differs from the whole render";
    double sum = 0.0;
    for (float v : a) sum += std::isfinite(v) ? v : 0.0f;
    EXPECT_GT(sum, 0.0);

    // A missing window, and parts of different frames, are refused with the file named.
    try {
        merge_exr_parts({parts[0], parts[1]}, dir.file("holes.exr"));
        FAIL() << "a frame with a hole was merged";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("uncovered"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(dir.file("holes.exr")));
    try {
        merge_exr_parts({parts[0], dir.file("whole.exr"), test::asset_dir() + "/env/studio.exr"},
                        dir.file("mixed.exr"));
        FAIL() << "parts of different frames were merged";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("studio.exr"), std::string::npos) << e.what();
    }
}

/** The same scene's beauty, 8 spp, samples [first, end) (end 0: all), as a --spp-range part. */
FrameResult render_range(const test::TempDir& dir, uint32_t first, uint32_t end,
                         bool progressive = true) {
    FrameRequest req = textured_request(dir, 8);
    req.options.spp_first = first;
    req.options.spp_end = end;
    req.options.progressive = progressive;
    return render_frame(req);
}

TEST(SppRange, SampleRangesMergeIntoTheWholeRenderBitForBit) {
    test::TempDir dir("spp_merge");
    const FrameResult whole = render_range(dir, 0, 0);
    EXPECT_EQ(whole.stats.spp_reached, 8u);
    ExrOptions o;
    o.half = false;
    write_exr(dir.file("whole.exr"), whole.image, 72, 40, whole.color, o);
    // Three ranges, one rendered in a single pass, written out of order.
    const uint32_t ranges[][2] = {{5, 8}, {0, 3}, {3, 5}};
    std::vector<std::string> parts;
    std::vector<SampleSum> total(whole.sums.size(), SampleSum(0));
    for (const auto& r : ranges) {
        const FrameResult part = render_range(dir, r[0], r[1], r[0] != 0);
        EXPECT_EQ(part.stats.spp_reached, r[1] - r[0]);
        EXPECT_EQ(part.stats.spp_frame, 8u);
        EXPECT_EQ(part.stats.samples, 72u * 40u * (r[1] - r[0])) << "only its samples";
        for (std::size_t i = 0; i < total.size(); ++i) total[i] += part.sums[i];
        ExrOptions po;
        po.half = false;
        po.sums = &part.sums;
        po.metadata = {{"spangle:spp", std::to_string(r[1] - r[0])},
                       {"spangle:spp_range", fmt::format("{}..{}", r[0], r[1])},
                       {"spangle:spp_frame", "8"}};
        parts.push_back(dir.file(fmt::format("range{}.exr", r[0])));
        write_exr(parts.back(), part.image, 72, 40, part.color, po);
    }
    EXPECT_TRUE(total == whole.sums) << "the parts' sums add up to the whole render's";
    const MergeReport rep = merge_exr_parts(parts, dir.file("merged.exr"));
    EXPECT_EQ(rep.sample_ranges, 3u);
    std::vector<std::string> names_whole, names_merged;
    const std::vector<float> a = read_all(dir.file("whole.exr"), names_whole);
    const std::vector<float> b = read_all(dir.file("merged.exr"), names_merged);
    EXPECT_EQ(names_merged, names_whole) << "R, G, B: the sums are not carried over";
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0)
        << "the merged frame differs from the whole render";
    double mean = 0.0;
    for (float v : a) mean += v;
    EXPECT_GT(mean, 0.0);

    // Ranges that leave samples out, or hold some twice, are refused.
    try {
        merge_exr_parts({parts[0], parts[1]}, dir.file("gap.exr"));
        FAIL() << "a merge without samples 3..5 was written";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("samples 3..5 of the frame's 8 are in no part"),
                  std::string::npos)
            << e.what();
    }
    try {
        merge_exr_parts({parts[0], parts[1], parts[2], parts[2]}, dir.file("twice.exr"));
        FAIL() << "a merge with samples 3..5 twice was written";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("samples 3..5 are in"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(dir.file("gap.exr")));
    EXPECT_FALSE(std::filesystem::exists(dir.file("twice.exr")));
}

TEST(SppRange, FixedPointSumsAreExactInAnyOrder) {
    // Values a float sum rounds differently by order: a huge glint beside small values.
    const float v[] = {1.0e8f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 2.5e-9f};
    SampleSum forward = 0, backward = 0;
    for (float x : v) forward += to_sample_sum(x);
    for (int i = 6; i >= 0; --i) backward += to_sample_sum(v[i]);
    EXPECT_TRUE(forward == backward);
    float ff = 0.0f, fb = 0.0f;
    for (float x : v) ff += x;
    for (int i = 6; i >= 0; --i) fb += v[i];
    EXPECT_NE(ff, fb) << "these values do round differently in floats (the test's premise)";
    EXPECT_EQ(sample_mean(forward, 7), static_cast<float>((1.0e8 + 5.0) / 7.0));
    // Words round-trip, negative sums included; NaN adds nothing; huge values are clamped.
    uint32_t w[4];
    for (const SampleSum s : {forward, -forward, SampleSum(-1), SampleSum(0)}) {
        sample_sum_words(s, w);
        EXPECT_TRUE(sample_sum_from_words(w) == s);
    }
    EXPECT_TRUE(to_sample_sum(std::numeric_limits<float>::quiet_NaN()) == 0);
    EXPECT_EQ(sample_mean(to_sample_sum(std::numeric_limits<float>::infinity()), 1), 0x1p60f);
}

TEST(CropMerge, AWindowOutsideTheImageIsRefused) {
    test::TempDir dir("crop_outside");
    try {
        render(dir, {60, 0, 80, 10});
        FAIL() << "a crop beyond the image rendered";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("is not inside the 72x40 image"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace spangle::test_crop_merge
