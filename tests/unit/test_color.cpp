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
    c.to_display(c.default_display(), c.default_view(c.default_display()), rgb, 1);
    EXPECT_NEAR(rgb[0], 0.5f, 1e-4f);
    EXPECT_NEAR(rgb[1], 1.0f, 1e-6f) << "the Standard view clips above 1";
    EXPECT_NEAR(rgb[2], 0.0f, 1e-6f) << "and below 0";
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
