// Output a compositor can use as it is: `spangle render --layers` on a scene with a transparent
// background writes an EXR whose data channels are 32-bit floats while the beauty is half, whose
// RGB is zero where alpha is zero (premultiplied), and whose Cryptomatte channels and manifest --
// decoded here from the file alone, by a reader of this test -- name the right object and
// material in each pixel, with coverages that add up to the pixel's alpha. The Cryptomatte ids
// are those of the specification's own examples.

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>

#include "core/cryptomatte.h"
#include "pipeline/frame.h"
#include "test_support.h"

namespace spangle::test_compositing {
namespace {

/** A layered EXR as a compositor sees it: every channel as floats, its types, its header's
 *  string attributes. */
struct ExrFile {
    int width = 0, height = 0;
    std::map<std::string, std::vector<float>> channels;
    std::map<std::string, Imf::PixelType> types;
    std::map<std::string, std::string> strings;

    float at(const std::string& c, int x, int y) const {
        return channels.at(c)[static_cast<std::size_t>(y) * width + x];
    }
};

ExrFile read_exr(const std::string& path) {
    Imf::InputFile in(path.c_str());
    const Imf::Header& h = in.header();
    const Imath::Box2i dw = h.dataWindow();
    ExrFile f;
    f.width = dw.max.x - dw.min.x + 1;
    f.height = dw.max.y - dw.min.y + 1;
    Imf::FrameBuffer fb;
    for (auto c = h.channels().begin(); c != h.channels().end(); ++c) {
        f.types[c.name()] = c.channel().type;
        if (c.channel().type == Imf::UINT) continue;
        auto& v = f.channels[c.name()];
        v.resize(static_cast<std::size_t>(f.width) * f.height);
        fb.insert(c.name(), Imf::Slice::Make(Imf::FLOAT, v.data(), dw));
    }
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    for (auto a = h.begin(); a != h.end(); ++a)
        if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&a.attribute()))
            f.strings[a.name()] = s->value();
    return f;
}

/** A Cryptomatte manifest ({"name":"hex8", ...}) as id -> name: the hex digits are the bits
 *  of the float id. */
std::map<uint32_t, std::string> parse_manifest(const std::string& json) {
    std::map<uint32_t, std::string> out;
    std::size_t i = 0;
    const auto string_at = [&](std::size_t& k) {
        std::string s;
        EXPECT_EQ(json[k], '"');
        for (++k; k < json.size() && json[k] != '"'; ++k) {
            if (json[k] == '\\') ++k;
            s += json[k];
        }
        ++k;
        return s;
    };
    while ((i = json.find('"', i)) != std::string::npos) {
        const std::string name = string_at(i);
        i = json.find('"', json.find(':', i));
        const std::string hex = string_at(i);
        EXPECT_EQ(hex.size(), 8u) << "the id of '" << name << "'";
        out[static_cast<uint32_t>(std::stoul(hex, nullptr, 16))] = name;
    }
    return out;
}

uint32_t bits_of(float f) {
    uint32_t b;
    std::memcpy(&b, &f, sizeof(b));
    return b;
}

TEST(Cryptomatte, IdsAreTheSpecificationsExamples) {
    // The manifest examples of the Cryptomatte specification (1.1.0, "Metadata").
    EXPECT_EQ(cryptomatte_hex(cryptomatte_id("bunny")), "13851a76");
    EXPECT_EQ(cryptomatte_hex(cryptomatte_id("default")), "42c9679f");
    EXPECT_EQ(cryptomatte_hex(cryptomatte_id("bunny_porcelain_mat")), "b24b26d4");
    // MurmurHash3_x86_32's published values with seed 0.
    EXPECT_EQ(murmur3_32(""), 0u);
    EXPECT_EQ(murmur3_32("The quick brown fox jumps over the lazy dog"), 0x2e4ff723u);
    EXPECT_EQ(cryptomatte_manifest({"a\"b", "c", "c"}),
              "{\"a\\\"b\":\"" + cryptomatte_hex(cryptomatte_id("a\"b")) + "\",\"c\":\"" +
                  cryptomatte_hex(cryptomatte_id("c")) + "\"}");
}

