// Image textures: lookups against the image they came from (bilinear at mip 0, a blurred mip for
// a large footprint), colour conversion, and whole renders: a textured parameter, a neutral
// normal map that must change nothing, and a flake mask whose empty half holds no glint.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "color/image_output.h"
#include "pipeline/frame.h"
#include "scene_request.h"
#include "shading/texture.h"
#include "test_support.h"

namespace spangle::test_textures {
namespace {

/** Writes w x h RGB floats as a 32-bit EXR (scene-linear: the working space of the config). */
void write_float_exr(const std::string& path, const std::vector<float>& rgb, int w, int h) {
    const ColorConfig color = test::shipped_config();
    ExrOptions o;
    o.half = false;
    write_exr(path, rgb, w, h, color, o);
}

/** An n x n RGB image whose pixel (x, y) is value(x, y) in every channel. */
template <class Value>
std::vector<float> grey_image(int n, const Value& value) {
    std::vector<float> img(3 * static_cast<std::size_t>(n * n));
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
            for (int c = 0; c < 3; ++c)
                img[3 * static_cast<std::size_t>(y * n + x) + static_cast<std::size_t>(c)] =
                    value(x, y);
    return img;
}

/** A TextureService over the shipped config whose cache lives in `dir`. */
struct Textures {
    explicit Textures(const test::TempDir& dir)
        : service(color, test::quiet_log(), {dir.file("cache"), 64}) {
        color.set_working_space("lin_rec709");
    }
    ColorConfig color = test::shipped_config();
    TextureService service;
};

/** 8 x 8 texels with distinct values: red = x, green = y, blue = x * y (quarter units). */
constexpr int kGrid = 8;
std::vector<float> grid_image() {
    std::vector<float> img(3 * kGrid * kGrid);
    for (int y = 0; y < kGrid; ++y)
        for (int x = 0; x < kGrid; ++x) {
            float* p = &img[3 * static_cast<std::size_t>(y * kGrid + x)];
            p[0] = 0.25f * static_cast<float>(x);
            p[1] = 0.25f * static_cast<float>(y);
            p[2] = 0.0625f * static_cast<float>(x * y);
        }
    return img;
}

/** One lookup at (s, t) with footprint derivatives d along both axes. */
std::vector<float> lookup(const TextureService& ts, const Texture& tex, float s, float t, float d,
                          int channels, int filter = 0) {
    TextureQuery q;
    q.resize(1);
    q.s[0] = s;
    q.t[0] = t;
    q.dsdx[0] = d;
    q.dtdy[0] = d;
    q.dtdx[0] = q.dsdy[0] = 0.0f;
    std::vector<float> out(static_cast<std::size_t>(channels));
    TextureRef clamp;
    clamp.wrap = 1;
    clamp.filter = filter;
    ts.lookup(tex, clamp, q, 1, channels, out.data());
    return out;
}

TEST(Texture, EachAxisWrapsAsItsOwnModeSays) {
    // glTF's wrapS and wrapT differ (a trim sheet clamped across, repeated along): both were
    // wrapped as wrapS says. The grid: red = x, green = y (quarter units).
    test::TempDir dir("texture_wrap_axes");
    constexpr int kH = 8;
    write_float_exr(dir.file("grid.exr"), grid_image(), kGrid, kGrid);
    Textures t(dir);
    TextureRef ref;
    ref.path = dir.file("grid.exr");
    ref.space = "raw";
    ref.wrap = 1;    // clamp along s
    ref.wrap_t = 0;  // periodic along t
    const auto tex = t.service.open(ref, false, {});
    TextureQuery q;
    q.resize(1);
    q.s[0] = -0.5f;             // clamped: the first column, red 0
    q.t[0] = 1.0f + 2.5f / kH;  // periodic: the third row's centre, green 0.5
    q.dsdx[0] = q.dtdy[0] = 1e-5f;
    q.dtdx[0] = q.dsdy[0] = 0.0f;
    float out[3];
    t.service.lookup(*tex, ref, q, 1, 3, out);
    EXPECT_NEAR(out[0], 0.0f, 2e-3f);
    EXPECT_NEAR(out[1], 0.5f, 2e-3f);
    // The cut-out's texels in memory wrap alike (s + 4 t).
    AlphaTexels a;
    a.width = a.height = 2;
    a.texels = {0, 65535, 65535, 0};  // row 0: 0 1; row 1: 1 0
    EXPECT_EQ(ref.wraps(), 1);
    // s beyond the right edge clamps to column 1; t one period on is row 0 again.
    EXPECT_NEAR(a.at(1.6f, 1.25f, ref.wraps(), true), 1.0f, 1e-6f);
    ref.wrap_t = 2;  // black along t: outside is 0
    EXPECT_NEAR(a.at(1.6f, 1.25f, ref.wraps(), true), 0.0f, 1e-6f);
}

TEST(Texture, LookupsAreBilinearAtTheFinestLevel) {
    test::TempDir dir("texture_bilinear");
    constexpr int kW = kGrid, kH = kGrid;
    const std::vector<float> img = grid_image();
    write_float_exr(dir.file("grid.exr"), img, kW, kH);
    Textures t(dir);
    TextureRef ref;
    ref.path = dir.file("grid.exr");
    ref.space = "raw";
    const auto tex = t.service.open(ref, false, {});
    ASSERT_EQ(tex->channels, 3);
    const auto texel = [&](int x, int y, int c) {
        return img[3 * static_cast<std::size_t>(y * kW + x) + static_cast<std::size_t>(c)];
    };
    // Between texel centres: the bilinear mix of the four around.
    for (const auto& [fx, fy] :
         {std::pair{2.5f, 3.5f}, {3.0f, 4.25f}, {5.7f, 1.2f}, {4.0f, 4.0f}}) {
        const float s = fx / kW, tt = fy / kH;
        const std::vector<float> got = lookup(t.service, *tex, s, tt, 1e-5f, 3);
        const float gx = fx - 0.5f, gy = fy - 0.5f;
        const int x0 = static_cast<int>(std::floor(gx)), y0 = static_cast<int>(std::floor(gy));
        const float ax = gx - static_cast<float>(x0), ay = gy - static_cast<float>(y0);
        for (int c = 0; c < 3; ++c) {
            const float want =
                (1 - ax) * (1 - ay) * texel(x0, y0, c) + ax * (1 - ay) * texel(x0 + 1, y0, c) +
                (1 - ax) * ay * texel(x0, y0 + 1, c) + ax * ay * texel(x0 + 1, y0 + 1, c);
            // The converted copy is half-float: 11 bits of mantissa.
            EXPECT_NEAR(got[static_cast<std::size_t>(c)], want, 2e-3f * std::max(1.0f, want))
                << "at texel coordinates (" << fx << ", " << fy << ") channel " << c;
        }
        // filter = "closest" (glTF's NEAREST): the texel the point falls in, even under a
        // footprint of several texels (no blurred level). (Points on a texel's edge, x = 3, may
        // take either side.)
        if (fx == std::floor(fx) || fy == std::floor(fy)) continue;
        for (const float d : {1e-5f, 0.3f}) {
            const std::vector<float> near = lookup(t.service, *tex, s, tt, d, 3, 2);
            const int x = std::min(static_cast<int>(fx), kW - 1),
                      y = std::min(static_cast<int>(fy), kH - 1);
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(near[static_cast<std::size_t>(c)], texel(x, y, c),
                            2e-3f * std::max(1.0f, texel(x, y, c)))
                    << "closest at (" << fx << ", " << fy << ") footprint " << d;
        }
    }
}

TEST(Texture, ALargeFootprintReadsABlurredLevel) {
    test::TempDir dir("texture_mip");
    // A one-texel checker of 0 and 1: any single texel is 0 or 1, its average is 0.5.
    constexpr int kN = 64;
    const std::vector<float> img =
        grey_image(kN, [](int x, int y) { return static_cast<float>((x + y) % 2); });
    write_float_exr(dir.file("checker.exr"), img, kN, kN);
    Textures t(dir);
    TextureRef ref;
    ref.path = dir.file("checker.exr");
    ref.space = "raw";
    const auto tex = t.service.open(ref, false, {});
    // A footprint of one texel at a texel centre: the texel itself.
    const float centre = (10.0f + 0.5f) / kN;
    EXPECT_NEAR(lookup(t.service, *tex, centre, centre, 1e-4f, 1)[0], 0.0f, 1e-3f);
    EXPECT_NEAR(lookup(t.service, *tex, centre + 1.0f / kN, centre, 1e-4f, 1)[0], 1.0f, 1e-3f);
    // A footprint of 16 texels: a coarse level, where the checker has averaged to grey (with
    // either filter: the footprint is round, anisotropic filtering takes the same level).
    for (int filter : {0, 1})
        for (float s : {0.2f, 0.37f, 0.61f})
            for (float tt : {0.3f, 0.55f})
                EXPECT_NEAR(lookup(t.service, *tex, s, tt, 16.0f / kN, 1, filter)[0], 0.5f, 0.03f)
                    << "at (" << s << ", " << tt << ") filter " << filter;
}

TEST(Texture, VRunsUpTheImageAndTheUvTransformMovesIt) {
    test::TempDir dir("texture_orient");
    // Row 0 is the top of an image: the top half white, the bottom half black, and a grey
    // left column strip to tell left from right.
    constexpr int kN = 16;
    const std::vector<float> img =
        grey_image(kN, [](int x, int y) { return x < 4 ? 0.5f : (y < kN / 2 ? 1.0f : 0.0f); });
    write_float_exr(dir.file("half.exr"), img, kN, kN);
    Textures t(dir);
    TextureRef ref;
    ref.path = dir.file("half.exr");
    ref.space = "raw";
    ref.wrap = 1;
    const auto tex = t.service.open(ref, false, {});
    const auto at = [&](const TextureRef& r, float u, float v) {
        const float d = 1e-4f, zero = 0.0f;
        TextureQuery q;
        texture_coordinates(r, &u, &v, &d, &zero, &zero, &d, 1, q);
        float out = -1.0f;
        t.service.lookup(*tex, r, q, 1, 1, &out);
        return out;
    };
    EXPECT_NEAR(at(ref, 0.8f, 0.9f), 1.0f, 1e-3f) << "v = 0.9 is near the image's top";
    EXPECT_NEAR(at(ref, 0.8f, 0.1f), 0.0f, 1e-3f);
    EXPECT_NEAR(at(ref, 0.1f, 0.5f), 0.5f, 1e-3f) << "u = 0.1 is at the left";
    // Rotated by 180 degrees about the origin and moved back into [0, 1]^2: top and bottom,
    // left and right swap.
    TextureRef turned = ref;
    turned.uv[0] = -1.0f;
    turned.uv[2] = 1.0f;
    turned.uv[4] = -1.0f;
    turned.uv[5] = 1.0f;
    EXPECT_NEAR(at(turned, 0.2f, 0.9f), 0.0f, 1e-3f);
    EXPECT_NEAR(at(turned, 0.2f, 0.1f), 1.0f, 1e-3f);
    EXPECT_NEAR(at(turned, 0.9f, 0.5f), 0.5f, 1e-3f);
}

TEST(Texture, ColourTexturesAreConvertedToTheWorkingSpaceOnce) {
    test::TempDir dir("texture_colour");
    std::vector<float> img = {0.5f, 0.25f, 1.0f, 0.5f, 0.25f, 1.0f,
                              0.5f, 0.25f, 1.0f, 0.5f, 0.25f, 1.0f};
    write_float_exr(dir.file("flat.exr"), img, 2, 2);
    Textures t(dir);
    t.color.set_working_space("ACEScg");
    TextureRef ref;
    ref.path = dir.file("flat.exr");
    ref.space = "lin_rec709";
    const auto tex = t.service.open(ref, true, {});
    float want[3] = {0.5f, 0.25f, 1.0f};
    t.color.convert("lin_rec709", "ACEScg", want, 1);
    const std::vector<float> got = lookup(t.service, *tex, 0.5f, 0.5f, 1e-3f, 3);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[static_cast<std::size_t>(c)], want[c], 2e-3f);
    // The same texture again: the cached copy, not a second conversion.
    EXPECT_EQ(t.service.open(ref, true, {}).get(), tex.get());
    const auto files = std::distance(std::filesystem::directory_iterator(dir.file("cache")),
                                     std::filesystem::directory_iterator{});
    EXPECT_EQ(files, 1);
}

TEST(Texture, PartialConversionsAKilledRenderLeftAreRemovedOnceStale) {
    // A render killed while it converted a texture left a hidden temporary in the cache for good
    // (3 to 28 MB each). One unwritten for an hour goes when the cache is next written; one of
    // a conversion that may still run (recent) stays, as do the cache's entries.
    namespace fs = std::filesystem;
    test::TempDir dir("texture_stale");
    fs::create_directories(dir.file("cache"));
    const std::string old_tmp = dir.file("cache/.big-0123456789abcdef.exr.4242.tmp.temp.exr");
    const std::string new_tmp = dir.file("cache/.big-fedcba9876543210.exr.4243.tmp.exr");
    const std::string entry = dir.file("cache/other-0123456789abcdef.exr");
    for (const std::string& f : {old_tmp, new_tmp, entry}) std::ofstream(f) << "partial";
    fs::last_write_time(old_tmp, fs::file_time_type::clock::now() - std::chrono::hours(2));
    fs::last_write_time(entry, fs::file_time_type::clock::now() - std::chrono::hours(2));
    write_float_exr(dir.file("flat.exr"), std::vector<float>(12, 0.5f), 2, 2);
    Textures t(dir);
    TextureRef ref;
    ref.path = dir.file("flat.exr");
    ref.space = "lin_rec709";
    ASSERT_TRUE(t.service.open(ref, true, {}));
    EXPECT_FALSE(fs::exists(old_tmp));
    EXPECT_TRUE(fs::exists(new_tmp));
    EXPECT_TRUE(fs::exists(entry));
}

TEST(Texture, AnExrIsReadInTheSpaceItsHeaderNames) {
    // Spangle's own render (colorSpace "ACEScg") used as a texture was read as lin_rec709,
    // though the file says what it is: now the header's space, when the config has it.
    test::TempDir dir("texture_header_space");
    ColorConfig acescg = test::shipped_config();
    acescg.set_working_space("ACEScg");
    ExrOptions o;
    o.half = false;
    write_exr(dir.file("plate.exr"),
              {0.5f, 0.2f, 0.1f, 0.5f, 0.2f, 0.1f, 0.5f, 0.2f, 0.1f, 0.5f, 0.2f, 0.1f}, 2, 2,
              acescg, o);
    Textures t(dir);  // working space lin_rec709
    TextureRef ref;
    ref.path = dir.file("plate.exr");
    const std::vector<float> got =
        lookup(t.service, *t.service.open(ref, true, {}), 0.5f, 0.5f, 1e-3f, 3);
    float want[3] = {0.5f, 0.2f, 0.1f};
    t.color.convert("ACEScg", "lin_rec709", want, 1);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[static_cast<std::size_t>(c)], want[c], 2e-3f);
    EXPECT_GT(std::fabs(want[0] - 0.5f), 0.05f) << "the two spaces differ here";
    // A space the config lacks: the usual one (linear for EXR), and a warning.
    ExrOptions named = o;
    named.metadata = {{"colorSpace", "Some Studio Space"}};
    write_exr(dir.file("other.exr"),
              {0.5f, 0.2f, 0.1f, 0.5f, 0.2f, 0.1f, 0.5f, 0.2f, 0.1f, 0.5f, 0.2f, 0.1f}, 2, 2,
              acescg, named);
    ref.path = dir.file("other.exr");
    const std::vector<float> as_is =
        lookup(t.service, *t.service.open(ref, true, {}), 0.5f, 0.5f, 1e-3f, 3);
    EXPECT_NEAR(as_is[0], 0.5f, 2e-3f);
    EXPECT_NEAR(as_is[1], 0.2f, 2e-3f);
    EXPECT_NEAR(as_is[2], 0.1f, 2e-3f);
}

