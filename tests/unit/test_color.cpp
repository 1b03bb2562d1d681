#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "core/error.h"
#include "test_support.h"

namespace spangle {
namespace {

using test::shipped_config;

TEST(ColorConfig, SrgbTextureDecodesToLinear) {
    ColorConfig c = shipped_config();
    float rgb[3] = {0.5f, 0.0f, 1.0f};
    c.convert("srgb_texture", "lin_rec709", rgb, 1);
    // IEC 61966-2-1: ((0.5 + 0.055) / 1.055)^2.4 = 0.214041.
    EXPECT_NEAR(rgb[0], 0.214041f, 1e-5f);
    EXPECT_NEAR(rgb[1], 0.0f, 1e-6f);
    EXPECT_NEAR(rgb[2], 1.0f, 1e-5f);
}

TEST(ColorConfig, Rec709RedInAcescg) {
    ColorConfig c = shipped_config();
    float rgb[3] = {1.0f, 0.0f, 0.0f};
    c.convert("lin_rec709", "ACEScg", rgb, 1);
    // Published linear-sRGB-to-ACEScg (Bradford) matrix, first column: 0.61310, 0.07019, 0.02062.
    EXPECT_NEAR(rgb[0], 0.61310f, 2e-4f);
    EXPECT_NEAR(rgb[1], 0.07019f, 2e-4f);
    EXPECT_NEAR(rgb[2], 0.02062f, 2e-4f);
    float grey[3] = {0.5f, 0.5f, 0.5f};
    c.convert("lin_rec709", "ACEScg", grey, 1);
    for (float g : grey) EXPECT_NEAR(g, 0.5f, 1e-4f) << "white maps to white under Bradford";
}

TEST(ColorConfig, DisplayViewEncodesSrgb) {
    ColorConfig c = shipped_config();
    c.set_working_space("lin_rec709");
    float rgb[3] = {0.214041f, 2.0f, -1.0f};
    c.to_display("sRGB", "Standard", rgb, 1);
    EXPECT_NEAR(rgb[0], 0.5f, 1e-4f);
    EXPECT_NEAR(rgb[1], 1.0f, 1e-6f) << "the Standard view clips above 1";
    EXPECT_NEAR(rgb[2], 0.0f, 1e-6f) << "and below 0";
}

/** sRGB decoding (the IEC 61966-2-1 curve). */
float srgb_decode(float v) {
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

TEST(ColorConfig, TheDefaultViewIsToneMappedAndKeepsABrightGlintsColour) {
    ColorConfig c = shipped_config();
    c.set_working_space("lin_rec709");
    std::string display, view;
    c.resolve_view(display, view);
    EXPECT_EQ(display, "sRGB");
    EXPECT_EQ(view, "Glint");
    // The view's formula (assets/tools/make_glint_lut.py): every channel times d / m, m the
    // largest, d = m / (m + 0.8). The LUT between log encodings must reproduce it.
    const float colours[][3] = {{8.0f, 2.5f, 1.2f},  {0.18f, 0.18f, 0.18f}, {1.0f, 1.0f, 1.0f},
                                {0.05f, 0.3f, 0.9f}, {30.0f, 0.5f, 12.0f},  {0.6f, 0.01f, 0.2f},
                                {120.f, 90.f, 100.f}};
    for (const auto& in : colours) {
        float out[3] = {in[0], in[1], in[2]};
        c.to_display("sRGB", "Glint", out, 1);
        const float m = std::max({in[0], in[1], in[2]});
        const float d = m / (m + 0.8f);
        // Tolerance: linear interpolation of log2 d between nodes h = 0.625 stops apart errs by
        // at most h^2 / 8 times the curvature of log2(m + 0.8) in stops (<= ln 2 / 4): 0.0085
        // in log2, 0.6% relative.
        for (int ch = 0; ch < 3; ++ch)
            EXPECT_NEAR(srgb_decode(out[ch]), in[ch] * d / m, 0.006f * (in[ch] * d / m) + 2e-4f)
                << "input (" << in[0] << ", " << in[1] << ", " << in[2] << ") channel " << ch;
    }
    // An orange glint eight times brighter than white: Standard clips it to white, the Glint
    // view keeps it orange (channel ratios 8 : 2.5 : 1.2), ACES 1.0 takes it near white.
    float glint[3] = {8.0f, 2.5f, 1.2f};
    float standard[3] = {glint[0], glint[1], glint[2]}, kept[3] = {glint[0], glint[1], glint[2]},
          aces[3] = {glint[0], glint[1], glint[2]};
    c.to_display("sRGB", "Standard", standard, 1);
    c.to_display("sRGB", "Glint", kept, 1);
    c.to_display("sRGB", "ACES 1.0 - SDR Video", aces, 1);
    for (float v : standard) EXPECT_NEAR(v, 1.0f, 1e-6f) << "Standard clips it to white";
    EXPECT_NEAR(srgb_decode(kept[1]) / srgb_decode(kept[0]), 2.5f / 8.0f, 0.01f);
    EXPECT_NEAR(srgb_decode(kept[2]) / srgb_decode(kept[0]), 1.2f / 8.0f, 0.01f);
    EXPECT_GT(aces[2], 0.8f) << "ACES 1.0 desaturates it (why Glint is the default)";
    // Unknown names say what exists.
    std::string bad_view = "Filmic";
    try {
        c.resolve_view(display, bad_view);
        FAIL() << "an unknown view was accepted";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("views: Glint, ACES 1.0 - SDR Video, Standard, Raw"),
                  std::string::npos)
            << e.what();
    }
}

TEST(ColorConfig, AliasesAndUnknownNames) {
    ColorConfig c = shipped_config();
    EXPECT_EQ(c.canonical_name("acescg").value_or(""), "ACEScg");
    EXPECT_FALSE(c.canonical_name("no such space").has_value());
    try {
        c.set_working_space("sRGB2");
        FAIL() << "an unknown working space must be refused";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("unknown colour space 'sRGB2'"), std::string::npos)
            << e.what();
    }
    EXPECT_EQ(c.working_space(), "ACEScg") << "scene_linear role is the default working space";
}

TEST(ColorConfig, WorkingChromaticities) {
    ColorConfig c = shipped_config();
    auto ap1 = c.working_chromaticities();
    ASSERT_TRUE(ap1.has_value());
    EXPECT_FLOAT_EQ(ap1->xy[0], 0.713f);
    EXPECT_FLOAT_EQ(ap1->xy[6], 0.32168f);
    c.set_working_space("lin_rec709");
    auto rec = c.working_chromaticities();
    ASSERT_TRUE(rec.has_value());
    EXPECT_FLOAT_EQ(rec->xy[0], 0.64f);
    EXPECT_FLOAT_EQ(rec->xy[7], 0.3290f);
}

TEST(ColorConfig, EnvironmentVariableOverridesFallbacks) {
    test::TempDir dir("ocio_env");
    const std::string copy = dir.file("copy.ocio");
    std::filesystem::copy_file(test::shipped_ocio(), copy);
    ::setenv("OCIO", copy.c_str(), 1);
    ColorConfig from_env = ColorConfig::load("", {test::shipped_ocio()});
    ColorConfig explicit_path = ColorConfig::load(test::shipped_ocio(), {});
    ::unsetenv("OCIO");
    EXPECT_EQ(from_env.path(), copy);
    EXPECT_EQ(explicit_path.path(), test::shipped_ocio()) << "an explicit path beats $OCIO";
    ColorConfig fallback = ColorConfig::load("", {dir.file("missing.ocio"), test::shipped_ocio()});
    EXPECT_EQ(fallback.path(), test::shipped_ocio());
}

TEST(ColorConfig, MissingConfigIsAClearError) {
    ::unsetenv("OCIO");
    try {
        ColorConfig::load("", {"/nonexistent/config.ocio"});
        FAIL();
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("no OpenColorIO config found"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("/nonexistent/config.ocio"), std::string::npos);
    }
}

}  // namespace
}  // namespace spangle