/** Two named squares, one partly behind the other, an unnamed third one (its mesh file names
 *  it), on a transparent background under a sky and a sphere light. */
std::string squares_scene() {
    return fmt::format(R"(
[render]
width = 48
height = 32
spp = 16
max_depth = 3
transparent_background = true
working_space = "lin_rec709"
[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]
fov = 40
[environment]
color = [0.4, 0.5, 0.6]
light_group = "sky"
[[material]]
name = "glitter"
plugin = "flake"
params = {{ base_color = 0.3, flake_weight = 0.5, density = 200000, flake_roughness = 0.3, gamma = 2, min_flakes = 5000, max_flakes = 10000 }}
[[material]]
name = "stone"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.3 }}
[[object]]
name = "hero"
mesh = "{0}/meshes/plane.ply"
material = "glitter"
rotate = [90, 0, 0]
scale = 0.3
[[object]]
name = "slab"
mesh = "{0}/meshes/plane.ply"
material = "stone"
rotate = [90, 0, 0]
translate = [0.45, 0.2, -0.5]
scale = 0.35
[[object]]
mesh = "{0}/meshes/plane.ply"
material = "stone"
rotate = [90, 0, 0]
translate = [-0.8, -0.4, 0]
scale = 0.15
[[light]]
type = "sphere"
center = [1, 1, 3]
radius = 0.1
intensity = 300
light_group = "key"
)",
                       test::asset_dir());
}

/** The (name, coverage) pairs of Cryptomatte `layer` at pixel (x, y), ranked. */
std::vector<std::pair<std::string, float>> ids_at(const ExrFile& f, const std::string& layer,
                                                  const std::map<uint32_t, std::string>& names,
                                                  int x, int y) {
    std::vector<std::pair<std::string, float>> out;
    for (int k = 0; f.channels.count(fmt::format("{}{:02}.R", layer, k)); ++k)
        for (const auto& [id, cov] : {std::pair{"R", "G"}, std::pair{"B", "A"}}) {
            const float c = f.at(fmt::format("{}{:02}.{}", layer, k, cov), x, y);
            if (c == 0.0f) continue;
            const uint32_t bits = bits_of(f.at(fmt::format("{}{:02}.{}", layer, k, id), x, y));
            const auto n = names.find(bits);
            EXPECT_NE(n, names.end()) << layer << ": an id the manifest lacks at " << x << "," << y;
            out.emplace_back(n == names.end() ? "?" : n->second, c);
        }
    return out;
}