TEST(Texture, AConfigEditedInPlaceConvertsAnew) {
    // The converted copy is found by what the conversion does, not by the config's path: a
    // config edited in place (a show's new version at the same $OCIO) kept the old colours until
    // someone emptied the cache.
    test::TempDir dir("texture_config_edit");
    const std::filesystem::path shipped = test::shipped_ocio();
    std::filesystem::copy(shipped.parent_path(), dir.file("ocio"),
                          std::filesystem::copy_options::recursive);
    const std::string config = dir.file("ocio") + "/" + shipped.filename().string();
    write_float_exr(dir.file("flat.exr"), std::vector<float>(12, 0.5f), 2, 2);
    TextureRef ref;
    ref.path = dir.file("flat.exr");
    ref.space = "srgb_texture";
    const auto value = [&] {
        ColorConfig color = ColorConfig::load(config, {});
        color.set_working_space("lin_rec709");
        TextureService service(color, test::quiet_log(), {dir.file("cache"), 64});
        return lookup(service, *service.open(ref, true, {}), 0.5f, 0.5f, 1e-3f, 3)[0];
    };
    EXPECT_NEAR(value(), 0.2140f, 2e-3f) << "sRGB 0.5 decoded";
    std::stringstream read;
    read << std::ifstream(config).rdbuf();
    std::string text = read.str();
    const std::string curve = "{gamma: 2.4, offset: 0.055}";
    ASSERT_NE(text.find(curve), std::string::npos);
    test::replace_all(text, curve, "{gamma: 1.0, offset: 0.0}");
    std::ofstream(config) << text;
    EXPECT_NEAR(value(), 0.5f, 2e-3f) << "the edited config's identity curve";
}

