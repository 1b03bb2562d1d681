#include <gtest/gtest.h>

#include <OpenEXR/ImfRgbaFile.h>
#include <OpenImageIO/imageio.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include "color/image_io.h"
#include "color/image_output.h"
#include "core/error.h"
#include "test_support.h"

namespace spangle::test_image_output {
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

TEST(ExrOutput, CountsEveryValueTooBrightForAHalfFloat) {
    // The count of values stored as infinity covered the beauty alone: a layered file held more.
    test::TempDir dir("exr_overflow");
    const ColorConfig color = test::shipped_config();
    std::vector<float> rgb = ramp(3, 2);
    rgb[4] = 1e6f;   // beyond 65504
    rgb[9] = -2e5f;  // and below -65504
    std::vector<float> layers(3 * 2 * 2, 1.0f);
    layers[0] = 1e6f;  // layer "a.R", written as half
    layers[3] = 1e6f;  // layer "a.Z", written as float: held exactly
    layers[5] = std::numeric_limits<float>::infinity();  // not finite to begin with: not counted
    ExrOptions opt;
    opt.layers = &layers;
    opt.layer_names = {"a.R", "a.Z"};
    opt.layer_full_float = {0, 1};
    EXPECT_EQ(write_exr(dir.file("o.exr"), rgb, 3, 2, color, opt), 3u);
    opt.half = false;
    EXPECT_EQ(write_exr(dir.file("f.exr"), rgb, 3, 2, color, opt), 0u);
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
    PngOptions standard;
    standard.view = "Standard";
    write_png_preview(dir.file("p.png"), rgb, 1, 1, color, standard);
    auto in = OIIO::ImageInput::open(dir.file("p.png"));
    ASSERT_TRUE(in);
    unsigned char px[3];
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px));
    EXPECT_EQ(px[0], 188) << "sRGB encoding of 0.5 is 0.7354, 187.5 in 8 bits";
    EXPECT_EQ(px[1], 0);
    EXPECT_EQ(px[2], 255) << "clipped";
    // The Glint view: both channels times d / m = (4 / 4.8) / 4, ratio kept.
    PngOptions glint;
    glint.view = "Glint";
    write_png_preview(dir.file("g.png"), rgb, 1, 1, color, glint);
    in = OIIO::ImageInput::open(dir.file("g.png"));
    ASSERT_TRUE(in);
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px));
    EXPECT_EQ(px[0], 91) << "sRGB encoding of 0.5 * 0.8333 / 4 = 0.104 is 0.3585, 91.4 in 8 bits";
    EXPECT_LE(px[1], 1);
    EXPECT_EQ(px[2], 235) << "sRGB encoding of 0.8333 is 0.9216, 235.0 in 8 bits";
    // The default view (Sparkle): m = 4 gives d = 0.99954 and a white share w = 0.104, so
    // R = 0.896 * 0.5 * d / 4 + w d = 0.2159 (sRGB 128.6), G = w d = 0.1040 (91.7), B = d (255).
    // Tolerance: the LUT errs by up to 3% in display-linear values (test_color.cpp), about 1.7
    // levels of 8 bits here; a channel that is 0 gets its white share from nodes on either side
    // of the blend's start, interpolated in log2 where it rises from nothing: 4% low (89 for
    // 91.7), so 3 levels.
    write_png_preview(dir.file("s.png"), rgb, 1, 1, color);
    in = OIIO::ImageInput::open(dir.file("s.png"));
    ASSERT_TRUE(in);
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px));
    EXPECT_NEAR(px[0], 128.6, 3.0);
    EXPECT_NEAR(px[1], 91.7, 3.0) << "a glint four times white starts to whiten";
    EXPECT_GE(px[2], 254);
}

}  // namespace
}  // namespace spangle::test_image_output