TEST(Compositing, LayeredExrIsReadyForACompositor) {
    test::TempDir dir("compositing");
    { std::ofstream(dir.file("squares.toml")) << squares_scene(); }
    const std::string exr = dir.file("squares.exr");
    const std::string cmd = fmt::format("{} render {} -o {} --layers -q --no-preview",
                                        SPANGLE_BINARY, dir.file("squares.toml"), exr);
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const ExrFile f = read_exr(exr);

    // The beauty is half (no --float); every channel the header calls data is a 32-bit float,
    // and so is every position, depth, normal and id channel.
    EXPECT_EQ(f.types.at("R"), Imf::HALF);
    ASSERT_TRUE(f.strings.count("spangle:dataChannels"));
    const std::string data = f.strings.at("spangle:dataChannels");
    std::size_t listed = 0;
    for (std::size_t a = 0; a <= data.size();) {
        const std::size_t b = std::min(data.find(',', a), data.size());
        const std::string name = data.substr(a, b - a);
        ASSERT_TRUE(f.types.count(name)) << name;
        EXPECT_EQ(f.types.at(name), Imf::FLOAT) << name;
        ++listed;
        a = b + 1;
    }
    for (const auto& [name, type] : f.types) {
        const bool is_data = name == "Z" || name == "object" || name.rfind("P.", 0) == 0 ||
                             name.rfind("Pobj.", 0) == 0 || name.rfind("N.", 0) == 0 ||
                             name.rfind("Crypto", 0) == 0;
        if (is_data) {
            EXPECT_EQ(type, Imf::FLOAT) << name;
            EXPECT_NE(data.find(name), std::string::npos) << name << " is not listed";
        }
    }
    EXPECT_EQ(listed, 11u + 24u) << "N, Z, P, Pobj, object and 2 x 12 Cryptomatte channels";

    // Premultiplied over a transparent background: nothing where nothing is.
    int empty = 0, covered = 0;
    for (int y = 0; y < f.height; ++y)
        for (int x = 0; x < f.width; ++x) {
            const float a = f.at("A", x, y);
            if (a == 0.0f) {
                ++empty;
                for (const char* c : {"R", "G", "B"})
                    ASSERT_EQ(f.at(c, x, y), 0.0f) << x << "," << y;
            } else if (a == 1.0f && f.at("R", x, y) > 0.0f) {
                ++covered;
            }
        }
    EXPECT_GT(empty, 500) << "most of the frame is background";
    EXPECT_GT(covered, 50) << "the sky still lights the squares";

    // The Cryptomatte metadata: a name, hash, conversion and manifest per key.
    std::map<std::string, std::map<uint32_t, std::string>> manifests;
    for (const auto& [key, value] : f.strings) {
        if (key.rfind("cryptomatte/", 0) != 0 || key.size() < 5 ||
            key.compare(key.size() - 5, 5, "/name") != 0)
            continue;
        const std::string at = key.substr(0, key.size() - 4);
        EXPECT_EQ(f.strings.at(at + "hash"), "MurmurHash3_32");
        EXPECT_EQ(f.strings.at(at + "conversion"), "uint32_to_float32");
        manifests[value] = parse_manifest(f.strings.at(at + "manifest"));
    }
    ASSERT_EQ(manifests.size(), 2u);
    const auto& objects = manifests.at("CryptoObject");
    const auto& materials = manifests.at("CryptoMaterial");
    std::vector<std::string> object_names, material_names;
    for (const auto& [id, n] : objects) object_names.push_back(n);
    for (const auto& [id, n] : materials) material_names.push_back(n);
    std::sort(object_names.begin(), object_names.end());
    std::sort(material_names.begin(), material_names.end());
    EXPECT_EQ(object_names, (std::vector<std::string>{"hero", "plane", "slab"}));
    EXPECT_EQ(material_names, (std::vector<std::string>{"glitter", "stone"}));

    // Every pixel: the coverages of the objects, and of the materials, add up to its alpha (the
    // squares are all the camera sees); ranks come in order of coverage.
    int shared = 0;
    for (int y = 0; y < f.height; ++y)
        for (int x = 0; x < f.width; ++x)
            for (const auto* kind : {"CryptoObject", "CryptoMaterial"}) {
                const auto ids = ids_at(f, kind, manifests.at(kind), x, y);
                float sum = 0.0f;
                for (std::size_t r = 0; r < ids.size(); ++r) {
                    sum += ids[r].second;
                    if (r > 0) {
                        EXPECT_LE(ids[r].second, ids[r - 1].second);
                    }
                }
                // Coverages are counts of 16 samples: exact in float.
                ASSERT_NEAR(sum, f.at("A", x, y), 1e-6f) << kind << " at " << x << "," << y;
                shared += ids.size() > 1;
            }
    EXPECT_GT(shared, 10) << "the squares' edges are shared with the background and each other";

    // The middle is the hero in its glitter; up and to the right, the slab in stone shows; the
    // third square (down left) is named by its mesh file.
    using Ids = std::vector<std::pair<std::string, float>>;
    EXPECT_EQ(ids_at(f, "CryptoObject", objects, 24, 16), (Ids{{"hero", 1.0f}}));
    EXPECT_EQ(ids_at(f, "CryptoMaterial", materials, 24, 16), (Ids{{"glitter", 1.0f}}));
    EXPECT_EQ(ids_at(f, "CryptoObject", objects, 32, 12), (Ids{{"slab", 1.0f}}));
    EXPECT_EQ(ids_at(f, "CryptoMaterial", materials, 32, 12), (Ids{{"stone", 1.0f}}));
    EXPECT_EQ(ids_at(f, "CryptoObject", objects, 12, 22), (Ids{{"plane", 1.0f}}));
}