/** A camera looking straight down at a unit plane under a small light; `material` is the
 *  [[material]] table's body. */
std::string plane_scene(const std::string& material, int spp = 8) {
    return fmt::format(R"(
[render]
width = 64
height = 64
spp = {}
max_depth = 1
filter = "box"
working_space = "lin_rec709"
[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]
fov = 20
[[material]]
name = "m"
{}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "m"
rotate = [90, 0, 0]
scale = 0.6
[[light]]
type = "sphere"
center = [0.4, 0.3, 3.2]
radius = 0.03
intensity = 3000
)",
                       spp, material, test::asset_dir());
}

FrameResult render_text(const test::TempDir& dir, const std::string& name,
                        const std::string& text) {
    return render_frame(test::text_request(dir, name, text));
}

TEST(Texture, ANeutralNormalMapChangesNothing) {
    test::TempDir dir("texture_normal");
    std::vector<float> flat(3 * 4 * 4);
    for (std::size_t i = 0; i < flat.size(); i += 3) {
        flat[i] = flat[i + 1] = 0.5f;
        flat[i + 2] = 1.0f;
    }
    write_float_exr(dir.file("flat_normal.exr"), flat, 4, 4);
    const std::string body = R"(plugin = "smooth"
model = "conductor"
params = { preset = "gold", roughness = 0.2 })";
    const FrameResult plain = render_text(dir, "plain.toml", plane_scene(body));
    const FrameResult mapped = render_text(
        dir, "mapped.toml", plane_scene(body + "\nnormal_map = { texture = \"flat_normal.exr\" }"));
    ASSERT_EQ(plain.image.size(), mapped.image.size());
    double sum = 0.0;
    for (std::size_t i = 0; i < plain.image.size(); ++i) {
        sum += plain.image[i];
        ASSERT_NEAR(mapped.image[i], plain.image[i], 1e-4f * std::max(1.0f, plain.image[i]))
            << "value " << i;
    }
    EXPECT_GT(sum, 1.0) << "the plane is lit";
    // A tilted map does change the image (the comparison above can fail).
    std::vector<float> tilted = flat;
    for (std::size_t i = 0; i < tilted.size(); i += 3) tilted[i] = 0.8f;
    write_float_exr(dir.file("tilted.exr"), tilted, 4, 4);
    const FrameResult t = render_text(
        dir, "tilted.toml", plane_scene(body + "\nnormal_map = { texture = \"tilted.exr\" }"));
    double diff = 0.0;
    for (std::size_t i = 0; i < t.image.size(); ++i) diff += std::fabs(t.image[i] - plain.image[i]);
    EXPECT_GT(diff, 0.1 * sum);
    // The opposite tilt in an image turned by 180 degrees in uv is the same tilt on the surface:
    // the map's axes follow the uv transform.
    std::vector<float> opposite = flat;
    for (std::size_t i = 0; i < opposite.size(); i += 3) opposite[i] = 0.2f;
    write_float_exr(dir.file("opposite.exr"), opposite, 4, 4);
    const FrameResult turned = render_text(
        dir, "turned.toml",
        plane_scene(body + "\nnormal_map = { texture = \"opposite.exr\", uv_transform = { rotate = "
                           "180 } }"));
    for (std::size_t i = 0; i < t.image.size(); ++i)
        ASSERT_NEAR(turned.image[i], t.image[i], 1e-3f * std::max(1.0f, t.image[i])) << i;
    // A negative strength inverts the bumps (glTF's negative normalTexture.scale, which the
    // reader clamped to 0, a flat map): the opposite tilt at strength -1 is the tilt.
    const FrameResult inverted = render_text(
        dir, "inverted.toml",
        plane_scene(body + "\nnormal_map = { texture = \"opposite.exr\", strength = -1 }"));
    for (std::size_t i = 0; i < t.image.size(); ++i)
        ASSERT_NEAR(inverted.image[i], t.image[i], 1e-3f * std::max(1.0f, t.image[i])) << i;
}