namespace spangle::test_image_output {
namespace {

/** Writes rgba (w x h x channels floats) with OpenImageIO in whatever format `path` names. */
void write_with_oiio(const std::string& path, const std::vector<float>& pixels, int w, int h,
                     int channels) {
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out) << OIIO::geterror();
    ASSERT_TRUE(out->open(path, OIIO::ImageSpec(w, h, channels, OIIO::TypeDesc::FLOAT)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()));
    ASSERT_TRUE(out->close());
}

TEST(ImageInput, ExrIsReadDirectlyAndOtherFormatsThroughTheOiioModule) {
    // The same pixels as an EXR (read with OpenEXR) and as a Radiance HDR (read by the
    // OpenImageIO module, opened on demand): both come back, in order, row 0 at the top.
    test::TempDir dir("image_input");
    const int w = 6, h = 4;
    std::vector<float> rgba(static_cast<std::size_t>(w * h * 4));
    for (std::size_t i = 0; i < rgba.size(); ++i)
        rgba[i] = 0.25f + static_cast<float>(i % 13) * 0.5f;
    write_with_oiio(dir.file("a.exr"), rgba, w, h, 4);
    ImageHeader exr;
    const std::vector<float> from_exr = read_image(dir.file("a.exr"), 3, exr);
    EXPECT_EQ(exr.width, w);
    EXPECT_EQ(exr.height, h);
    EXPECT_EQ(exr.channels, 4) << "the header reports every channel";
    ASSERT_EQ(from_exr.size(), static_cast<std::size_t>(w * h * 3)) << "but three are read";
    for (std::size_t p = 0; p < static_cast<std::size_t>(w * h); ++p)
        for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(from_exr[3 * p + c], rgba[4 * p + c]);

    std::vector<float> rgb(static_cast<std::size_t>(w * h * 3));
    for (std::size_t p = 0; p < static_cast<std::size_t>(w * h); ++p)
        for (std::size_t c = 0; c < 3; ++c) rgb[3 * p + c] = rgba[4 * p + c];
    write_with_oiio(dir.file("a.hdr"), rgb, w, h, 3);
    const ImageHeader hdr_header = read_image_header(dir.file("a.hdr"));
    EXPECT_EQ(hdr_header.width, w);
    ImageHeader hdr;
    const std::vector<float> from_hdr = read_image(dir.file("a.hdr"), 3, hdr);
    ASSERT_EQ(from_hdr.size(), rgb.size());
    for (std::size_t i = 0; i < rgb.size(); ++i)
        EXPECT_NEAR(from_hdr[i], rgb[i], 0.01f * rgb[i]) << "RGBE keeps 8 bits of mantissa";
}

/** Writes a w x h grey image at path in `format` (OpenImageIO's type), naming `space` as its
 *  oiio:ColorSpace when not empty. */
void write_typed(const std::string& path, OIIO::TypeDesc format, const std::string& space) {
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out) << OIIO::geterror();
    OIIO::ImageSpec spec(4, 2, 3, format);
    if (!space.empty()) spec.attribute("oiio:ColorSpace", space);
    const std::vector<float> grey(4 * 2 * 3, 0.5f);
    ASSERT_TRUE(out->open(path, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, grey.data()));
    ASSERT_TRUE(out->close());
}

TEST(ImageInput, UsualSpaceFollowsThePixelsNotTheName) {
    // A map or texture whose scene names no space: floating-point pixels are linear whatever
    // the format (a float TIFF map of 10 was sRGB-decoded to 224), integer ones sRGB unless the
    // file says linear; an 8-bit .tx maketx made from an sRGB PNG says sRGB (it was read as
    // linear, 2.3x too bright).
    test::TempDir dir("usual_space");
    write_typed(dir.file("f.tif"), OIIO::TypeDesc::FLOAT, "");
    write_typed(dir.file("h.tif"), OIIO::TypeDesc::HALF, "");
    write_typed(dir.file("b.tif"), OIIO::TypeDesc::UINT8, "");
    write_typed(dir.file("w.tif"), OIIO::TypeDesc::UINT16, "");
    write_typed(dir.file("lin.png"), OIIO::TypeDesc::UINT16, "Linear");
    write_typed(dir.file("s.tx"), OIIO::TypeDesc::UINT8, "sRGB");
    write_typed(dir.file("f.tx"), OIIO::TypeDesc::HALF, "");
    write_typed(dir.file("g.png"), OIIO::TypeDesc::UINT8, "");
    write_typed(dir.file("e.exr"), OIIO::TypeDesc::HALF, "");
    // A float TIFF named .png: its bytes say what it is.
    write_typed(dir.file("f_as.tif"), OIIO::TypeDesc::FLOAT, "");
    fs::rename(dir.file("f_as.tif"), dir.file("f_as.png"));
    for (const char* f : {"f.tif", "h.tif", "lin.png", "f.tx", "e.exr", "f_as.png"})
        EXPECT_EQ(usual_image_space(dir.file(f)), "lin_rec709") << f;
    for (const char* f : {"b.tif", "w.tif", "s.tx", "g.png"})
        EXPECT_EQ(usual_image_space(dir.file(f)), "srgb_texture") << f;
}

