#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <filesystem>
#include <fstream>

#include "color/image_output.h"
#include "core/error.h"
#include "test_support.h"

namespace spangle {
namespace {

namespace fs = std::filesystem;

std::vector<float> ramp(int w, int h) {
    std::vector<float> rgb(static_cast<std::size_t>(w * h * 3));
    for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i % 97) / 16.0f;
    return rgb;
}

/** Files in dir other than `keep`: an atomic writer must leave no temporaries behind. */
std::vector<std::string> other_files(const fs::path& dir, const std::string& keep) {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().filename() != keep) out.push_back(e.path().filename().string());
    return out;
}

TEST(ExrOutput, HeaderCarriesChromaticitiesAndColourSpace) {
    test::TempDir dir("exr_header");
    ColorConfig color = test::shipped_config();
    const auto rgb = ramp(7, 5);
    write_exr(dir.file("a.exr"), rgb, 7, 5, color, ExrOptions{});
    auto in = OIIO::ImageInput::open(dir.file("a.exr"));
    ASSERT_TRUE(in) << OIIO::geterror();
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.width, 7);
    EXPECT_EQ(spec.nchannels, 3);
    EXPECT_EQ(spec.format, OIIO::TypeDesc::HALF) << "half by default";
    EXPECT_EQ(spec.get_string_attribute("colorSpace"), "ACEScg");
    EXPECT_EQ(spec.get_string_attribute("compression"), "zip");
    const OIIO::ParamValue* chroma = spec.find_attribute("chromaticities");
    ASSERT_NE(chroma, nullptr);
    ASSERT_EQ(chroma->type(), OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8));
    const auto* xy = static_cast<const float*>(chroma->data());
    const float ap1[8] = {0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f};
    for (int i = 0; i < 8; ++i) EXPECT_FLOAT_EQ(xy[i], ap1[i]);
    std::vector<float> back(rgb.size());
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, back.data()));
    // Half precision: relative error below 2^-11 for these magnitudes.
    for (std::size_t i = 0; i < rgb.size(); ++i)
        EXPECT_NEAR(back[i], rgb[i], rgb[i] * 0.0005f + 1e-6f);
    EXPECT_TRUE(other_files(dir.path(), "a.exr").empty());
}

TEST(ExrOutput, FloatOnRequestAndRec709Chromaticities) {
    test::TempDir dir("exr_float");
    ColorConfig color = test::shipped_config();
    color.set_working_space("lin_rec709");
    ExrOptions opt;
    opt.half = false;
    opt.compression = "piz";
    write_exr(dir.file("f.exr"), ramp(4, 4), 4, 4, color, opt);
    auto in = OIIO::ImageInput::open(dir.file("f.exr"));
    ASSERT_TRUE(in);
    EXPECT_EQ(in->spec().format, OIIO::TypeDesc::FLOAT);
    EXPECT_EQ(in->spec().get_string_attribute("compression"), "piz");
    EXPECT_EQ(in->spec().get_string_attribute("colorSpace"), "lin_rec709");
    const auto* xy = static_cast<const float*>(in->spec().find_attribute("chromaticities")->data());
    EXPECT_FLOAT_EQ(xy[0], 0.64f);
    EXPECT_FLOAT_EQ(xy[6], 0.3127f);
}

TEST(ExrOutput, FailedWriteLeavesNothingAndKeepsTheOldFile) {
    test::TempDir dir("exr_atomic");
    ColorConfig color = test::shipped_config();
    std::ofstream(dir.file("keep.exr")) << "previous render";
    ExrOptions bad;
    bad.compression = "zipp";
    try {
        write_exr(dir.file("keep.exr"), ramp(2, 2), 2, 2, color, bad);
        FAIL();
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("unknown EXR compression 'zipp'"), std::string::npos);
    }
    std::ifstream in(dir.file("keep.exr"));
    std::string content;
    std::getline(in, content);
    EXPECT_EQ(content, "previous render");
    EXPECT_TRUE(other_files(dir.path(), "keep.exr").empty());
    try {
        write_exr(dir.file("missing/dir/x.exr"), ramp(2, 2), 2, 2, color, ExrOptions{});
        FAIL();
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
    }
}

TEST(ExrOutput, ReplacesAnExistingFileWhole) {
    test::TempDir dir("exr_replace");
    ColorConfig color = test::shipped_config();
    std::ofstream(dir.file("out.exr")) << "previous render";
    write_exr(dir.file("out.exr"), ramp(3, 3), 3, 3, color, ExrOptions{});
    auto in = OIIO::ImageInput::open(dir.file("out.exr"));
    ASSERT_TRUE(in) << "the new image replaced the old bytes";
    EXPECT_EQ(in->spec().width, 3);
    EXPECT_TRUE(other_files(dir.path(), "out.exr").empty());
}

TEST(PngPreview, GoesThroughTheDisplayView) {
    test::TempDir dir("png");
    ColorConfig color = test::shipped_config();
    color.set_working_space("lin_rec709");
    const std::vector<float> rgb = {0.5f, 0.0f, 4.0f};
    write_png_preview(dir.file("p.png"), rgb, 1, 1, color);
    auto in = OIIO::ImageInput::open(dir.file("p.png"));
    ASSERT_TRUE(in);
    unsigned char px[3];
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px));
    EXPECT_EQ(px[0], 188) << "sRGB encoding of 0.5 is 0.7354, 187.5 in 8 bits";
    EXPECT_EQ(px[1], 0);
    EXPECT_EQ(px[2], 255) << "clipped";
}

}  // namespace
}  // namespace spangle