TEST(Texture, ANumberParameterReadsAColourImagesChannelOrLuminance) {
    // Found by a user: a colour image linked into Blender's Roughness is read by its luminance;
    // Spangle read its first channel (a red/blue checker rendered 7x too rough in half its
    // squares). `channel` says which: "r", "g", "b" or "luminance" (of a raw image: Rec.709's
    // weights, as Blender's scene-linear space).
    test::TempDir dir("texture_channel");
    const float rgb[3] = {0.9f, 0.1f, 0.3f};
    const float y = 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2];
    const auto image = [](float r, float g, float b) {
        std::vector<float> px(3 * 4 * 4);
        for (std::size_t i = 0; i < px.size(); i += 3) {
            px[i] = r;
            px[i + 1] = g;
            px[i + 2] = b;
        }
        return px;
    };
    write_float_exr(dir.file("colour.exr"), image(rgb[0], rgb[1], rgb[2]), 4, 4);
    write_float_exr(dir.file("lum.exr"), image(y, y, y), 4, 4);
    write_float_exr(dir.file("green.exr"), image(rgb[1], rgb[1], rgb[1]), 4, 4);
    write_float_exr(dir.file("red.exr"), image(rgb[0], rgb[0], rgb[0]), 4, 4);
    const auto metal = [&](const std::string& file, const std::string& channel) {
        const std::string ch = channel.empty() ? "" : ", channel = \"" + channel + "\"";
        return render_text(
            dir, file + channel + ".toml",
            plane_scene("plugin = \"smooth\"\nmodel = \"conductor\"\n"
                        "params = { preset = \"silver\", roughness = { texture = \"" +
                        file + "\", space = \"raw\"" + ch + " } }"));
    };
    const auto near = [](const FrameResult& a, const FrameResult& b) {
        double diff = 0.0, sum = 0.0;
        for (std::size_t i = 0; i < a.image.size(); ++i) {
            diff += std::fabs(a.image[i] - b.image[i]);
            sum += std::fabs(b.image[i]);
        }
        return diff / std::max(sum, 1e-9);
    };
    const FrameResult lum = metal("colour.exr", "luminance"), grey = metal("lum.exr", "");
    const FrameResult first = metal("colour.exr", ""), red = metal("red.exr", "");
    const FrameResult green = metal("colour.exr", "g"), green_grey = metal("green.exr", "");
    // Textures are kept as half floats: the grey image holds y rounded to half, the colour one
    // each channel rounded (half's step is 2^-11 of a value: 5e-4).
    EXPECT_LT(near(lum, grey), 1e-3) << "luminance: the grey image of that value";
    EXPECT_LT(near(green, green_grey), 1e-4) << "channel g: the green channel";
    EXPECT_LT(near(first, red), 1e-4) << "no channel: the first, as before";
    EXPECT_GT(near(lum, first), 0.05) << "the comparisons above can fail";
    // A colour parameter has no channel to pick.
    try {
        render_text(
            dir, "bad.toml",
            plane_scene("plugin = \"smooth\"\nmodel = \"diffuse\"\n"
                        "params = { albedo = { texture = \"colour.exr\", channel = \"g\" } }"));
        ADD_FAILURE() << "a channel on a colour parameter was accepted";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("parameter 'albedo' is a colour: 'channel' picks"),
                  std::string::npos)
            << e.what();
    }
}

