#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "color/image_output.h"
#include "core/error.h"
#include "pipeline/session.h"
#include "test_support.h"

namespace spangle::test_color {
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

TEST(ColorConfig, DataSpacesAreKnownByWhatTheConfigSays) {
    // A texture in a data space by another config's name ("Non-Color") is read as numbers: its
    // coloured scale is not carried through the primaries (scene_builder makes it "raw").
    const ColorConfig foreign = ColorConfig::load(test::test_dir() + "/ocio/foreign.ocio", {});
    EXPECT_TRUE(foreign.is_data("Non-Color"));
    EXPECT_FALSE(foreign.is_data(foreign.working_space()));
    EXPECT_FALSE(foreign.is_data("no such space"));
    const ColorConfig shipped = test::shipped_config();
    EXPECT_TRUE(shipped.is_data("raw"));
    EXPECT_FALSE(shipped.is_data("srgb_texture"));
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

/** The Sparkle view's formula in display-linear values (assets/tools/make_glint_lut.py): every
 *  channel times d / m (m the largest channel, d linear to 0.5 and a shoulder above), blended
 *  towards (d, d, d) by a smoothstep of log2 m from 1 to 6. */
std::array<float, 3> sparkle_formula(const float* in) {
    const double m = std::max({in[0], in[1], in[2]});
    const double d = m <= 0.5 ? m : 0.5 + 0.5 * (1.0 - std::exp(-(m - 0.5) / 0.5));
    const double t = std::clamp((std::log2(m) - 1.0) / 5.0, 0.0, 1.0);
    const double w = t * t * (3.0 - 2.0 * t);
    std::array<float, 3> out{};
    for (int ch = 0; ch < 3; ++ch) out[ch] = float((1.0 - w) * in[ch] * d / m + w * d);
    return out;
}

TEST(ColorConfig, TheDefaultViewKeepsHueBelowTwiceWhiteAndTakesBrightGlintsToWhite) {
    ColorConfig c = shipped_config();
    c.set_working_space("lin_rec709");
    std::string display, view;
    c.resolve_view(display, view);
    EXPECT_EQ(display, "sRGB");
    EXPECT_EQ(view, "Sparkle");
    const float colours[][3] = {{0.18f, 0.18f, 0.18f}, {1.0f, 1.0f, 1.0f},  {0.05f, 0.3f, 0.9f},
                                {1.9f, 0.6f, 0.2f},    {8.0f, 2.5f, 1.2f},  {30.0f, 0.5f, 12.0f},
                                {44.0f, 20.0f, 8.0f},  {0.6f, 0.01f, 0.2f}, {120.f, 90.f, 100.f}};
    for (const auto& in : colours) {
        float out[3] = {in[0], in[1], in[2]};
        c.to_display("sRGB", "Sparkle", out, 1);
        const auto want = sparkle_formula(in);
        // Tolerance: the LUT's nodes are 0.625 stops apart; between them the tone curve and the
        // white blend (both smooth in log2 m but with kinks in curvature at m = 0.5 and 2) are
        // interpolated linearly. The formula, put through a tetrahedral interpolation of the
        // same nodes in Python, errs by at most 2.9% of a channel's display-linear value over
        // these colours (at 1.9, next to the blend's start): 4% leaves room for float.
        for (int ch = 0; ch < 3; ++ch)
            EXPECT_NEAR(srgb_decode(out[ch]), std::min(want[ch], 1.0f), 0.04f * want[ch] + 2e-4f)
                << "input (" << in[0] << ", " << in[1] << ", " << in[2] << ") channel " << ch;
    }
    // Diffuse white shows at 0.816 display-linear (sRGB 0.914), middle grey at 0.18 (0.461).
    float white[3] = {1.0f, 1.0f, 1.0f}, grey[3] = {0.18f, 0.18f, 0.18f};
    c.to_display("sRGB", "Sparkle", white, 1);
    c.to_display("sRGB", "Sparkle", grey, 1);
    EXPECT_NEAR(white[0], 0.914f, 0.005f);
    EXPECT_NEAR(grey[0], 0.461f, 0.005f);
    // An orange glint below twice diffuse white keeps its channel ratios, as under Glint.
    float orange[3] = {1.9f, 0.6f, 0.2f};
    c.to_display("sRGB", "Sparkle", orange, 1);
    EXPECT_NEAR(srgb_decode(orange[1]) / srgb_decode(orange[0]), 0.6f / 1.9f, 0.01f);
    EXPECT_NEAR(srgb_decode(orange[2]) / srgb_decode(orange[0]), 0.2f / 1.9f, 0.01f);
    // A glint 44 times diffuse white (the brightest pixels of a render at 16 spp) shows white:
    // every channel above 0.97 in sRGB, where Glint keeps it a dimmer orange.
    float bright[3] = {44.0f, 20.0f, 8.0f}, glint[3] = {44.0f, 20.0f, 8.0f};
    c.to_display("sRGB", "Sparkle", bright, 1);
    c.to_display("sRGB", "Glint", glint, 1);
    for (float v : bright) EXPECT_GT(v, 0.97f) << "a bright glint reaches white";
    EXPECT_LT(glint[2], 0.75f) << "the Glint view keeps it coloured";
}

TEST(ColorConfig, TheGlintViewIsToneMappedAndKeepsABrightGlintsColour) {
    ColorConfig c = shipped_config();
    c.set_working_space("lin_rec709");
    std::string display = "sRGB", view;
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
    EXPECT_GT(aces[2], 0.8f) << "ACES 1.0 desaturates it";
    // Unknown names say what exists.
    std::string bad_view = "Filmic";
    try {
        c.resolve_view(display, bad_view);
        FAIL() << "an unknown view was accepted";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find(
                      "views: Sparkle, Glint, ACES 1.0 - SDR Video, Standard, Raw"),
                  std::string::npos)
            << e.what();
    }
}

TEST(ColorConfig, AColourOutsideTheWorkingGamutIsClippedAndSaid) {
    // ACEScg green in a lin_rec709 scene is (-0.62, 1.14, -0.13): its negative parts are
    // clipped (radiance cannot be negative), which makes another colour: said at the colour,
    // once. In ACEScg it is kept, and nothing is said.
    test::TempDir dir("gamut_note");
    const auto notes_for = [&](const std::string& working) {
        std::ofstream(dir.file("s.toml"))
            << "[render]\nwidth = 8\nheight = 8\nworking_space = \"" << working
            << "\"\n[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[environment]\n"
               "color = { rgb = [0, 1, 0], space = \"ACEScg\" }\n";
        RenderOptions options;
        Session session({}, test::shipped_ocio(), options, test::quiet_log());
        session.load(dir.file("s.toml"), 0.0);
        return session.info().notes;
    };
    const std::vector<std::string> narrow = notes_for("lin_rec709");
    ASSERT_EQ(narrow.size(), 1u);
    EXPECT_NE(narrow[0].find("s.toml:9:9: colour (0, 1, 0) in 'ACEScg' is outside the working "
                             "space 'lin_rec709'"),
              std::string::npos)
        << narrow[0];
    EXPECT_TRUE(notes_for("ACEScg").empty());
}

TEST(ColorConfig, AMaterialsColourOutsideTheWorkingGamutIsSaid) {
    // A parameter's colour was clamped to its range after the conversion without a word (the
    // same colour on a light or the sky was said).
    test::TempDir dir("gamut_param");
    const auto said = [&](const std::string& working) {
        std::ofstream(dir.file("s.toml"))
            << "[render]\nwidth = 8\nheight = 8\nworking_space = \"" << working
            << "\"\n[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[[material]]\n"
               "name = \"m\"\nplugin = \"smooth\"\nmodel = \"diffuse\"\n"
               "params = { albedo = { rgb = [0, 1, 0], space = \"ACEScg\" } }\n[[object]]\n"
               "mesh = \""
            << test::asset_dir() << "/meshes/sphere.obj\"\nmaterial = \"m\"\n";
        RenderOptions options;
        const Logger log{LogLevel::Warning};
        Session session({}, test::shipped_ocio(), options, log);
        testing::internal::CaptureStderr();
        session.load(dir.file("s.toml"), 0.0);
        return testing::internal::GetCapturedStderr();
    };
    const std::string narrow = said("lin_rec709");
    EXPECT_NE(narrow.find("s.toml:12:21: material 'm': 'albedo' (0, 1, 0) in 'ACEScg' is (-0.6218, "
                          "1.141, -0.129) in the working space 'lin_rec709', outside [0, 1]"),
              std::string::npos)
        << narrow;
    EXPECT_EQ(said("ACEScg").find("outside"), std::string::npos);
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

/** A config that says nothing of encodings but for one space (as every v1 config and many v2
 *  ones): a log, an sRGB-like and a linear (matrix) space, a clamp declared scene-linear and the
 *  same clamp silent, a named transform and a space whose LUT is missing. */
constexpr const char* kSilentConfig = R"(ocio_profile_version: 2.1
search_path: "luts"
roles:
  default: Linear Ref
  scene_linear: Linear Ref
  compositing_log: Log Enc
displays:
  Monitor:
    - !<View> {name: Raw, colorspace: Linear Ref}
colorspaces:
  - !<ColorSpace>
    name: Linear Ref
  - !<ColorSpace>
    name: Wide Gamut
    to_scene_reference: !<MatrixTransform> {matrix: [2, 0, 0, 0, 0, 4, 0, 0, 0, 0, 8, 0, 0, 0, 0, 1]}
  - !<ColorSpace>
    name: Log Enc
    to_scene_reference: !<LogAffineTransform> {base: 2, log_side_slope: 0.1, log_side_offset: 0.5, direction: inverse}
  - !<ColorSpace>
    name: Curve Enc
    from_scene_reference: !<ExponentWithLinearTransform> {gamma: 2.4, offset: 0.055, direction: inverse}
  - !<ColorSpace>
    name: Lut Space
    to_scene_reference: !<FileTransform> {src: missing.spi1d}
  - !<ColorSpace>
    name: Clamped Declared
    encoding: scene-linear
    to_scene_reference: !<RangeTransform> {min_in_value: 0, max_in_value: 0.5, min_out_value: 0, max_out_value: 0.5}
  - !<ColorSpace>
    name: Clamped Silent
    to_scene_reference: !<RangeTransform> {min_in_value: 0, max_in_value: 0.5, min_out_value: 0, max_out_value: 0.5}
named_transforms:
  - !<NamedTransform>
    name: Doubler
    transform: !<MatrixTransform> {matrix: [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]}
)";

TEST(ColorConfig, AWorkingSpaceIsTestedForLinearityWhereTheConfigIsSilent) {
    // A log or gamma-encoded working space was taken whenever the config did not say its
    // encoding: a black frame with false warnings, or light added in encoded values. Its
    // transform is now tried on colours; a named transform is no colour space; a space whose LUT
    // is missing is said at the key, as is a colour converted through it.
    test::TempDir dir("ocio_silent");
    std::ofstream(dir.file("config.ocio")) << kSilentConfig;
    const auto load = [&](const std::string& working, const std::string& sky_space) {
        std::ofstream(dir.file("s.toml"))
            << "[render]\nwidth = 8\nheight = 8\nworking_space = \"" << working
            << "\"\n[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[environment]\n"
               "color = { rgb = [0.5, 0.25, 0.125], space = \""
            << sky_space << "\" }\n";
        RenderOptions options;
        Session session({}, dir.file("config.ocio"), options, test::quiet_log());
        try {
            session.load(dir.file("s.toml"), 0.0);
        } catch (const SpangleError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    EXPECT_EQ(load("Linear Ref", "Linear Ref"), "");
    EXPECT_EQ(load("Wide Gamut", "Linear Ref"), "") << "a matrix is linear";
    // A space the config declares scene-linear is taken at its word (a clamp above 0.5 would
    // fail the test on colours); the same transform with nothing said is tested, and fails.
    EXPECT_EQ(load("Clamped Declared", "Linear Ref"), "");
    EXPECT_NE(load("Clamped Silent", "Linear Ref").find("is not scene-linear"), std::string::npos);
    for (const char* encoded : {"Log Enc", "compositing_log", "Curve Enc"}) {
        const std::string e = load(encoded, "Linear Ref");
        EXPECT_NE(e.find("s.toml:4:17: error: working_space '" + std::string(encoded) +
                         "' is not scene-linear (its transform to the reference is not linear"),
                  std::string::npos)
            << e;
    }
    const std::string named = load("Doubler", "Linear Ref");
    EXPECT_NE(named.find("s.toml:4:17: error: 'Doubler' is a named transform of the OCIO config, "
                         "not a colour space"),
              std::string::npos)
        << named;
    const std::string lut = load("Lut Space", "Linear Ref");
    EXPECT_NE(lut.find("s.toml:4:17: error: colour space 'Lut Space': its transform to the "
                       "reference cannot be made"),
              std::string::npos)
        << lut;
    const std::string sky = load("Linear Ref", "Lut Space");
    EXPECT_NE(sky.find("s.toml:9:"), std::string::npos) << sky;
    EXPECT_NE(sky.find("colour conversion from 'Lut Space'"), std::string::npos) << sky;
}

TEST(ColorConfig, ADefaultWorkingSpaceIsTestedForLinearityToo) {
    // A scene that names no working space takes the config's scene_linear role: a role naming
    // a log space rendered with exit status 0, the header naming the log space over linear
    // values. Now an error at [render], as the key's own is at the key.
    test::TempDir dir("ocio_role");
    std::string config = kSilentConfig;
    const std::string role = "  scene_linear: Linear Ref\n";
    ASSERT_NE(config.find(role), std::string::npos);
    const auto with_role = [&](const std::string& space) {
        std::string c = config;
        c.replace(c.find(role), role.size(), "  scene_linear: " + space + "\n");
        std::ofstream(dir.file("config.ocio")) << c;
    };
    std::ofstream(dir.file("s.toml")) << "[render]\nwidth = 8\nheight = 8\n[camera]\nposition = "
                                         "[0, 0, 4]\nlook_at = [0, 0, 0]\n";
    const auto load = [&]() {
        RenderOptions options;
        Session session({}, dir.file("config.ocio"), options, test::quiet_log());
        try {
            session.load(dir.file("s.toml"), 0.0);
        } catch (const SpangleError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    with_role("Wide Gamut");
    EXPECT_EQ(load(), "") << "a matrix is linear";
    for (const char* encoded : {"Log Enc", "Curve Enc"}) {
        with_role(encoded);
        const std::string e = load();
        EXPECT_NE(e.find("s.toml:1:1: error: the OCIO config's scene_linear role names '" +
                         std::string(encoded) + "'"),
                  std::string::npos)
            << e;
        EXPECT_NE(e.find("not scene-linear"), std::string::npos) << e;
    }
}

TEST(ColorConfig, APngIsTaggedSrgbOnlyForAnSrgbDisplaysView) {
    // Every preview carried an sRGB chunk, the Raw view's data and a gamma-2 display's too:
    // colour-managed viewers re-encoded their pixels.
    ColorConfig shipped = shipped_config();
    const std::vector<float> grey(3 * 4, 0.18f);
    const auto tagged = [&](const ColorConfig& c, const std::string& display,
                            const std::string& view) {
        PngOptions o;
        o.display = display;
        o.view = view;
        const std::string png = encode_png_preview(grey, 2, 2, c, o);
        // Untagged means no colour chunk at all (libpng writes a gamma of 1/2.2 otherwise).
        if (png.find("gAMA") != std::string::npos) ADD_FAILURE() << "a gAMA chunk";
        return png.find("sRGB") != std::string::npos;
    };
    EXPECT_TRUE(tagged(shipped, "", ""));
    EXPECT_TRUE(tagged(shipped, "sRGB", "Standard"));
    EXPECT_FALSE(tagged(shipped, "sRGB", "Raw"));
    test::TempDir dir("png_tag");
    std::ofstream(dir.file("config.ocio")) << R"(ocio_profile_version: 2
roles:
  default: Linear Ref
  scene_linear: Linear Ref
displays:
  Studio Monitor:
    - !<View> {name: Plain, colorspace: Gamma Disp}
colorspaces:
  - !<ColorSpace>
    name: Linear Ref
  - !<ColorSpace>
    name: Gamma Disp
    from_scene_reference: !<ExponentTransform> {value: [2, 2, 2, 1], direction: inverse}
)";
    ColorConfig gamma = ColorConfig::load(dir.file("config.ocio"), {});
    EXPECT_FALSE(tagged(gamma, "", ""));
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

TEST(ColorConfig, WorkingChromaticitiesNameWhatTheInterchangeMeasures) {
    // A config with a CIE XYZ (D65) interchange role (as studio configs have): ACEScg under
    // another name measures as AP1 seen from D65 (red at 0.7132, white at D65's) and was written
    // so; a space named ACEScg that is Rec.709 was written as AP1. Both are now the published
    // chromaticities of what they measure; a space of other primaries keeps its measurement.
    test::TempDir dir("ocio_chroma");
    std::ofstream(dir.file("config.ocio")) << R"(ocio_profile_version: 2.1
roles:
  default: AP0
  scene_linear: ACES - ACEScg
  cie_xyz_d65_interchange: XYZ D65
displays:
  Monitor:
    - !<View> {name: Raw, colorspace: AP0}
colorspaces:
  - !<ColorSpace>
    name: AP0
  - !<ColorSpace>
    name: ACES - ACEScg
    to_scene_reference: !<MatrixTransform> {matrix: [0.6954522414, 0.1406786965, 0.1638690622, 0, 0.0447945634, 0.8596711185, 0.0955343182, 0, -0.0055258826, 0.0040252103, 1.0015006723, 0, 0, 0, 0, 1]}
  - !<ColorSpace>
    name: ACEScg
    to_scene_reference: !<MatrixTransform> {matrix: [0.4396329819, 0.3829886982, 0.1773783199, 0, 0.0897764430, 0.8134394287, 0.0967841283, 0, 0.0175411704, 0.1115465533, 0.8709122763, 0, 0, 0, 0, 1]}
  - !<ColorSpace>
    name: Odd
    to_scene_reference: !<MatrixTransform> {matrix: [0.8, 0.2, 0, 0, 0, 0.9, 0.1, 0, 0.1, 0, 0.9, 0, 0, 0, 0, 1]}
  - !<ColorSpace>
    name: XYZ D65
    to_scene_reference: !<MatrixTransform> {matrix: [0.9382798493, -0.0044514458, 0.0166275236, 0, 0.3373688908, 0.7295215667, -0.0668904575, 0, 0.0011739508, -0.0037107064, 1.0915945063, 0, 0, 0, 0, 1], direction: inverse}
)";
    ColorConfig c = ColorConfig::load(dir.file("config.ocio"), {});
    const auto ap1 = c.working_chromaticities();
    ASSERT_TRUE(ap1.has_value());
    EXPECT_FLOAT_EQ(ap1->xy[0], 0.713f);
    EXPECT_FLOAT_EQ(ap1->xy[3], 0.830f);
    EXPECT_FLOAT_EQ(ap1->xy[6], 0.32168f);
    c.set_working_space("ACEScg");
    const auto rec = c.working_chromaticities();
    ASSERT_TRUE(rec.has_value());
    EXPECT_FLOAT_EQ(rec->xy[0], 0.64f) << "a space named ACEScg that measures as Rec.709";
    EXPECT_FLOAT_EQ(rec->xy[6], 0.3127f);
    c.set_working_space("Odd");
    const auto odd = c.working_chromaticities();
    ASSERT_TRUE(odd.has_value());
    for (float known : {0.713f, 0.7347f, 0.64f}) EXPECT_GT(std::fabs(odd->xy[0] - known), 0.01f);
    EXPECT_NEAR(odd->xy[6], 0.3127f, 2e-3f) << "measured through the interchange: D65's white";
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
}  // namespace spangle::test_color