TEST(ImageInput, APngCutShortIsSaidBeforeLibpngReadsIt) {
    // libpng printed "libpng error: IDAT: Read error: hit end of file" on stderr beside the
    // error, and the error itself held three of its lines.
    test::TempDir dir("image_png_cut");
    std::ifstream in(test::asset_dir() + "/textures/beetle_livery.png", std::ios::binary);
    const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    ASSERT_GT(bytes.size(), 3000u);
    ImageHeader h;
    std::ofstream(dir.file("whole.png"), std::ios::binary) << bytes;
    EXPECT_FALSE(read_image(dir.file("whole.png"), 3, h).empty());
    std::ofstream(dir.file("cut.png"), std::ios::binary) << bytes.substr(0, 3000);
    try {
        read_image(dir.file("cut.png"), 3, h, "texture");
        FAIL() << "a PNG cut short was read";
    } catch (const SpangleError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("cannot read texture '" + dir.file("cut.png") +
                            "': the PNG file is cut short (3000 bytes; its IDAT chunk"),
                  std::string::npos)
            << what;
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
    // Cut just before its IEND chunk: every chunk whole, but no end.
    std::ofstream(dir.file("no_end.png"), std::ios::binary) << bytes.substr(0, bytes.size() - 12);
    EXPECT_THROW(read_image(dir.file("no_end.png"), 3, h, "texture"), SpangleError);
    // Cut before its first IDAT: the header alone reads (textures read it first), and libpng
    // printed its lines there.
    const std::size_t idat = bytes.find("IDAT");
    ASSERT_NE(idat, std::string::npos);
    std::ofstream(dir.file("no_data.png"), std::ios::binary) << bytes.substr(0, idat - 4);
    testing::internal::CaptureStderr();
    try {
        read_image_header(dir.file("no_data.png"), "texture", true);
        ADD_FAILURE() << "the header of a PNG without its data was taken";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("the PNG file is cut short"), std::string::npos)
            << e.what();
    }
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

TEST(ImageInput, LuminanceChromaExrKeepsItsColour) {
    // OpenEXR's YC images (Y, RY, BY; written by cameras and some compositors) are rebuilt into
    // RGB: read as Y alone they came out grey.
    test::TempDir dir("image_yc");
    const int w = 8, h = 6;
    std::vector<Imf::Rgba> px(static_cast<std::size_t>(w * h));
    for (auto& p : px) p = Imf::Rgba(0.8f, 0.2f, 0.1f, 1.0f);
    {
        Imf::RgbaOutputFile out(dir.file("yc.exr").c_str(), w, h, Imf::WRITE_YC);
        out.setFrameBuffer(px.data(), 1, static_cast<std::size_t>(w));
        out.writePixels(h);
    }
    ImageHeader header;
    EXPECT_EQ(read_image_header(dir.file("yc.exr")).channels, 3);
    const std::vector<float> rgb = read_image(dir.file("yc.exr"), 3, header);
    ASSERT_EQ(rgb.size(), static_cast<std::size_t>(w * h * 3));
    EXPECT_EQ(header.channels, 3);
    // Chroma is subsampled and stored in half floats: a flat colour comes back within 2%.
    for (std::size_t p = 0; p < static_cast<std::size_t>(w * h); ++p) {
        EXPECT_NEAR(rgb[3 * p + 0], 0.8f, 0.016f);
        EXPECT_NEAR(rgb[3 * p + 1], 0.2f, 0.004f);
        EXPECT_NEAR(rgb[3 * p + 2], 0.1f, 0.002f);
    }
}

TEST(ExrOutput, CarriesRenderTimeAndCameraMatrices) {
    test::TempDir dir("exr_matrices");
    ExrOptions o;
    o.floats = {{"renderTimeSeconds", 12.5f}};
    std::array<float, 16> m{};
    for (std::size_t i = 0; i < 16; ++i) m[i] = static_cast<float>(i) + 0.5f;
    o.matrices = {{"worldToCamera", m}};
    write_exr(dir.file("m.exr"), ramp(4, 3), 4, 3, test::shipped_config(), o);
    auto in = OIIO::ImageInput::open(dir.file("m.exr"));
    ASSERT_TRUE(in) << OIIO::geterror();
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.get_float_attribute("renderTimeSeconds", -1.0f), 12.5f);
    const OIIO::ParamValue* p = spec.find_attribute("worldToCamera");
    ASSERT_TRUE(p);
    ASSERT_EQ(p->type(), OIIO::TypeDesc(OIIO::TypeMatrix44));
    const auto* v = static_cast<const float*>(p->data());
    for (std::size_t i = 0; i < 16; ++i) EXPECT_EQ(v[i], m[i]) << "row-major, element " << i;
}

TEST(ImageInput, UnreadableFilesNameWhatAndWhere) {
    test::TempDir dir("image_input_bad");
    std::ofstream(dir.file("junk.exr")) << "not an image at all";
    ImageHeader h;
    try {
        read_image(dir.file("junk.exr"), 3, h, "environment map");
        FAIL() << "junk was read";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot read environment map '" +
                                             dir.file("junk.exr") + "'"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_THROW(read_image_header(dir.file("missing.exr")), SpangleError);
}

}  // namespace
}  // namespace spangle::test_image_output