TEST(Texture, ANormalMapTiltedAwayFromTheViewerStillReflects) {
    // A white diffuse floor in a white furnace, seen at 68 degrees from its normal, under maps
    // tilting the normal 42 degrees towards -u, +u, -v and +v: from one side or another the
    // viewer is below the mapped normal, and the diffuse model reflected nothing there (the
    // floor rendered black where real bumps show their lit side). The normal is bent back so
    // that the viewer's mirror direction leaves the surface: every pixel stays bright.
    test::TempDir dir("texture_normal_away");
    int dark_maps = 0;
    for (int axis = 0; axis < 2; ++axis)
        for (const float tilt : {0.05f, 0.95f}) {
            std::vector<float> map(3 * 4 * 4);
            for (std::size_t i = 0; i < map.size(); i += 3) {
                map[i] = map[i + 1] = 0.5f;
                map[i + static_cast<std::size_t>(axis)] = tilt;
                map[i + 2] = 1.0f;
            }
            const std::string name = fmt::format("tilt{}_{}", axis, tilt > 0.5f ? "up" : "down");
            write_float_exr(dir.file(name + ".exr"), map, 4, 4);
            const FrameResult r = render_text(dir, name + ".toml",
                                              fmt::format(R"(
[render]
width = 48
height = 32
spp = 32
max_depth = 8
filter = "box"
[camera]
position = [-3, 1.2, 0.4]
look_at = [0, 0, 0]
fov = 20
[environment]
color = [1, 1, 1]
[[material]]
name = "m"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 1.0 }}
normal_map = {{ texture = "{}.exr" }}
[[object]]
mesh = "{}/meshes/plane.ply"
material = "m"
scale = 20
)",
                                                          name, test::asset_dir()));
            ASSERT_EQ(r.width, 48u);
            float lowest = 1e9f;
            for (const float v : r.image) lowest = std::min(lowest, v);
            EXPECT_GT(lowest, 0.3f) << name << ": a pixel went dark";
            dark_maps += lowest < 0.05f ? 1 : 0;
        }
    EXPECT_EQ(dark_maps, 0);
}