/** A floor seen from straight above, lit by a point light up and to the left (-x), and a small
 *  square "blocker" 0.5 m over the floor's middle: its shadow falls 0.5 m to the right (+x), on
 *  pixel (43, 32) of the 64 x 64 image; pixel (10, 32) is floor in the light. */
std::string catcher_scene(bool catcher) {
    return fmt::format(R"(
[render]
width = 64
height = 64
spp = 16
max_depth = 3
filter = "box"
transparent_background = true
working_space = "lin_rec709"
[camera]
position = [0, 4, 0]
look_at = [0, 0, 0]
up = [0, 0, -1]
fov = 40
[[material]]
name = "ground"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.5 }}
shadow_catcher = {}
[[material]]
name = "paint"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.8 }}
[[object]]
name = "floor"
mesh = "{}/meshes/plane.ply"
material = "ground"
scale = 2
[[object]]
name = "blocker"
mesh = "{}/meshes/plane.ply"
material = "paint"
translate = [0, 0.5, 0]
scale = 0.15
[[light]]
type = "point"
position = [-1.5, 2, 0]
intensity = 5
)",
                       catcher, test::asset_dir(), test::asset_dir());
}

FrameResult render_catcher(const test::TempDir& dir, bool catcher) {
    { std::ofstream(dir.file("catcher.toml")) << catcher_scene(catcher); }
    FrameRequest req;
    req.scene = dir.file("catcher.toml");
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.layers = true;
    req.options.background_apart = true;
    return render_frame(req);
}

TEST(Compositing, AShadowCatcherKeepsOnlyTheShadowAsAlpha) {
    test::TempDir dir("shadow_catcher");
    const FrameResult with = render_catcher(dir, true);
    const FrameResult without = render_catcher(dir, false);
    const auto& n = with.layer_names;
    const std::size_t lc = n.size();
    const auto index = [&](const std::string& name) {
        return static_cast<std::size_t>(std::find(n.begin(), n.end(), name) - n.begin());
    };
    ASSERT_LT(index("shadow"), lc) << "a scene with a shadow catcher has a shadow matte";
    const auto layer = [&](const std::string& name, std::size_t x, std::size_t y) {
        return with.layers[(y * with.width + x) * lc + index(name)];
    };
    const auto red = [](const FrameResult& r, std::size_t x, std::size_t y) {
        return r.image[3 * (y * r.width + x)];
    };
    // In the blocker's shadow: every next-event query is blocked (one point light: no noise),
    // so the floor there is opaque shadow, and shows no light of its own.
    EXPECT_EQ(layer("shadow", 43, 32), 1.0f);
    EXPECT_EQ(layer("A", 43, 32), 1.0f);
    EXPECT_LT(red(with, 43, 32), 0.01f);
    // In the light: no shadow, fully transparent; the floor's own light is the plate's, gone
    // from the beauty but for what the blocker reflects onto it.
    EXPECT_EQ(layer("shadow", 10, 32), 0.0f);
    EXPECT_EQ(layer("A", 10, 32), 0.0f);
    EXPECT_GT(red(without, 10, 32), 0.05f) << "an ordinary floor is lit there";
    EXPECT_LT(red(with, 10, 32), 0.05f * red(without, 10, 32));
    // The blocker itself is untouched: opaque and lit as without a catcher, bit for bit.
    EXPECT_EQ(layer("A", 32, 32), 1.0f);
    EXPECT_EQ(layer("shadow", 32, 32), 0.0f);
    EXPECT_EQ(red(with, 32, 32), red(without, 32, 32));
    // Without a catcher the floor is opaque everywhere and no matte is written.
    EXPECT_EQ(std::find(without.layer_names.begin(), without.layer_names.end(), "shadow"),
              without.layer_names.end());
}

}  // namespace
}  // namespace spangle::test_compositing