TEST(Texture, ABumpMapsStrengthBlendsTheNormalsAsBlendersBumpDoes) {
    // strength 0: the surface's normal (the image of no map); 1: the bumped one; between: the
    // normalised blend of the two, which is not a lower height (Blender's Bump Strength).
    test::TempDir dir("texture_bump_strength");
    std::vector<float> ramp(3 * 16 * 16);
    for (std::size_t p = 0; p < 16 * 16; ++p)
        ramp[3 * p] = ramp[3 * p + 1] = ramp[3 * p + 2] = static_cast<float>(p % 16) / 15.0f;
    write_float_exr(dir.file("ramp.exr"), ramp, 16, 16);
    const std::string body = R"(plugin = "smooth"
model = "diffuse")";
    const auto with = [&](const std::string& name, const std::string& map) {
        return render_text(dir, name, plane_scene(body + "\n" + map)).image;
    };
    const std::vector<float> plain = with("plain.toml", "");
    const std::string bump = "bump_map = { texture = \"ramp.exr\", ";
    const std::vector<float> none = with("none.toml", bump + "height = 1, strength = 0 }");
    const std::vector<float> full = with("full.toml", bump + "height = 1 }");
    const std::vector<float> half = with("half.toml", bump + "height = 1, strength = 0.5 }");
    const std::vector<float> lower = with("lower.toml", bump + "height = 0.5 }");
    const auto distance = [](const std::vector<float>& a, const std::vector<float>& b) {
        double d = 0.0;
        for (std::size_t i = 0; i < a.size(); ++i) d += std::fabs(a[i] - b[i]);
        return d;
    };
    ASSERT_EQ(plain.size(), none.size());
    EXPECT_LT(distance(none, plain), 1e-3 * distance(full, plain));
    EXPECT_GT(distance(half, plain), 0.1 * distance(full, plain));
    EXPECT_GT(distance(half, full), 0.1 * distance(full, plain));
    EXPECT_GT(distance(half, lower), 0.05 * distance(full, plain)) << "a blend is not a height";
    // Out of [0, 1] is an error at the key.
    EXPECT_THROW(with("bad.toml", "bump_map = { texture = \"ramp.exr\", strength = 1.5 }"),
                 SpangleError);
}

TEST(Texture, AFlakeMaskHoldsNoGlintWhereItIsZero) {
    test::TempDir dir("texture_mask");
    // Left half of the image 0, right half 1. The plane's uvs span [0, 4]: a uv scale of 1/4
    // lays the image over the whole plane.
    constexpr int kN = 32;
    const std::vector<float> mask =
        grey_image(kN, [](int x, int) { return x < kN / 2 ? 0.0f : 1.0f; });
    write_float_exr(dir.file("mask.exr"), mask, kN, kN);
    const auto flake = [](const std::string& weight) {
        return "plugin = \"flake\"\nparams = { base_color = 0.2, flake_weight = " + weight +
               ", density = 200000, flake_roughness = 0.3, gamma = 2, min_flakes = 5000, "
               "max_flakes = 10000 }";
    };
    const FrameResult masked = render_text(
        dir, "masked.toml",
        plane_scene(
            flake("{ texture = \"mask.exr\", wrap = \"clamp\", uv_transform = { scale = 0.25 } }"),
            16));
    const FrameResult none = render_text(dir, "none.toml", plane_scene(flake("0.0"), 16));
    const FrameResult full = render_text(dir, "full.toml", plane_scene(flake("1.0"), 16));
    // Which half of the image the mask's zero half covers depends on the plane's uv layout:
    // the one that is closer to the flake-free render.
    const uint32_t w = masked.width, h = masked.height;
    const auto lum = [&](const FrameResult& r, uint32_t x, uint32_t y) {
        const float* p = &r.image[3 * (static_cast<std::size_t>(y) * w + x)];
        return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    };
    // Per half (0: x < w / 2): difference to the flake-free and to the all-flake render, the
    // flake-free render's sum, the brightest pixel. 4 pixels each side of the edge are left out
    // (the mask is filtered across it).
    double to_none[2] = {0, 0}, to_full[2] = {0, 0}, none_sum[2] = {0, 0}, brightest[2] = {0, 0};
    int pixels[2] = {0, 0};
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x) {
            if (x + 4 >= w / 2 && x <= w / 2 + 4) continue;
            const int half = x < w / 2 ? 0 : 1;
            const double m = lum(masked, x, y);
            to_none[half] += std::fabs(m - lum(none, x, y));
            to_full[half] += std::fabs(m - lum(full, x, y));
            none_sum[half] += lum(none, x, y);
            brightest[half] = std::max(brightest[half], m);
            ++pixels[half];
        }
    const int zero = to_none[0] < to_none[1] ? 0 : 1, one = 1 - zero;
    ASSERT_GT(pixels[zero], 100);
    ASSERT_GT(pixels[one], 100);
    // Where the mask is 0 the image is the flake-free render's, value for value.
    EXPECT_LE(to_none[zero], 1e-5 * none_sum[zero]) << "the zero half differs from weight 0";
    // Where it is 1, the all-flake render's glints.
    EXPECT_LE(to_full[one], 1e-4 * pixels[one]) << "the one half differs from weight 1";
    EXPECT_GT(brightest[one], 4.0 * brightest[zero]) << "the glitter half glints";
}

/** tests/scenes/textured.toml with `from` replaced by `to`, its relative paths made absolute,
 *  rendered at 64 x 32, 4 spp. */
FrameResult render_textured(const test::TempDir& dir, const std::string& name,
                            const std::string& from = "", const std::string& to = "") {
    std::ofstream(dir.file(name)) << test::scene_text(
        "textured.toml", from.empty()
                             ? std::vector<std::pair<std::string, std::string>>{}
                             : std::vector<std::pair<std::string, std::string>>{{from, to}});
    FrameRequest req;
    req.scene = dir.file(name);
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.width_override = 64;
    req.options.height_override = 32;
    req.options.spp_override = 4;
    req.options.texture_cache = dir.file("cache");
    return render_frame(req);
}

TEST(Texture, EveryKindOfInputInOneSceneRendersAndMatters) {
    test::TempDir dir("texture_scene");
    const FrameResult all = render_textured(dir, "all.toml");
    double sum = 0.0;
    for (float v : all.image) {
        ASSERT_TRUE(std::isfinite(v));
        sum += v;
    }
    EXPECT_GT(sum, 0.0);
    EXPECT_EQ(all.stats.nonfinite, 0u);
    // Each input, replaced by a constant, changes the image: it was used.
    const std::pair<std::string, std::string> constant[] = {
        {"roughness = { texture = \"textures/roughness_ramp.png\" }", "roughness = 0.3"},
        {"normal_map = { texture = \"textures/ripple_normal.png\", strength = 1.0, uv_transform = "
         "{ "
         "scale = [4, 2] } }",
         ""},
        {"flake_weight = { texture = \"../../assets/textures/beetle_flakes.png\" }",
         "flake_weight = 0.45"},
        {"albedo = { texture = \"../../assets/textures/beetle_livery.png\", uv_transform = { scale "
         "= "
         "[2, 1] } }",
         "albedo = 0.5"},
    };
    for (const auto& [from, to] : constant) {
        const FrameResult r = render_textured(dir, "variant.toml", from, to);
        double diff = 0.0;
        for (std::size_t i = 0; i < r.image.size(); ++i)
            diff += std::fabs(r.image[i] - all.image[i]);
        EXPECT_GT(diff, 1e-3 * sum) << "replacing " << from;
    }
}

TEST(Texture, ParametersThatMustBeConstantRefuseATexture) {
    test::TempDir dir("texture_refuse");
    std::vector<float> px(3 * 4, 0.5f);
    write_float_exr(dir.file("t.exr"), px, 2, 2);
    try {
        render_text(dir, "bad.toml", plane_scene(R"(plugin = "smooth"
model = "plastic"
params = { roughness = { texture = "t.exr" } })"));
        FAIL() << "a texture on plastic's roughness was accepted";
    } catch (const SpangleError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("bad.toml:"), std::string::npos) << what;
        EXPECT_NE(what.find("cannot take a texture"), std::string::npos) << what;
        EXPECT_NE(what.find("albedo"), std::string::npos) << what;  // what can take one
    }
    try {
        render_text(dir, "missing.toml", plane_scene(R"(plugin = "smooth"
model = "diffuse"
params = { albedo = { texture = "nowhere.png" } })"));
        FAIL() << "a missing texture file was accepted";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("texture file 'nowhere.png' not found"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace spangle::test_textures
