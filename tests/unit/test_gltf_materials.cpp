// The glTF reader's materials, animations, errors and containers: metallic-roughness and its
// extensions onto the smooth plugin, SPANGLE_materials_flakes onto the flake plugin, embedded
// images as cached files, node animations as matrix keys, errors at the JSON's line:col, and
// .glb and external .bin files read as the same scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "desc_support.h"
#include "gltf_writer.h"
#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/gltf/gltf_textures.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "scene/toml_scene_writer.h"
#include "scene_request.h"
#include "test_support.h"

namespace spangle::test_gltf_materials {
namespace {

using test::GltfWriter;
using test::has_note;
namespace fs = std::filesystem;

/** The bytes of a file. */
std::string bytes_of(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/** A unit quad's mesh JSON with material `material`. */
std::string quad_mesh(GltfWriter& w, int material) {
    const int p = w.floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, "VEC3", 3);
    const int uv = w.floats({0, 1, 1, 1, 1, 0, 0, 0}, "VEC2", 2);
    const int i = w.u16({0, 1, 2, 0, 2, 3});
    return fmt::format(
        R"({{"primitives":[{{"attributes":{{"POSITION":{},"TEXCOORD_0":{}}},"indices":{},"material":{}}}]}})",
        p, uv, i, material);
}

/** m's parameter `name` (throws when m has none). */
const ParamDesc& param_of(const MaterialDesc& m, const std::string& name) {
    for (const ParamDesc& p : m.params)
        if (p.name == name) return p;
    throw std::runtime_error("material " + m.name + " has no parameter " + name);
}

/** Whether m has a parameter `name`. */
bool has_param(const MaterialDesc& m, const std::string& name) {
    for (const ParamDesc& p : m.params)
        if (p.name == name) return true;
    return false;
}

/** Sets $SPANGLE_TEXTURE_CACHE to `dir` for the test's life. */
struct CacheEnv {
    explicit CacheEnv(const std::string& dir) { ::setenv("SPANGLE_TEXTURE_CACHE", dir.c_str(), 1); }
    ~CacheEnv() { ::unsetenv("SPANGLE_TEXTURE_CACHE"); }
    CacheEnv(const CacheEnv&) = delete;
    CacheEnv& operator=(const CacheEnv&) = delete;
};

/** A scene of nine quads, one per material, using every material feature the reader reads. */
std::string material_body(GltfWriter& w, const std::string& png) {
    const int image_view = w.view(png.data(), png.size());
    std::string meshes, nodes;
    for (int m = 0; m < 9; ++m) {
        if (m) meshes += ',';
        meshes += quad_mesh(w, m);
        nodes += fmt::format(R"({}{{"mesh":{}}})", m ? "," : "", m);
    }
    const std::string tt =
        R"("extensions":{"KHR_texture_transform":{"offset":[0.5,0.25],"rotation":0,"scale":[2,4]}})";
    return fmt::format(
        R"("extensionsUsed":["KHR_texture_transform","KHR_materials_clearcoat","KHR_materials_ior","KHR_materials_specular","KHR_materials_transmission","KHR_materials_emissive_strength","KHR_materials_iridescence","SPANGLE_materials_flakes","KHR_materials_anisotropy","EXT_lights_image_based"],)"
        R"("images":[{{"bufferView":{},"mimeType":"image/png"}},{{"uri":"data:image/png;base64,{}"}}],)"
        R"("samplers":[{{"wrapS":33071,"wrapT":33071,"magFilter":9728}},{{"wrapS":33648,"wrapT":10497,"magFilter":9729}}],)"
        R"("textures":[{{"source":0,"sampler":0}},{{"source":1,"sampler":1}}],)"
        R"("materials":[)"
        // 0: factors only.
        R"({{"name":"Paint","pbrMetallicRoughness":{{"baseColorFactor":[0.8,0.2,0.1,1],"metallicFactor":0.25,"roughnessFactor":0.5}}}},)"
        // 1: every texture, with a transform, a normal map, occlusion and emission.
        R"({{"name":"Textured","pbrMetallicRoughness":{{"baseColorTexture":{{"index":0,{}}},"baseColorFactor":[0.5,0.5,0.5,1],)"
        R"("metallicRoughnessTexture":{{"index":1}}}},"normalTexture":{{"index":0,"scale":0.5}},)"
        R"("occlusionTexture":{{"index":0}},"emissiveFactor":[1,0.5,0],"doubleSided":true,)"
        R"("extensions":{{"KHR_materials_emissive_strength":{{"emissiveStrength":4}}}}}},)"
        // 2: clear coat, ior, specular.
        R"({{"name":"Coated","extensions":{{"KHR_materials_clearcoat":{{"clearcoatFactor":0.75,"clearcoatRoughnessFactor":0.1,"clearcoatNormalTexture":{{"index":0}}}},)"
        R"("KHR_materials_ior":{{"ior":1.8}},"KHR_materials_specular":{{"specularFactor":0.5,"specularColorFactor":[1,0.9,0.8],"specularTexture":{{"index":0}}}}}}}},)"
        // 3: transmission onto the dielectric.
        R"({{"name":"Glass","pbrMetallicRoughness":{{"roughnessFactor":0.3,"metallicFactor":0}},"extensions":{{"KHR_materials_transmission":{{"transmissionFactor":1}},"KHR_materials_ior":{{"ior":1.33}}}}}},)"
        // 4: iridescence and sheen (not carried), alpha blending.
        R"({{"name":"Bubble","alphaMode":"BLEND","extensions":{{"KHR_materials_iridescence":{{"iridescenceFactor":1}},"KHR_materials_anisotropy":{{}}}}}},)"
        // 5: flakes with every kind of value; base colour and coat from the core material.
        R"({{"name":"CarPaint","pbrMetallicRoughness":{{"baseColorFactor":[0.1,0.02,0.02,1]}},)"
        R"("extensions":{{"KHR_materials_clearcoat":{{"clearcoatFactor":1,"clearcoatRoughnessFactor":0.2}},)"
        R"("SPANGLE_materials_flakes":{{"density":150000,"flake_roughness":0.2,"seed":7,"shadowing":false,)"
        R"("fresnel":"schlick","flake_f0":0.8,"flake_color":[1,0.9,0.7],"flake_weight":{{"index":1,"scale":0.5}}}}}}}},)"
        // 6 and 7: two materials with one name; 8: no name.
        R"({{"name":"Twin","alphaMode":"MASK"}},{{"name":"Twin"}},{{}}],)"
        R"("nodes":[{}],"meshes":[{}])",
        image_view, test::base64(png), tt, nodes, meshes);
}

TEST(GltfMaterials, MetallicRoughnessAndItsExtensionsMapOntoTheSmoothAndFlakePlugins) {
    test::TempDir dir("gltf_materials");
    CacheEnv cache(dir.file("cache"));
    const std::string png = bytes_of(test::test_dir() + "/scenes/textures/roughness_ramp.png");
    GltfWriter w;
    w.write_gltf(dir.file("mat.gltf"), material_body(w, png));
    const SceneDescription d = read_gltf_scene(dir.file("mat.gltf"), {});
    ASSERT_EQ(d.materials.size(), 9u);
    const MaterialDesc& paint = d.materials[0];
    EXPECT_EQ(paint.name, "Paint");
    EXPECT_EQ(paint.plugin, "smooth");
    EXPECT_EQ(paint.model, "metal_rough");
    EXPECT_EQ(param_of(paint, "base_color").kind, ParamDesc::Kind::Color);
    EXPECT_EQ(param_of(paint, "base_color").color.space, "lin_rec709");  // glTF factors are linear
    EXPECT_FLOAT_EQ(param_of(paint, "base_color").color.rgb.y, 0.2f);
    EXPECT_EQ(param_of(paint, "metallic").number, 0.25);
    EXPECT_EQ(param_of(paint, "roughness").number, 0.5);

    const MaterialDesc& tex = d.materials[1];
    const ParamDesc& base = param_of(tex, "base_color");
    ASSERT_EQ(base.kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(base.texture.space, "srgb_texture");  // colour textures are sRGB-encoded
    EXPECT_EQ(base.texture.scale[0], 0.5f);         // times baseColorFactor
    EXPECT_EQ(base.texture.wrap, 1);                // CLAMP_TO_EDGE
    EXPECT_EQ(base.texture.filter, 2);              // magFilter NEAREST: closest
    // KHR_texture_transform, offset (0.5, 0.25), scale (2, 4), in Spangle's v = 1 - t:
    // s = 2 u + 0.5 and 1 - t = 1 - (4 (1 - v) + 0.25) = 4 v - 3.25.
    const float want[6] = {2, 0, 0.5f, 0, 4, -3.25f};
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(base.texture.uv[k], want[k], 1e-6f) << k;
    const ParamDesc& mr = param_of(tex, "metallic_roughness");
    ASSERT_EQ(mr.kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(mr.texture.space, "raw");  // data
    EXPECT_EQ(mr.texture.wrap, 3);       // MIRRORED_REPEAT along s
    EXPECT_EQ(mr.texture.wrap_t, 0);     // REPEAT along t (it was noted and wrapped as s)
    EXPECT_EQ(mr.texture.filter, 0);     // magFilter LINEAR: trilinear
    EXPECT_FALSE(has_note(d, "wraps s and t differently"));
    ASSERT_EQ(tex.maps.size(), 1u);
    EXPECT_EQ(tex.maps[0].name, "normal_map");
    EXPECT_EQ(tex.maps[0].texture.amount, 0.5f);
    EXPECT_EQ(tex.maps[0].texture.space, "raw");
    EXPECT_TRUE(has_note(d, "occlusionTexture is ignored"));
    // The embedded image (a buffer view) and the data URI of the same bytes are one file in the
    // cache, named by the bytes' hash, holding those bytes.
    EXPECT_EQ(base.texture.path, mr.texture.path);
    EXPECT_EQ(fs::path(base.texture.path).parent_path(),
              fs::path(dir.file("cache")) / "gltf-images");
    EXPECT_EQ(bytes_of(base.texture.path), png);
    // --texture-cache names the folder (it was ignored for embedded images: a farm node with a
    // read-only home failed to render).
    SceneReadOptions to_cache;
    to_cache.texture_cache = dir.file("chosen");
    const SceneDescription chosen = read_gltf_scene(dir.file("mat.gltf"), to_cache);
    EXPECT_EQ(fs::path(param_of(chosen.materials[1], "base_color").texture.path).parent_path(),
              fs::path(dir.file("chosen")) / "gltf-images");

    const MaterialDesc& coat = d.materials[2];
    EXPECT_EQ(param_of(coat, "clearcoat").number, 0.75);
    EXPECT_NEAR(param_of(coat, "clearcoat_roughness").number, 0.1, 1e-12);
    EXPECT_NEAR(param_of(coat, "ior").number, 1.8, 1e-12);
    EXPECT_EQ(param_of(coat, "specular").number, 0.5);
    EXPECT_FLOAT_EQ(param_of(coat, "specular_color").color.rgb.z, 0.8f);
    EXPECT_TRUE(has_note(d, "specularTexture (its alpha channel) is dropped"));
    EXPECT_TRUE(has_note(d, "clearcoatNormalTexture is dropped"));

    const MaterialDesc& glass = d.materials[3];
    EXPECT_EQ(glass.model, "dielectric");
    EXPECT_NEAR(param_of(glass, "roughness").number, 0.09, 1e-12);  // alpha = roughness^2
    EXPECT_NEAR(param_of(glass, "ior").number, 1.33, 1e-12);
    EXPECT_EQ(param_of(glass, "multiscatter").number, 1.0) << "rough glass keeps its light";

    EXPECT_TRUE(has_note(d, "KHR_materials_iridescence is dropped"));
    EXPECT_TRUE(has_note(d, "material extension KHR_materials_anisotropy is not read"));
    // BLEND is a cut-out by chance (noted: no refraction, no blending order); MASK is a cut-out
    // at alphaCutoff, but Twin's factor alpha (1) passes it whole: nothing to cut.
    EXPECT_TRUE(has_note(d, "alphaMode BLEND is drawn as a cut-out"));
    EXPECT_FALSE(d.materials[4].alpha) << "alpha 1 by chance is opaque";
    EXPECT_FALSE(d.materials[6].alpha);
    EXPECT_FALSE(has_note(d, "alphaMode MASK"));
    EXPECT_TRUE(has_note(d, "doubleSided emissive material emits from its front faces only"));
    int aniso = 0;  // one note, at the material, not another for extensionsUsed
    for (const std::string& n : d.notes)
        aniso += n.find("KHR_materials_anisotropy") != std::string::npos;
    EXPECT_EQ(aniso, 1);
    EXPECT_TRUE(has_note(d, "extension EXT_lights_image_based is not read"));

    const MaterialDesc& flakes = d.materials[5];
    EXPECT_EQ(flakes.plugin, "flake");
    EXPECT_EQ(param_of(flakes, "density").number, 150000.0);
    EXPECT_TRUE(param_of(flakes, "seed").is_integer);
    EXPECT_EQ(param_of(flakes, "shadowing").kind, ParamDesc::Kind::Bool);
    EXPECT_EQ(param_of(flakes, "fresnel").text, "schlick");
    EXPECT_EQ(param_of(flakes, "flake_color").kind, ParamDesc::Kind::Color);
    EXPECT_EQ(param_of(flakes, "flake_weight").kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(param_of(flakes, "flake_weight").texture.space, "raw");
    EXPECT_EQ(param_of(flakes, "flake_weight").texture.scale[0], 0.5f);
    EXPECT_FLOAT_EQ(param_of(flakes, "base_color").color.rgb.x, 0.1f);
    EXPECT_EQ(param_of(flakes, "coat").number, 1.0);
    EXPECT_NEAR(param_of(flakes, "coat_roughness").number, 0.04, 1e-12);
    EXPECT_FALSE(has_param(flakes, "metallic"));

    EXPECT_EQ(d.materials[6].name, "Twin");
    EXPECT_EQ(d.materials[7].name, "Twin_2");
    EXPECT_EQ(d.materials[8].name, "material_8");

    // Emission: emissiveFactor x emissiveStrength, linear Rec.709, on the objects using it.
    ASSERT_TRUE(d.objects[1].emission);
    EXPECT_EQ(d.objects[1].emission->color.rgb.y, 0.5f);
    EXPECT_EQ(d.objects[1].emission->intensity, 4.0);
    EXPECT_FALSE(d.objects[0].emission);
    // Each parameter is blamed on its place in the JSON: line 1, the column of its value.
    EXPECT_EQ(param_of(paint, "metallic").loc.line, 1);
    EXPECT_GT(param_of(paint, "metallic").loc.column, 1);
}

TEST(GltfMaterials, TransmissionTakesTheBaseColourAndTheVolumesAttenuation) {
    // Coloured glass: the base colour is the dielectric's transmission_color; with
    // KHR_materials_volume, Beer-Lambert over thicknessFactor deepens it: c^(thickness /
    // distance), here 0.25^(1 / 2) = 0.5 on red and green.
    test::TempDir dir("gltf_tint");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, 0);
    w.write_gltf(
        dir.file("glass.gltf"),
        fmt::format(
            R"("materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.9,0.5,0.2,1]}},)"
            R"("extensions":{{"KHR_materials_transmission":{{"transmissionFactor":1}},)"
            R"("KHR_materials_volume":{{"thicknessFactor":1,"attenuationDistance":2,)"
            R"("attenuationColor":[0.25,0.25,1]}}}}}}],"meshes":[{}],)"
            R"("nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0)",
            mesh));
    const SceneDescription d = read_gltf_scene(dir.file("glass.gltf"), {});
    ASSERT_EQ(d.materials.size(), 1u);
    const MaterialDesc& glass = d.materials[0];
    EXPECT_EQ(glass.model, "dielectric");
    const ParamDesc& tint = param_of(glass, "transmission_color");
    EXPECT_NEAR(tint.color.rgb.x, 0.45f, 1e-6f);
    EXPECT_NEAR(tint.color.rgb.y, 0.25f, 1e-6f);
    EXPECT_NEAR(tint.color.rgb.z, 0.2f, 1e-6f);
    EXPECT_EQ(tint.color.space, "lin_rec709");
    EXPECT_TRUE(has_note(d, "attenuation is approximated"));
    for (const std::string& n : d.notes) {
        EXPECT_EQ(n.find("is not read"), std::string::npos) << n;
        EXPECT_EQ(n.find("base colour"), std::string::npos) << n;
    }
}

TEST(GltfMaterials, SpecularGlossinessBecomesMetalRough) {
    // KHR_materials_pbrSpecularGlossiness (older exporters, Sketchfab): it rendered as glTF's
    // default material, a white rough metal. Material 0: factors alone, a dim specular (F0
    // 0.04: a dielectric of index 1.5, specular_color 1); material 1: textures (green, alpha 0
    // on the left and 1 on the right) as diffuse and specular-glossiness, specular factor
    // [1, 0.8, 0.5], glossiness 0.8.
    test::TempDir dir("gltf_specgloss");
    CacheEnv cache(dir.file("cache"));
    const std::string png = bytes_of(test::test_dir() + "/scenes/textures/half_alpha.png");
    GltfWriter w;
    const int view = w.view(png.data(), png.size());
    const std::string mesh = quad_mesh(w, 0), mesh1 = quad_mesh(w, 1);
    const std::string sg = "KHR_materials_pbrSpecularGlossiness";
    w.write_gltf(
        dir.file("sg.gltf"),
        fmt::format(R"("materials":[{{"extensions":{{"{0}":{{"diffuseFactor":[0.5,0.25,0.125,1],)"
                    R"("specularFactor":[0.04,0.04,0.04],"glossinessFactor":0.7}}}}}},)"
                    R"({{"extensions":{{"{0}":{{"diffuseTexture":{{"index":0}},)"
                    R"("specularFactor":[1,0.8,0.5],"glossinessFactor":0.8,)"
                    R"("specularGlossinessTexture":{{"index":0}}}}}}}}],)"
                    R"("images":[{{"bufferView":{1},"mimeType":"image/png"}}],)"
                    R"("textures":[{{"source":0}}],"meshes":[{2},{3}],)"
                    R"("nodes":[{{"mesh":0}},{{"mesh":1}}],"scenes":[{{"nodes":[0,1]}}],"scene":0)",
                    sg, view, mesh, mesh1));
    SceneDescription d = read_gltf_scene(dir.file("sg.gltf"), {});
    ASSERT_EQ(d.materials.size(), 2u);
    for (const std::string& n : d.notes) EXPECT_EQ(n.find(sg), std::string::npos) << n;
    const MaterialDesc& dim = d.materials[0];
    EXPECT_EQ(dim.model, "metal_rough");
    EXPECT_EQ(param_of(dim, "metallic").number, 0.0);
    EXPECT_NEAR(param_of(dim, "ior").number, 1.5, 1e-9);
    EXPECT_NEAR(param_of(dim, "specular_color").color.rgb.x, 1.0f, 1e-5f);
    EXPECT_NEAR(param_of(dim, "roughness").number, 0.3, 1e-9);
    EXPECT_FLOAT_EQ(param_of(dim, "base_color").color.rgb.y, 0.25f);
    // Textured: converted texel by texel to metallic-roughness (the converter's metalness
    // solve), a linear base colour image and a packed one (G roughness, B metallic), 16 bits.
    const MaterialDesc& textured = d.materials[1];
    EXPECT_EQ(param_of(textured, "metallic").number, 1.0);
    EXPECT_EQ(param_of(textured, "roughness").number, 1.0);
    const ParamDesc& base = param_of(textured, "base_color");
    ASSERT_EQ(base.kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(base.texture.space.value_or(""), "lin_rec709");
    const ParamDesc& packed = param_of(textured, "metallic_roughness");
    ASSERT_EQ(packed.kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(packed.texture.space.value_or(""), "raw");
    // 16 x 16 texels of 3 x 16 bits: on the left glossiness 0 (roughness 1), on the right 0.8
    // (roughness 0.2); the texels are sRGB (40, 160, 60), the specular that times [1, 0.8, 0.5].
    const std::string ppm = bytes_of(packed.texture.path);
    const std::string header = "P6\n16 16\n65535\n";
    ASSERT_EQ(ppm.substr(0, header.size()), header);
    ASSERT_EQ(ppm.size(), header.size() + 6 * 16 * 16);
    const auto sample = [&](int x, int y, int c) {
        const std::size_t at = header.size() + 2 * static_cast<std::size_t>(3 * (16 * y + x) + c);
        return (static_cast<uint8_t>(ppm[at]) * 256 + static_cast<uint8_t>(ppm[at + 1])) / 65535.0;
    };
    EXPECT_NEAR(sample(2, 5, 1), 1.0, 1e-4);
    EXPECT_NEAR(sample(13, 5, 1), 0.2, 1e-4);
    const Vec3 texel{static_cast<float>(srgb_to_linear(40 / 255.0)),
                     static_cast<float>(srgb_to_linear(160 / 255.0)),
                     static_cast<float>(srgb_to_linear(60 / 255.0))};
    double metallic = 0.0;
    Vec3 want;
    gltf::spec_gloss_to_metal(texel, texel * Vec3(1.0f, 0.8f, 0.5f), metallic, want);
    EXPECT_NEAR(sample(13, 5, 2), metallic, 1e-4);
    EXPECT_GT(metallic, 0.2) << "a bright specular: partly metal";
    const std::string bppm = bytes_of(base.texture.path);
    ASSERT_EQ(bppm.size(), ppm.size());
    const std::size_t g = header.size() + 2 * static_cast<std::size_t>(3 * (16 * 5 + 13) + 1);
    EXPECT_NEAR((static_cast<uint8_t>(bppm[g]) * 256 + static_cast<uint8_t>(bppm[g + 1])) / 65535.0,
                want.y, 1e-4);
    // Both are accepted by the plugin and render finite pixels.
    d.render.width = 16;
    d.render.height = 8;
    d.render.spp = 1;
    RenderOptions options;
    options.threads = 2;
    options.texture_cache = dir.file("textures");
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    ASSERT_NO_THROW(session.load(d));
    session.render();
    for (float v : session.result().image) ASSERT_TRUE(std::isfinite(v));
}

TEST(GltfMaterials, ASpecularGlossinessMetalIsAMetalAndBadValuesAreErrors) {
    // Chrome (white specular, black diffuse, glossiness 0.3): the converter's metalness solve
    // gives metallic 1, base colour white, so metal_rough keeps the light between its
    // microfacets (as a dielectric of F0 1 it rendered 30% dark at this roughness). A file
    // that requires the extension is read; wrong values are errors at their place.
    test::TempDir dir("gltf_specgloss_metal");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, 0);
    const auto file = [&](const std::string& ext) {
        return fmt::format(
            R"("extensionsUsed":["KHR_materials_pbrSpecularGlossiness"],)"
            R"("extensionsRequired":["KHR_materials_pbrSpecularGlossiness"],)"
            R"("materials":[{{"extensions":{{"KHR_materials_pbrSpecularGlossiness":{}}}}}],)"
            R"("meshes":[{}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0)",
            ext, mesh);
    };
    w.write_gltf(dir.file("chrome.gltf"),
                 file(R"({"diffuseFactor":[0,0,0,1],"specularFactor":[1,1,1],)"
                      R"("glossinessFactor":0.3})"));
    const SceneDescription d = read_gltf_scene(dir.file("chrome.gltf"), {});
    const MaterialDesc& m = d.materials.at(0);
    EXPECT_NEAR(param_of(m, "metallic").number, 1.0, 1e-9);
    EXPECT_NEAR(param_of(m, "roughness").number, 0.7, 1e-9);
    EXPECT_FLOAT_EQ(param_of(m, "base_color").color.rgb.y, 1.0f);
    for (const std::string& bad : {std::string(R"({"specularFactor":[1,1,1,1]})"),
                                   std::string(R"({"diffuseFactor":[0.5,0.5,0.5]})"),
                                   std::string(R"({"glossinessFactor":"high"})")}) {
        SCOPED_TRACE(bad);
        w.write_gltf(dir.file("bad.gltf"), file(bad));
        try {
            read_gltf_scene(dir.file("bad.gltf"), {});
            ADD_FAILURE() << "read";
        } catch (const SpangleError& e) {
            EXPECT_NE(std::string(e.what()).find("bad.gltf:1:"), std::string::npos) << e.what();
        }
    }
}

/** Renders `d` at 8 x 8 from `position` towards `look_at` (vertical fov in degrees) with the
 *  texture cache in `dir`; the middle pixel (4, 4), in the working space and in linear Rec.709,
 *  and the working space's name. */
struct MiddlePixel {
    Vec3 working, rec709;
    std::string working_space;
};
MiddlePixel middle_pixel(SceneDescription d, const test::TempDir& dir, Vec3 position, Vec3 look_at,
                         double fov, uint32_t spp) {
    d.render.width = 8;
    d.render.height = 8;
    d.render.spp = spp;
    d.camera.position = position;
    d.camera.look_at = look_at;
    d.camera.fov_deg = fov;
    RenderOptions options;
    options.threads = 2;
    options.texture_cache = dir.file("textures");
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(d);
    session.render();
    const std::vector<float>& img = session.result().image;
    const std::size_t mid = (4 * 8 + 4) * 3;
    float px[3] = {img[mid], img[mid + 1], img[mid + 2]};
    MiddlePixel out{{px[0], px[1], px[2]}, {}, session.color().working_space()};
    session.color().convert(out.working_space, "lin_rec709", px, 1);
    out.rec709 = Vec3(px[0], px[1], px[2]);
    return out;
}

TEST(GltfMaterials, AWebPTextureIsRead) {
    // EXT_texture_webp (glTF-Transform's and web exporters' compressed textures), required and
    // without a PNG fallback: its image is the base colour texture (it was dropped, the factor
    // standing in).
    test::TempDir dir("gltf_webp");
    CacheEnv cache(dir.file("cache"));
    // An 8 x 8 pure red WebP (lossy, as oiiotool writes it).
    const std::string webp = bytes_of(test::test_dir() + "/scenes/textures/red.webp");
    ASSERT_EQ(webp.substr(8, 4), "WEBP");
    GltfWriter w;
    const int view = w.view(webp.data(), webp.size());
    const std::string mesh = quad_mesh(w, 0);
    w.write_gltf(
        dir.file("webp.gltf"),
        fmt::format(R"("extensionsUsed":["EXT_texture_webp"],)"
                    R"("extensionsRequired":["EXT_texture_webp"],)"
                    R"("materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}},)"
                    R"("metallicFactor":0}}}}],)"
                    R"("images":[{{"bufferView":{},"mimeType":"image/webp"}}],)"
                    R"("textures":[{{"extensions":{{"EXT_texture_webp":{{"source":0}}}}}}],)"
                    R"("meshes":[{}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0)",
                    view, mesh));
    SceneDescription d = read_gltf_scene(dir.file("webp.gltf"), {});
    const ParamDesc& base = param_of(d.materials.at(0), "base_color");
    ASSERT_EQ(base.kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(std::filesystem::path(base.texture.path).extension(), ".webp");
    EXPECT_EQ(bytes_of(base.texture.path), webp);
    for (const std::string& n : d.notes) EXPECT_EQ(n.find("WebP"), std::string::npos) << n;
    // Rendered: the quad is red.
    const Vec3 px = middle_pixel(d, dir, {0.5f, 0.5f, 3}, {0.5f, 0.5f, 0}, 8, 4).working;
    EXPECT_GT(px.x, 5.0f * px.y) << "red";
    EXPECT_GT(px.x, 5.0f * px.z) << "red";
}

TEST(GltfMaterials, SheenBecomesTheSheenLayerOfMetalRough) {
    test::TempDir dir("gltf_sheen");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, 0);
    w.write_gltf(
        dir.file("velvet.gltf"),
        fmt::format(R"("extensionsUsed":["KHR_materials_sheen"],)"
                    R"("extensionsRequired":["KHR_materials_sheen"],)"
                    R"("materials":[{{"extensions":{{"KHR_materials_sheen":{{)"
                    R"("sheenColorFactor":[0.8,0.2,0.3],"sheenRoughnessFactor":0.4}}}}}}],)"
                    R"("meshes":[{}],"nodes":[{{"mesh":0}}],)"
                    R"("scenes":[{{"nodes":[0]}}],"scene":0)",
                    mesh));
    const SceneDescription d = read_gltf_scene(dir.file("velvet.gltf"), {});
    const MaterialDesc& m = d.materials.at(0);
    EXPECT_EQ(m.model, "metal_rough");
    EXPECT_FLOAT_EQ(param_of(m, "sheen_color").color.rgb.y, 0.2f);
    EXPECT_NEAR(param_of(m, "sheen_roughness").number, 0.4, 1e-12);
    for (const std::string& n : d.notes)
        EXPECT_EQ(n.find("KHR_materials_sheen"), std::string::npos);
}

TEST(GltfMaterials, AnUnlitMaterialShowsItsBaseColourWhateverTheLight) {
    // KHR_materials_unlit (scans, baked lighting): the base colour is what the camera sees. It
    // is emitted (both faces) over a black surface, so a frame-filling unlit quad renders its
    // base colour, converted to the working space, with or without the studio light.
    test::TempDir dir("gltf_flat_colour");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, 0);
    w.write_gltf(dir.file("unlit.gltf"),
                 fmt::format(R"("materials":[{{"pbrMetallicRoughness":{{)"
                             R"("baseColorFactor":[0.6,0.3,0.1,1]}},)"
                             R"("extensions":{{"KHR_materials_unlit":{{}}}}}}],"meshes":[{}],)"
                             R"("nodes":[{{"mesh":0,"translation":[-0.5,-0.5,0]}}],)"
                             R"("cameras":[{{"type":"perspective","perspective":)"
                             R"({{"yfov":0.2,"znear":0.01}}}}],)"
                             R"("scenes":[{{"nodes":[0]}}],"scene":0)",
                             mesh));
    SceneDescription d = read_gltf_scene(dir.file("unlit.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    ASSERT_TRUE(d.objects[0].emission);
    EXPECT_TRUE(d.objects[0].emission->two_sided);
    EXPECT_FLOAT_EQ(d.objects[0].emission->color.rgb.x, 0.6f);
    const MaterialDesc& m = d.materials[0];
    EXPECT_EQ(m.model, "diffuse");
    EXPECT_EQ(param_of(m, "albedo").color.rgb.x, 0.0f);
    for (const std::string& n : d.notes)
        EXPECT_EQ(n.find("KHR_materials_unlit"), std::string::npos) << n;
    // Seen head-on from a default camera placed at +z by hand: the middle pixels are the
    // base colour.
    const MiddlePixel px = middle_pixel(d, dir, {0, 0, 3}, {0, 0, 0}, d.camera.fov_deg, 4);
    float want[3] = {0.6f, 0.3f, 0.1f};
    test::shipped_config().convert("lin_rec709", px.working_space, want, 1);
    EXPECT_NEAR(px.working.x, want[0], 2e-3f);
    EXPECT_NEAR(px.working.y, want[1], 2e-3f);
    EXPECT_NEAR(px.working.z, want[2], 2e-3f);
}

TEST(GltfMaterials, AFactorTimesATextureKeepsTheFactorsHue) {
    // glTF multiplies a factor and a texture in linear Rec.709; channel by channel in the
    // working space (ACEScg) an orange factor over a grey texture rendered red. Over the grey
    // ramp, the pixel's colour in Rec.709 is the factor's times a grey: red / green = 10, no
    // blue. For a material parameter (an unlit-looking diffuse base) and for emission (unlit).
    test::TempDir dir("gltf_factor_hue");
    CacheEnv cache(dir.file("cache"));
    std::ofstream(dir.file("ramp.png"), std::ios::binary)
        << bytes_of(test::test_dir() + "/scenes/textures/roughness_ramp.png");
    for (const bool unlit : {false, true}) {
        GltfWriter w;
        const std::string mesh = quad_mesh(w, 0);
        const std::string material =
            unlit ? R"("extensions":{"KHR_materials_unlit":{}})"
                  : R"("extensions":{"KHR_materials_specular":{"specularFactor":0}})";
        w.write_gltf(
            dir.file("hue.gltf"),
            fmt::format(R"("materials":[{{"pbrMetallicRoughness":{{)"
                        R"("baseColorFactor":[0.8,0.08,0,1],"metallicFactor":0,)"
                        R"("roughnessFactor":1,"baseColorTexture":{{"index":0}}}},{}}}],)"
                        R"("images":[{{"uri":"ramp.png"}}],"textures":[{{"source":0}}],)"
                        R"("meshes":[{}],"nodes":[{{"mesh":0,"translation":[-0.5,-0.5,0]}}],)"
                        R"("scenes":[{{"nodes":[0]}}],"scene":0)",
                        material, mesh));
        const Vec3 px = middle_pixel(read_gltf_scene(dir.file("hue.gltf"), {}), dir, {0, 0, 3},
                                     {0, 0, 0}, 5, 16)
                            .rec709;
        ASSERT_GT(px.x, 0.01f) << (unlit ? "unlit" : "lit");
        EXPECT_NEAR(px.x / px.y, 10.0f, 0.3f)
            << (unlit ? "unlit" : "lit") << ": " << px.x << " " << px.y << " " << px.z;
        EXPECT_LT(std::fabs(px.z), 0.01f * px.x) << (unlit ? "unlit" : "lit");
    }
}

TEST(GltfMaterials, EveryMaterialIsAcceptedByItsPluginAndRenders) {
    test::TempDir dir("gltf_materials_render");
    CacheEnv cache(dir.file("cache"));
    const std::string png = bytes_of(test::test_dir() + "/scenes/textures/roughness_ramp.png");
    GltfWriter w;
    w.write_gltf(dir.file("mat.gltf"), material_body(w, png));
    SceneDescription d = read_gltf_scene(dir.file("mat.gltf"), {});
    d.render.width = 16;
    d.render.height = 8;
    d.render.spp = 1;
    RenderOptions options;
    options.threads = 2;
    options.texture_cache = dir.file("textures");
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    ASSERT_NO_THROW(session.load(d)) << "a plugin refused a material the reader made";
    session.render();
    for (float v : session.result().image) ASSERT_TRUE(std::isfinite(v));
}

TEST(GltfMaterials, AnImageWrittenOnceIsNotWrittenAgain) {
    test::TempDir dir("gltf_image_once");
    CacheEnv cache(dir.file("cache"));
    const std::string png = bytes_of(test::test_dir() + "/scenes/textures/roughness_ramp.png");
    GltfWriter w;
    w.write_gltf(dir.file("mat.gltf"), material_body(w, png));
    const std::string file =
        param_of(read_gltf_scene(dir.file("mat.gltf"), {}).materials[1], "base_color").texture.path;
    const auto written = fs::last_write_time(file);
    const std::string again =
        param_of(read_gltf_scene(dir.file("mat.gltf"), {}).materials[1], "base_color").texture.path;
    EXPECT_EQ(again, file);
    EXPECT_EQ(fs::last_write_time(file), written);  // unchanged: the texture cache keeps its entry
}

/** Two nodes: a parent turning LINEAR about +y at t = 0, 1, 2 (0, 90, 180 degrees) and a child
 *  stepping from (0, 0, 1) to (1, 0, 1) at t = 0.5, 1.5 (STEP), and a third node animated by a
 *  CUBICSPLINE scale. */
std::string animated_body(GltfWriter& w) {
    const std::string mesh = quad_mesh(w, 0);
    const float s = std::sqrt(0.5f);
    const int t_turn = w.floats({0, 1, 2}, "SCALAR", 1);
    const int v_turn = w.floats({0, 0, 0, 1, 0, s, 0, s, 0, 1, 0, 0}, "VEC4", 4);
    const int t_step = w.floats({0.5f, 1.5f}, "SCALAR", 1);
    const int v_step = w.floats({0, 0, 1, 1, 0, 1}, "VEC3", 3);
    const int t_cubic = w.floats({0, 1}, "SCALAR", 1);
    const int v_cubic = w.floats({0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, 2, 2, 2, 0, 0, 0}, "VEC3", 3);
    return fmt::format(
        R"("materials":[{{}}],"meshes":[{}],)"
        R"("nodes":[{{"children":[1]}},{{"mesh":0,"translation":[0,0,1]}},{{"mesh":0}}],)"
        R"("animations":[{{"channels":[{{"sampler":0,"target":{{"node":0,"path":"rotation"}}}},)"
        R"({{"sampler":1,"target":{{"node":1,"path":"translation"}}}}],)"
        R"("samplers":[{{"input":{},"output":{}}},{{"input":{},"output":{},"interpolation":"STEP"}}]}},)"
        R"({{"channels":[{{"sampler":0,"target":{{"node":2,"path":"scale"}}}},{{"sampler":0,"target":{{"node":2,"path":"weights"}}}}],)"
        R"("samplers":[{{"input":{},"output":{},"interpolation":"CUBICSPLINE"}}]}}])",
        mesh, t_turn, v_turn, t_step, v_step, t_cubic, v_cubic);
}

// A card flip: a cube's x scale animated LINEAR from 1 to -1 over one second. At 0.5 s its
// placement is singular (the cube is a square of no thickness) and rays sent into its space made
// Embree assert: a crash on a real glTF (this test aborted before the fix). That instant now
// leaves the cube out: an object with no volume, its placement not invertible.
TEST(GltfAnimation, AScaleThroughZeroNeitherCrashesNorShowsTheFlatObject) {
    test::TempDir dir("gltf_flip");
    const auto write = [&](const std::string& name) {
        GltfWriter w;
        // A unit cube with a normal per face corner, as exporters write it.
        std::vector<float> cp, cn;
        std::vector<uint16_t> ci;
        for (int axis = 0; axis < 3; ++axis)
            for (const float side : {0.0f, 1.0f}) {
                const auto base = static_cast<uint16_t>(cp.size() / 3);
                for (int k = 0; k < 4; ++k) {
                    float q[3];
                    q[axis] = side;
                    q[(axis + 1) % 3] = static_cast<float>(k == 1 || k == 2);
                    q[(axis + 2) % 3] = static_cast<float>(k >= 2);
                    cp.insert(cp.end(), {q[0] - 0.5f, q[1] - 0.5f, q[2] - 0.5f});
                    float n[3] = {0, 0, 0};
                    n[axis] = side > 0.0f ? 1.0f : -1.0f;
                    cn.insert(cn.end(), {n[0], n[1], n[2]});
                }
                const bool flip = side == 0.0f;
                ci.insert(ci.end(), {base, static_cast<uint16_t>(base + (flip ? 2 : 1)),
                                     static_cast<uint16_t>(base + (flip ? 1 : 2)), base,
                                     static_cast<uint16_t>(base + (flip ? 3 : 2)),
                                     static_cast<uint16_t>(base + (flip ? 2 : 3))});
            }
        const int pa = w.floats(cp, "VEC3", 3), na = w.floats(cn, "VEC3", 3), ia = w.u16(ci);
        const std::string cube = fmt::format(
            R"({{"primitives":[{{"attributes":{{"POSITION":{},"NORMAL":{}}},"indices":{},"material":0}}]}})",
            pa, na, ia);
        const int t = w.floats({0, 1}, "SCALAR", 1);
        const int v = w.floats({1, 1, 1, -1, 1, 1}, "VEC3", 3);
        // No camera: the default framing looks at the cube from above and aside, as at the
        // real file that crashed.
        w.write_gltf(
            dir.file(name),
            fmt::format(
                R"("materials":[{{"pbrMetallicRoughness":{{"metallicFactor":0}}}}],"meshes":[{}],)"
                R"("nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0,)"
                R"("animations":[{{"channels":[{{"sampler":0,"target":{{"node":0,"path":"scale"}}}}],)"
                R"("samplers":[{{"input":{},"output":{}}}]}}])",
                cube, t, v));
        return dir.file(name);
    };
    const std::string flipping = write("flip.gltf");
    const auto render = [&](const std::string& path, double time) {
        FrameRequest req = test::quiet_request(path);
        req.options.threads = 2;
        req.options.width_override = 32;
        req.options.height_override = 24;
        req.options.spp_override = 4;
        req.time = time;
        return render_frame(req).image;
    };
    const auto finite = [](const std::vector<float>& img) {
        return std::all_of(img.begin(), img.end(), [](float x) { return std::isfinite(x); });
    };
    const std::vector<float> flat = render(flipping, 0.5);
    ASSERT_TRUE(finite(flat));
    const std::vector<float> half = render(flipping, 0.25);
    ASSERT_TRUE(finite(half));
    EXPECT_NE(half, flat) << "at scale 0.5 the cube shows, at 0 it is left out";
}

TEST(GltfSkin, ASkinnedMeshIsPlacedByItsJointNotItsNode) {
    // As Blender and Mixamo export a character: an "Armature" node (at x = 2, scale 0.01) with a
    // joint under it (at y = 100 in the armature's units: 1 m up), the skinned mesh's node at the
    // root with no transform of its own (the spec ignores it), and an inverse bind matrix that
    // undoes the joint's local offset. The mesh belongs at the armature: at x = 2, 1/100 size.
    test::TempDir dir("gltf_skin");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, 0);
    const int ibm = w.floats({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -100, 0, 1}, "MAT4", 16);
    w.write_gltf(dir.file("skin.gltf"),
                 fmt::format(R"("materials":[{{}}],"meshes":[{}],)"
                             R"("nodes":[{{"name":"Armature","translation":[2,0,0],)"
                             R"("scale":[0.01,0.01,0.01],"children":[1]}},)"
                             R"({{"name":"hips","translation":[0,100,0]}},)"
                             R"({{"name":"body","mesh":0,"skin":0}}],)"
                             R"("skins":[{{"joints":[1],"inverseBindMatrices":{}}}],)"
                             R"("scenes":[{{"nodes":[0,2]}}],"scene":0)",
                             mesh, ibm));
    const SceneDescription d = read_gltf_scene(dir.file("skin.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    ASSERT_TRUE(d.objects[0].placement.matrix);
    const Affine& m = *d.objects[0].placement.matrix;
    const Vec3 o = m.apply_point({0, 0, 0}), x = m.apply_point({1, 0, 0});
    EXPECT_NEAR(o.x, 2.0f, 1e-5f);
    EXPECT_NEAR(o.y, 0.0f, 1e-5f) << "the joint's offset is undone by its inverse bind matrix";
    EXPECT_NEAR(x.x - o.x, 0.01f, 1e-6f) << "the armature's scale applies";
    EXPECT_TRUE(has_note(d, "drawn rigidly, placed by the skin's first joint"));
}

TEST(GltfAnimation, NodeChannelsBecomeMatrixKeysAtTheUnionOfTheirTimes) {
    test::TempDir dir("gltf_anim");
    GltfWriter w;
    w.write_gltf(dir.file("anim.gltf"), animated_body(w));
    const SceneDescription d = read_gltf_scene(dir.file("anim.gltf"), {});
    ASSERT_EQ(d.objects.size(), 2u);
    const Keys<MatrixKey>& child = d.objects[0].matrix_keys;
    // The parent's 0, 1, 2 and the child's 0.5 and 1.5, the step at 1.5 with a key 1e-4 s before
    // it holding the previous value (before its first key a channel holds its first value); and,
    // as the parent's turn carries the child along an arc, a key every 3 degrees of that turn
    // (90 degrees a second: 1/30 s apart).
    std::vector<double> times;
    for (const MatrixKey& k : child.keys) times.push_back(k.time.seconds);
    for (const double t : {0.0, 0.5, 1.0, 1.5 - 1e-4, 1.5, 2.0})
        EXPECT_TRUE(std::any_of(times.begin(), times.end(),
                                [&](double k) { return std::fabs(k - t) < 1e-6; }))
            << "no key at " << t;
    for (std::size_t i = 1; i < times.size(); ++i)
        EXPECT_LE(times[i] - times[i - 1], 1.0 / 30.0 + 1e-6) << i;
    // The child's origin is the parent's turn R_y(90 t degrees) applied to its translation,
    // (0, 0, 1) until the step at 1.5 s and (1, 0, 1) from it: (x, 0, z) -> (x cos + z sin, 0,
    // z cos - x sin).
    for (std::size_t i = 0; i < times.size(); ++i) {
        const auto turn = static_cast<float>(times[i] * kPi / 2);
        const float x = times[i] >= 1.5 ? 1.0f : 0.0f;
        const Vec3 o = child.keys[i].matrix.apply_point({0, 0, 0});
        EXPECT_NEAR(o.x, x * std::cos(turn) + std::sin(turn), 1e-5f) << times[i];
        EXPECT_NEAR(o.z, std::cos(turn) - x * std::sin(turn), 1e-5f) << times[i];
    }
    // The cubic spline is sampled at its keys and three points between: at s = 0.5 the Hermite
    // value of 1 -> 2 with zero tangents is 1.5.
    const Keys<MatrixKey>& cubic = d.objects[1].matrix_keys;
    ASSERT_EQ(cubic.keys.size(), 5u);
    EXPECT_NEAR(cubic.keys[2].matrix.m[0][0], 1.5f, 1e-5f);
    EXPECT_TRUE(has_note(d, "CUBICSPLINE animation is approximated"));
    EXPECT_TRUE(has_note(d, "morph weights whose output is not SCALAR is dropped"));
    // 2 s at 24 fps: frames 1 to 49.
    EXPECT_EQ(d.render.frame_end, 49);
    // The builder turns the keys into motion; the scene is animated.
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo info = build_scene(d, color, registry, 1.0);
    EXPECT_TRUE(info.animated);
    const Vec3 o = info.object_to_world[0].apply_point({0, 0, 0});
    EXPECT_NEAR(o.x, 1.0f, 1e-4f);  // at t = 1 s, a key exactly
    EXPECT_NEAR(o.z, 0.0f, 1e-4f);
    // Between keys the child stays on its circle (it cut the chord between the parent's keys:
    // at 0.25 s, 0.92 of the radius from the axis).
    ecs::Registry between;
    const SceneInfo at = build_scene(d, color, between, 0.26);
    const Vec3 q = at.object_to_world[0].apply_point({0, 0, 0});
    EXPECT_NEAR(std::hypot(q.x, q.z), 1.0f, 4e-4f);
    EXPECT_NEAR(std::atan2(q.x, q.z), 0.26f * kPi / 2, 1e-3f);
}

/** The SpangleError message of reading `text` as a .gltf in `dir`. */
std::string error_of(const test::TempDir& dir, const std::string& text,
                     const char* name = "bad.gltf") {
    std::ofstream(dir.file(name), std::ios::binary) << text;
    try {
        read_gltf_scene(dir.file(name), {});
    } catch (const SpangleError& e) {
        return e.what();
    }
    return "no error";
}

TEST(GltfMaterials, ImageUrisWithASchemeAndAByteOrderMark) {
    // file:// names a path on this machine (it was looked for as "DIR/file:/..."); an https://
    // image is not fetched, said once at its URI, with no raw tinygltf line besides; a UTF-8
    // byte-order mark before the JSON is skipped ("unexpected character" at 1:1 before).
    test::TempDir dir("gltf_uris");
    const std::string ramp = test::test_dir() + "/scenes/textures/roughness_ramp.png";
    const auto write = [&](const std::string& file, const std::string& uri, bool bom) {
        GltfWriter w;
        const std::string mesh = quad_mesh(w, 0);
        w.write_gltf(dir.file(file),
                     fmt::format(R"("images":[{{"uri":"{}"}}],"textures":[{{"source":0}}],)"
                                 R"("materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":)"
                                 R"({{"index":0}}}}}}],"meshes":[{}],"nodes":[{{"mesh":0}}])",
                                 uri, mesh));
        if (!bom) return;
        const std::string text = bytes_of(dir.file(file));
        std::ofstream(dir.file(file), std::ios::binary) << "\xEF\xBB\xBF" << text;
    };
    write("file.gltf", "file://" + ramp, true);
    const SceneDescription f = read_gltf_scene(dir.file("file.gltf"), {});
    ASSERT_EQ(f.materials.size(), 1u);
    EXPECT_EQ(param_of(f.materials[0], "base_color").texture.path, ramp);
    write("web.gltf", "https://example.com/ramp.png", false);
    const SceneDescription web = read_gltf_scene(dir.file("web.gltf"), {});
    EXPECT_TRUE(has_note(web, "image URI 'https://example.com/ramp.png' is not fetched"));
    for (const std::string& n : web.notes)
        EXPECT_EQ(n.find("Failed to load external"), std::string::npos) << n;
    // A spot light without its "spot" object: said at the lights, in words.
    EXPECT_NE(
        error_of(dir, R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_lights_punctual"],)"
                      R"("extensions":{"KHR_lights_punctual":{"lights":[{"type":"spot"}]}}})")
            .find(R"(light of type "spot" needs its "spot" object)"),
        std::string::npos);
}

TEST(GltfErrors, BufferFaultsAreSaidAtTheirUriWithWhatTheyHold) {
    // tinygltf's words at 1:1 ("File not found : quad.bin", "Failed to decode 'uri'") said
    // neither which buffer nor where it looked, nor that a data URI was short; a file:// buffer
    // was looked for as a relative path.
    test::TempDir dir("gltf_buffers");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, -1);
    const std::string body = fmt::format(R"("meshes":[{}],"nodes":[{{"mesh":0}}])", mesh);
    w.write_gltf_bin(dir.file("buffers.gltf"), "quad.bin", body);
    ASSERT_EQ(read_gltf_scene(dir.file("buffers.gltf"), {}).objects.size(), 1u);
    const std::string text = bytes_of(dir.file("buffers.gltf"));
    // Said where the uri's value is written (line 1 of this one-line file).
    const std::string at = fmt::format("buffers.gltf:1:{}: error: ", text.find("\"quad.bin\"") + 1);
    const auto error = [&](const std::string& with) {
        std::string t = text;
        t.replace(t.find("\"quad.bin\""), 10, with);
        return error_of(dir, t, "buffers.gltf");
    };
    std::filesystem::rename(dir.file("quad.bin"), dir.file("kept.bin"));
    EXPECT_NE(error("\"quad.bin\"").find(at), std::string::npos);
    EXPECT_NE(
        error("\"quad.bin\"")
            .find("buffer 0: file 'quad.bin' not found (looked for " + dir.file("quad.bin") + ")"),
        std::string::npos)
        << error("\"quad.bin\"");
    std::ofstream(dir.file("short.bin"), std::ios::binary) << "0123456789";
    EXPECT_NE(
        error("\"short.bin\"").find("buffer 0: file 'short.bin' holds 10 bytes, its byteLength"),
        std::string::npos)
        << error("\"short.bin\"");
    EXPECT_NE(error("\"data:application/octet-stream;base64,AAAA\"")
                  .find("buffer 0: its data URI holds 3 bytes, its byteLength says"),
              std::string::npos);
    EXPECT_NE(error("\"data:application/octet-stream;base64,A$A=\"").find("is not base64"),
              std::string::npos);
    EXPECT_NE(error("\"https://example.com/quad.bin\"")
                  .find("buffer 0: URI 'https://example.com/quad.bin' is not fetched"),
              std::string::npos);
    // file:// names a path on this machine, and that file is the one watched and hashed (the
    // URI as written was: its file was never watched).
    EXPECT_EQ(error("\"file://" + dir.file("kept.bin") + "\""), "no error");
    const SceneDescription d = read_gltf_scene(dir.file("buffers.gltf"), {});
    EXPECT_NE(std::find(d.files.begin(), d.files.end(), dir.file("kept.bin")), d.files.end());
}

TEST(GltfErrors, AnImageViewPastItsBufferIsSaidAtTheImage) {
    // tinygltf hands an image's view to the image callback unchecked: a view one byte past the
    // end of its buffer was read past the buffer's memory (found by the fuzzer from a
    // draco_transcoder .glb, whose texture is in a view).
    test::TempDir dir("gltf_image_view");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, -1);
    const std::string png(16, 'x');
    const int view = w.view(png.data(), png.size());
    const std::string body = fmt::format(
        R"("meshes":[{}],"nodes":[{{"mesh":0}}],"images":[{{"bufferView":{},"mimeType":"image/png"}}])",
        mesh, view);
    w.write_glb(dir.file("ok.glb"), body);
    EXPECT_NO_THROW(read_gltf_scene(dir.file("ok.glb"), {}));
    // The buffer one byte shorter than the view's end (the BIN chunk as long as before).
    std::string text = bytes_of(dir.file("ok.glb"));
    const std::string length = fmt::format(R"("byteLength":{}}}])", w.bin.size());
    const std::size_t at = text.find(length);
    ASSERT_NE(at, std::string::npos);
    const std::string shorter = fmt::format(R"("byteLength":{}}}])", w.bin.size() - 1);
    ASSERT_EQ(shorter.size(), length.size()) << "the test keeps the JSON chunk's length";
    text.replace(at, length.size(), shorter);
    const std::string e = error_of(dir, text, "short.glb");
    EXPECT_NE(e.find("image 0: buffer view " + std::to_string(view)), std::string::npos) << e;
    EXPECT_NE(e.find("runs past the end of buffer 0"), std::string::npos) << e;
    EXPECT_NE(e.find("short.glb:1:"), std::string::npos) << e;
    // The image's member written with an escape, which the JSON parser reads as bufferView (the
    // check read member names as written, missed the view and tinygltf read past the buffer).
    const std::string plain = R"("images":[{"bufferView")";
    const std::size_t key = text.find(plain);
    ASSERT_NE(key, std::string::npos);
    std::string escaped = text;
    escaped.replace(key, plain.size(), R"("images":[{"buffer\u0056iew")");
    // The JSON chunk's length (bytes 12-15) and the file's (8-11) grow by the five bytes and
    // three spaces of padding (a chunk's length is a multiple of 4).
    uint32_t json_length;
    std::memcpy(&json_length, escaped.data() + 12, 4);
    escaped.insert(20 + json_length + 5, 3, ' ');
    for (const std::size_t field : {std::size_t{8}, std::size_t{12}}) {
        uint32_t n;
        std::memcpy(&n, escaped.data() + field, 4);
        n += 8;
        std::memcpy(escaped.data() + field, &n, 4);
    }
    const std::string e2 = error_of(dir, escaped, "escaped.glb");
    EXPECT_NE(e2.find("image 0: buffer view " + std::to_string(view)), std::string::npos) << e2;
    EXPECT_NE(e2.find("runs past the end of buffer 0"), std::string::npos) << e2;
}

TEST(GltfErrors, MemberNamesAreReadAsTheJsonParserReadsThem) {
    // An accessor whose "bufferView" is written with a \u escape is the same accessor: its
    // data were all zeros (the view was taken as missing) without a word.
    test::TempDir dir("gltf_escaped_names");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, -1);
    w.write_gltf(dir.file("plain.gltf"),
                 fmt::format(R"("meshes":[{}],"nodes":[{{"mesh":0}}])", mesh));
    std::string text = bytes_of(dir.file("plain.gltf"));
    const std::size_t at = text.find(R"("accessors":[{"bufferView")");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, 26, R"("accessors":[{"buffer\u0056iew")");
    std::ofstream(dir.file("escaped.gltf"), std::ios::binary) << text;
    const SceneDescription a = read_gltf_scene(dir.file("plain.gltf"), {});
    const SceneDescription b = read_gltf_scene(dir.file("escaped.gltf"), {});
    ASSERT_EQ(a.objects.size(), 1u);
    ASSERT_EQ(b.objects.size(), 1u);
    const auto& pa = std::get<InlineMeshShape>(a.objects[0].shape).mesh->positions;
    const auto& pb = std::get<InlineMeshShape>(b.objects[0].shape).mesh->positions;
    EXPECT_EQ(pa, pb);
    EXPECT_EQ(std::vector<float>(pb.begin() + 3, pb.begin() + 6), (std::vector<float>{1, 0, 0}));
}

TEST(GltfErrors, ABuffersSizeAndUriAreCheckedWhereWritten) {
    // tinygltf said these at 1:1 in its own words ("'byteLength' property is not a positive
    // integer", "'uri' is missing", "File not found : data:;base64,..."), and refused a .bin
    // longer than its byteLength, which glTF allows (exporters pad them to 4 bytes).
    test::TempDir dir("gltf_buffer_sizes");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, -1);
    const std::string body = fmt::format(R"("meshes":[{}],"nodes":[{{"mesh":0}}])", mesh);
    w.write_gltf_bin(dir.file("sizes.gltf"), "quad.bin", body);
    const std::string text = bytes_of(dir.file("sizes.gltf"));
    const std::size_t length_at = text.find("\"byteLength\":", text.find("\"buffers\""));
    ASSERT_NE(length_at, std::string::npos);
    const std::size_t value_at = length_at + 13;
    const std::size_t value_end = text.find_first_of(",}", value_at);
    const std::string length = text.substr(value_at, value_end - value_at);
    const auto with_length = [&](const std::string& value) {
        std::string t = text;
        t.replace(value_at, value_end - value_at, value);
        return error_of(dir, t, "sizes.gltf");
    };
    const std::string at =
        fmt::format("{}:1:{}: error: buffer 0: ", dir.file("sizes.gltf"), value_at + 1);
    EXPECT_EQ(with_length("0"), at + "byteLength 0 is not a size in bytes (a whole number, at "
                                     "least 1)");
    EXPECT_EQ(with_length("-8"), at + "byteLength -8 is not a size in bytes (a whole number, at "
                                      "least 1)");
    EXPECT_EQ(with_length("12.5"), at + "byteLength 12.5 is not a size in bytes (a whole number, "
                                        "at least 1)");
    EXPECT_EQ(with_length("\"" + length + "\""),
              at + "byteLength \"" + length + "\" is a string; write the number without quotes");
    EXPECT_EQ(with_length("null"), at + "byteLength must be a number");
    // A whole number written with a fraction or an exponent: tinygltf refused it at 1:1.
    EXPECT_EQ(with_length(length + ".0"), at + "byteLength " + length +
                                              ".0 must be written as a whole number (" + length +
                                              "): glTF readers take it as an integer");
    const auto with_uri = [&](const std::string& value) {
        std::string t = text;
        t.replace(t.find("\"quad.bin\""), 10, value);
        return error_of(dir, t, "sizes.gltf");
    };
    const std::string uri_at = fmt::format("{}:1:{}: error: buffer 0: ", dir.file("sizes.gltf"),
                                           text.find("\"quad.bin\"") + 1);
    EXPECT_EQ(with_uri("\"\""), uri_at + "its uri is empty (it names no file)");
    EXPECT_EQ(with_uri("7"), uri_at + "its uri must be a string, not 7");
    EXPECT_EQ(with_uri("\"data:;base64,AAAA\""),
              uri_at +
                  "data URI of type '': a buffer's is application/octet-stream or "
                  "application/gltf-buffer");
    EXPECT_EQ(with_uri("\"data:application/octet-stream;BASE64,AAAA\""),
              uri_at + "write ';base64' in a data URI in lower case");
    EXPECT_EQ(with_uri("\"data:Application/Octet-Stream;base64,AAAA\""),
              uri_at +
                  "write the data URI's media type in lower case ('application/octet-stream'): "
                  "glTF readers compare it as written");
    EXPECT_EQ(with_uri("\"qu%00ad.bin\""),
              uri_at + "file 'qu%00ad.bin' not found (looked for " + dir.file("qu%00ad.bin") + ")");
    // A .bin longer than byteLength is read up to it; FILE:// is file://.
    std::string bytes = bytes_of(dir.file("quad.bin"));
    std::ofstream(dir.file("padded.bin"), std::ios::binary) << bytes << std::string(3, '\0');
    EXPECT_EQ(with_uri("\"padded.bin\""), "no error");
    EXPECT_EQ(with_uri("\"FILE://" + dir.file("padded.bin") + "\""), "no error");
    const SceneDescription d = read_gltf_scene(dir.file("sizes.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_NE(std::find(d.files.begin(), d.files.end(), dir.file("padded.bin")), d.files.end());
    // Two buffers naming one file with different byteLengths: each is read up to its own (the
    // second was read up to the first's, and tinygltf refused it at 1:1).
    std::string two = text;
    two.replace(two.find("\"quad.bin\""), 10, "\"padded.bin\"");
    two.insert(two.find(']', two.find("\"buffers\"")), R"(,{"uri":"padded.bin","byteLength":4})");
    EXPECT_EQ(error_of(dir, two, "sizes.gltf"), "no error");
    EXPECT_EQ(read_gltf_scene(dir.file("sizes.gltf"), {}).objects.size(), 1u);
    // A JSON-escaped slash (some writers escape every one) and a Windows path's backslash.
    std::filesystem::create_directories(dir.file("sub"));
    std::ofstream(dir.file("sub/quad.bin"), std::ios::binary) << bytes;
    EXPECT_EQ(with_uri(R"("sub\/quad.bin")"), "no error");
    EXPECT_EQ(with_uri(R"("sub\\quad.bin")"), "no error");
}

TEST(GltfErrors, MistakesAreReportedAtTheirLineAndColumn) {
    test::TempDir dir("gltf_errors");
    const std::string f = dir.file("bad.gltf");
    const std::string kReExport =
        "re-export it without the extension, or take it out of extensionsRequired if the file's "
        "core data stands without it (then what the extension adds is left out); gltf-transform "
        "can turn its KTX2 textures into PNG";
    EXPECT_EQ(error_of(dir, "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [ {] \n}"),
              f + ":3:15: error: invalid JSON: expected a member name in double quotes");
    EXPECT_EQ(error_of(dir, "{\"asset\":{\"version\":\"2.0\"},\n\"nodes\":[{\"mesh\":4}]}"),
              f + ":2:18: error: mesh 4 does not exist (the file has 0)");
    // A property of another kind than the schema's is said at its place (tinygltf skipped it:
    // primitives written as an object drew nothing, "no node draws a mesh" at 1:1).
    EXPECT_EQ(error_of(dir,
                       "{\"asset\":{\"version\":\"2.0\"},\n\"meshes\":[{\"primitives\": "
                       "{\"attributes\":{}}}]}"),
              f + ":2:26: error: 'primitives' must be an array (glTF 2.0), got an object");
    EXPECT_EQ(
        error_of(dir,
                 "{\"asset\":{\"version\":\"2.0\"},\n\"materials\":[{"
                 "\"pbrMetallicRoughness\": [1]}]}"),
        f + ":2:39: error: 'pbrMetallicRoughness' must be an object (glTF 2.0), got an array");
    EXPECT_EQ(error_of(dir,
                       "{\"asset\":{\"version\":\"2.0\"},\n\"materials\":[{"
                       "\"normalTexture\": {\"index\": 0, \"scale\": \"2\"}}]}"),
              f + ":2:54: error: 'scale' must be a number (glTF 2.0), got a string");
    // A texture index of -1 (tinygltf's "none written") is no texture of the file, as 5 of 1
    // is not (it rendered untextured without a word).
    EXPECT_EQ(error_of(dir,
                       "{\"asset\":{\"version\":\"2.0\"},\n\"materials\":[{"
                       "\"pbrMetallicRoughness\":\n{\"baseColorTexture\": {\"index\": -1}}}]}"),
              f + ":3:22: error: texture -1 does not exist (the file has 0): 'index' names one "
                  "of the file's textures, from 0");
    EXPECT_EQ(error_of(dir,
                       "{\"asset\":{\"version\":\"2.0\"},\"extensionsRequired\":[\"KHR_texture_"
                       "basisu\"],\"extensionsUsed\":[\"KHR_texture_basisu\"]}"),
              f +
                  ":1:49: error: the file requires extension KHR_texture_basisu, which "
                  "Spangle does not read: " +
                  kReExport);
    // The same where the file's data would fail tinygltf first (indices without a bufferView):
    // the requirement is what is wrong ("accessor[0] invalid bufferView" before).
    EXPECT_EQ(error_of(dir,
                       "{\"asset\":{\"version\":\"2.0\"},\"extensionsRequired\":[\"KHR_texture_"
                       "basisu\"],\"accessors\":[{\"componentType\":5123,\"count\":3,"
                       "\"type\":\"SCALAR\"}],\"meshes\":[{\"primitives\":[{\"attributes\":{},"
                       "\"indices\":0}]}]}"),
              f +
                  ":1:49: error: the file requires extension KHR_texture_basisu, which "
                  "Spangle does not read: " +
                  kReExport);
    EXPECT_NE(error_of(dir, "{\"asset\":{\"version\":\"1.0\"}}").find("only 2.x is read"),
              std::string::npos);
    // An accessor's count, componentType and type at their place (tinygltf said them at 1:1
    // without naming the accessor).
    const auto accessor = [&](const std::string& members) {
        return error_of(dir,
                        "{\"asset\":{\"version\":\"2.0\"},\n\"accessors\":[{" + members + "}]}");
    };
    EXPECT_EQ(accessor(R"("count":24.0,"componentType":5126,"type":"VEC3")"),
              f + ":2:23: error: accessor 0: count 24.0 is not a number of elements (a whole "
                  "number, at least 1, written without a fraction)");
    EXPECT_EQ(accessor(R"("count":24,"componentType":5126,"type":"VEC5")"),
              f + ":2:54: error: accessor 0: type \"VEC5\" is not one of glTF's (SCALAR, VEC2, "
                  "VEC3, VEC4, MAT2, MAT3, MAT4)");
    EXPECT_EQ(accessor(R"("count":24,"type":"VEC3")"),
              f + ":2:14: error: accessor 0 has no componentType (5120 to 5126: the type of its "
                  "numbers)");
    EXPECT_NE(error_of(dir, "{\"asset\":{\"version\":\"2.0\"},\"nodes\":[{\"children\":[0]}]}")
                  .find("must form trees"),
              std::string::npos);
    // An accessor that runs past its buffer view.
    GltfWriter w;
    const int p = w.floats({0, 0, 0, 1, 0, 0, 1, 1, 0}, "VEC3", 3);
    w.accessors[static_cast<std::size_t>(p)] =
        R"({"bufferView":0,"componentType":5126,"count":4,"type":"VEC3"})";
    w.write_gltf(
        dir.file("short.gltf"),
        fmt::format(
            R"("nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{}}}}}]}}])",
            p));
    try {
        read_gltf_scene(dir.file("short.gltf"), {});
        FAIL() << "no error";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("do not fit in buffer view 0 (36 bytes)"),
                  std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("short.gltf:1:"), std::string::npos) << e.what();
    }
    // Indices beyond the vertices.
    GltfWriter w2;
    const int p2 = w2.floats({0, 0, 0, 1, 0, 0, 1, 1, 0}, "VEC3", 3);
    const int i2 = w2.u16({0, 1, 3});
    w2.write_gltf(
        dir.file("idx.gltf"),
        fmt::format(
            R"("nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":{}}},"indices":{}}}]}}])",
            p2, i2));
    EXPECT_THROW(read_gltf_scene(dir.file("idx.gltf"), {}), SpangleError);
}

TEST(GltfMeshes, ANanNormalFallsBackToFaceNormalsLikeAZeroOne) {
    // Some exporters write NaN normals for degenerate faces: the file is read, the mesh takes
    // its face normals, and a note says so (it refused the whole file).
    test::TempDir dir("gltf_nan_normal");
    GltfWriter w;
    const int p = w.floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3", 3);
    const int n = w.floats({0, 0, 1, NAN, 0, 1, 0, 0, 1}, "VEC3", 3);
    w.write_gltf(dir.file("nan.gltf"),
                 fmt::format(R"("meshes":[{{"primitives":[{{"attributes":{{"POSITION":{},)"
                             R"("NORMAL":{}}}}}]}}],"nodes":[{{"mesh":0}}])",
                             p, n));
    const SceneDescription d = read_gltf_scene(dir.file("nan.gltf"), {});
    ASSERT_EQ(d.objects.size(), 1u);
    const auto* shape = std::get_if<InlineMeshShape>(&d.objects[0].shape);
    ASSERT_NE(shape, nullptr);
    EXPECT_TRUE(shape->mesh->normals.empty());
    EXPECT_TRUE(has_note(d, "a NORMAL is not a finite number"));
}

TEST(GltfErrors, NumbersBeyondAFloatAndUnboundedZeroAccessorsAreRefused) {
    test::TempDir dir("gltf_range");
    const std::string head = "{\"asset\":{\"version\":\"2.0\"},\n";
    const std::string quad =
        "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],"
        "\"buffers\":[{\"byteLength\":36,\"uri\":\"data:application/octet-stream;base64,"
        "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAACAPwAAgD8AAAAA\"}],"
        "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
        "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":"
        "\"VEC3\",\"min\":[0,0,0],\"max\":[1,1,0]}]}";
    // A matrix entry past FLT_MAX is an error at the matrix, not an infinite placement.
    const std::string m = error_of(
        dir, head + "\"nodes\":[{\"mesh\":0,\"matrix\":[1e39,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]}],\n" +
                 quad);
    EXPECT_NE(m.find("bad.gltf:2:"), std::string::npos) << m;
    EXPECT_NE(m.find("is not a finite float"), std::string::npos) << m;
    // Two finite scales whose product overflows.
    const std::string w = error_of(dir, head +
                                            "\"nodes\":[{\"scale\":[1e30,1,1],\"children\":[1]},"
                                            "{\"mesh\":0,\"scale\":[1e30,1,1]}],\n" +
                                            quad);
    EXPECT_NE(w.find("world transform overflows a float"), std::string::npos) << w;
    // An accessor without a buffer view is zeros; 20 million of them are refused before any
    // memory is taken.
    const std::string z =
        error_of(dir, head + "\"nodes\":[{\"mesh\":0}],\n" +
                          "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],"
                          "\"accessors\":[{\"componentType\":5126,\"count\":20000000,\"type\":"
                          "\"VEC3\",\"min\":[0,0,0],\"max\":[0,0,0]}]}");
    EXPECT_NE(z.find("has no buffer view and 20000000 elements"), std::string::npos) << z;
}

TEST(GltfContainers, ATomlSceneImportsAGltfAndOverridesItsMaterialByName) {
    test::TempDir dir("gltf_import");
    GltfWriter w;
    const std::string mesh = quad_mesh(w, 0);
    w.write_gltf(
        dir.file("quad.gltf"),
        R"("nodes":[{"mesh":0,"translation":[0,0,-2]}],"meshes":[)" + mesh +
            R"(],"materials":[{"name":"Paint","pbrMetallicRoughness":{"metallicFactor":1},)"
            R"("emissiveFactor":[1,0,0],"extensions":{"KHR_materials_emissive_strength":)"
            R"({"emissiveStrength":4}}}])");
    std::ofstream(dir.file("scene.toml")) << R"([camera]
position = [0, 0, 5]
look_at = [0, 0, 0]

[[import]]
file = "quad.gltf"
translate = [1, 0, 0]
lights = false

[[material]]
name = "Paint"
plugin = "smooth"
model = "diffuse"
)";
    const SceneDescription d = read_scene(dir.file("scene.toml"));
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_EQ(d.objects[0].material, "Paint");
    ASSERT_EQ(d.materials.size(), 1u);  // the importing file's replaces the glTF's
    EXPECT_EQ(d.materials[0].model, "diffuse");
    EXPECT_TRUE(d.lights.empty());         // lights = false drops the studio light
    EXPECT_EQ(d.camera.position.z, 5.0f);  // the importing file's camera wins
    // The glTF material's glow goes with it (the replaced paint glowed red).
    EXPECT_FALSE(d.objects[0].emission.has_value());
    EXPECT_TRUE(has_note(d, "material 'Paint' of " + dir.file("quad.gltf") + " emitted light"));
    EXPECT_TRUE(read_gltf_scene(dir.file("quad.gltf"), {}).objects[0].emission.has_value());
    // Its glow was the file's only light (so it had no studio light): the studio light stands
    // in for it, as for a file without light (the sky; the key light is left out by `lights`).
    ASSERT_TRUE(d.environment.has_value());
    ASSERT_TRUE(d.environment->color.has_value());
    EXPECT_FLOAT_EQ(d.environment->color->rgb.x, 0.25f);
    EXPECT_TRUE(has_note(d, "has no light left: the default studio light stands in"));
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo info = build_scene(d, color, registry, 0.0);
    // The glTF node's translation, then the import's placement.
    const Vec3 o = info.object_to_world[0].apply_point({0, 0, 0});
    EXPECT_NEAR(o.x, 1.0f, 1e-6f);
    EXPECT_NEAR(o.z, -2.0f, 1e-6f);
}

TEST(GltfMaterials, AMeshTakesTheUvSetItsMaterialReads) {
    // A mesh whose only uvs are TEXCOORD_1, under a material whose texture reads set 1, had no
    // uvs at all ("no uvs" once per triangle, the texture mapped through nothing).
    test::TempDir dir("gltf_uv_set");
    CacheEnv cache(dir.file("cache"));
    const std::string png = bytes_of(test::test_dir() + "/scenes/textures/roughness_ramp.png");
    std::ofstream(dir.file("t.png"), std::ios::binary) << png;
    const auto write = [&](const char* set, int tex_coord, const std::string& info_extra = "") {
        GltfWriter w;
        std::string mesh = quad_mesh(w, 0);
        mesh.replace(mesh.find("TEXCOORD_0"), 10, set);
        w.write_gltf(
            dir.file("uv.gltf"),
            fmt::format(R"("meshes":[{}],"nodes":[{{"mesh":0}}],"images":[{{"uri":"t.png"}}],)"
                        R"("textures":[{{"source":0}}],"materials":[{{"pbrMetallicRoughness":)"
                        R"({{"baseColorTexture":{{"index":0,"texCoord":{}{}}}}}}}])",
                        mesh, tex_coord, info_extra));
        return read_gltf_scene(dir.file("uv.gltf"), {});
    };
    const SceneDescription zero = write("TEXCOORD_0", 0);
    const SceneDescription one = write("TEXCOORD_1", 1);
    // KHR_texture_transform's texCoord overrides the texture reference's (Khronos'
    // TextureTransformMultiTest): set 1 is read, and no note says otherwise.
    const SceneDescription overridden =
        write("TEXCOORD_1", 0, R"(,"extensions":{"KHR_texture_transform":{"texCoord":1}})");
    ASSERT_EQ(one.objects.size(), 1u);
    const auto uvs = [](const SceneDescription& d) {
        return std::get<InlineMeshShape>(d.objects[0].shape).mesh->uvs;
    };
    EXPECT_FALSE(uvs(one).empty());
    EXPECT_EQ(uvs(one), uvs(zero));
    EXPECT_FALSE(has_note(one, "TEXCOORD_1 is dropped"));
    EXPECT_FALSE(has_note(one, "another uv set"));
    EXPECT_EQ(uvs(overridden), uvs(zero));
    EXPECT_FALSE(has_note(overridden, "TEXCOORD_1 is dropped"));
    EXPECT_FALSE(has_note(overridden, "another uv set"));
}

TEST(GltfMaterials, MaskAndBlendCutTheSurfaceByTheBaseColoursAlpha) {
    // alphaMode MASK: the base colour texture's alpha times the factor's, cut at alphaCutoff;
    // BLEND: the same alpha by chance; without a texture, the factor's alpha alone.
    test::TempDir dir("gltf_alpha");
    CacheEnv cache(dir.file("cache"));
    const std::string png = bytes_of(test::test_dir() + "/scenes/textures/half_alpha.png");
    std::ofstream(dir.file("leaf.png"), std::ios::binary) << png;
    GltfWriter w;
    std::string meshes, nodes;
    for (int m = 0; m < 6; ++m) {
        meshes += fmt::format("{}{}", m ? "," : "", quad_mesh(w, m));
        nodes += fmt::format(R"({}{{"mesh":{}}})", m ? "," : "", m);
    }
    w.write_gltf(
        dir.file("leaves.gltf"),
        fmt::format(
            R"("meshes":[{}],"nodes":[{}],"images":[{{"uri":"leaf.png"}}],)"
            R"("textures":[{{"source":0}}],"materials":[)"
            R"({{"name":"mask","alphaMode":"MASK","alphaCutoff":0.3,"pbrMetallicRoughness":)"
            R"({{"baseColorTexture":{{"index":0}},"baseColorFactor":[1,1,1,0.8]}}}},)"
            R"({{"name":"blend","alphaMode":"BLEND","pbrMetallicRoughness":)"
            R"({{"baseColorFactor":[1,1,1,0.25]}}}},)"
            R"({{"name":"default_cutoff","alphaMode":"MASK","pbrMetallicRoughness":)"
            R"({{"baseColorFactor":[1,1,1,0.4]}}}},)"
            R"({{"name":"opaque","alphaMode":"OPAQUE","pbrMetallicRoughness":)"
            R"({{"baseColorTexture":{{"index":0}},"baseColorFactor":[1,1,1,0.1]}}}},)"
            R"({{"name":"lower","alphaMode":"mask"}},)"
            R"({{"name":"far","alphaMode":"MASK","alphaCutoff":1.5,"pbrMetallicRoughness":)"
            R"({{"baseColorFactor":[1,1,1,0.9]}}}}])",
            meshes, nodes));
    const SceneDescription d = read_gltf_scene(dir.file("leaves.gltf"), {});
    ASSERT_EQ(d.materials.size(), 6u);
    const MaterialDesc& mask = d.materials[0];
    ASSERT_TRUE(mask.alpha);
    EXPECT_EQ(mask.alpha->kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(mask.alpha->texture.channel, kAlphaOrOpaque) << "alpha, or opaque without one";
    EXPECT_FLOAT_EQ(mask.alpha->texture.scale[0], 0.8f);
    EXPECT_EQ(mask.alpha->texture.space, "raw");
    ASSERT_TRUE(mask.alpha_cutoff);
    EXPECT_DOUBLE_EQ(*mask.alpha_cutoff, 0.3);
    const MaterialDesc& blend = d.materials[1];
    ASSERT_TRUE(blend.alpha);
    EXPECT_EQ(blend.alpha->kind, ParamDesc::Kind::Number);
    EXPECT_DOUBLE_EQ(blend.alpha->number, 0.25);
    EXPECT_FALSE(blend.alpha_cutoff);
    // 0.4 under the default cutoff 0.5: cut whole (the object is not seen).
    ASSERT_TRUE(d.materials[2].alpha);
    EXPECT_DOUBLE_EQ(*d.materials[2].alpha_cutoff, 0.5);
    EXPECT_FALSE(d.materials[3].alpha) << "OPAQUE ignores alpha";
    // Modes and cutoffs glTF does not allow are said, not taken silently.
    EXPECT_FALSE(d.materials[4].alpha);
    EXPECT_TRUE(has_note(d, "alphaMode \"mask\" is not OPAQUE, MASK or BLEND"))
        << ::testing::PrintToString(d.notes);
    ASSERT_TRUE(d.materials[5].alpha);
    EXPECT_DOUBLE_EQ(*d.materials[5].alpha_cutoff, 1.0);
    EXPECT_TRUE(has_note(d, "alphaCutoff 1.5 is outside [0, 1]: 1 stands in"));
    // Converted to TOML, the mask reads the image's alpha channel ("a", which an image without
    // one reads as 1), not its red (convert wrote "r"), and renders the same image.
    write_toml_scene(d, dir.file("converted.toml"), dir.file("converted_meshes"));
    EXPECT_NE(bytes_of(dir.file("converted.toml")).find("channel = \"a\""), std::string::npos);
    const auto render = [&](const std::string& scene) {
        FrameRequest req = test::quiet_request(scene);
        req.options.texture_cache = dir.file("cache");
        req.options.width_override = 24;
        req.options.height_override = 16;
        req.options.spp_override = 4;
        return render_frame(req).image;
    };
    const std::vector<float> direct = render(dir.file("leaves.gltf"));
    EXPECT_EQ(render(dir.file("converted.toml")), direct);
}

TEST(GltfMaterials, ANoteSaidOnceCountsAndListsItsOtherPlaces) {
    // Each kind of note is said once per load: it now says how many more places it applies to
    // and where (an artist with 80 materials could not tell which lost their alpha).
    test::TempDir dir("gltf_note_places");
    GltfWriter w;
    std::string meshes;
    for (int m = 0; m < 7; ++m) {
        if (m > 0) meshes += ",";
        meshes += quad_mesh(w, m);
    }
    std::string materials;
    for (int m = 0; m < 7; ++m)
        materials += fmt::format(R"({}{{"name":"m{}","alphaMode":"BLEND"}})", m ? "," : "", m);
    std::string nodes;
    for (int m = 0; m < 7; ++m) nodes += fmt::format(R"({}{{"mesh":{}}})", m ? "," : "", m);
    w.write_gltf(
        dir.file("many.gltf"),
        fmt::format(R"("meshes":[{}],"materials":[{}],"nodes":[{}])", meshes, materials, nodes));
    const SceneDescription d = read_gltf_scene(dir.file("many.gltf"), {});
    int said = 0;
    for (const std::string& n : d.notes)
        if (n.find("alphaMode BLEND") != std::string::npos) {
            ++said;
            EXPECT_NE(n.find("(and 6 more places: "), std::string::npos) << n;
            EXPECT_NE(n.find(", ...)"), std::string::npos) << n;
        }
    EXPECT_EQ(said, 1);
}

TEST(GltfContainers, GlbAndExternalBufferReadAsTheEmbeddedGltf) {
    test::TempDir dir("gltf_glb");
    GltfWriter w;
    const std::string body = animated_body(w);
    w.write_gltf(dir.file("a.gltf"), body);
    w.write_gltf_bin(dir.file("b.gltf"), "b.bin", body);
    w.write_glb(dir.file("c.glb"), body);
    const SceneDescription a = read_scene(dir.file("a.gltf"));
    const SceneDescription b = read_scene(dir.file("b.gltf"));
    const SceneDescription c = read_scene(dir.file("c.glb"));  // the loader picks glTF by extension
    ASSERT_EQ(a.objects.size(), 2u);
    for (const SceneDescription* d : {&b, &c}) {
        ASSERT_EQ(d->objects.size(), a.objects.size());
        const auto& ma = *std::get<InlineMeshShape>(a.objects[0].shape).mesh;
        const auto& md = *std::get<InlineMeshShape>(d->objects[0].shape).mesh;
        EXPECT_EQ(ma.positions, md.positions);
        EXPECT_EQ(ma.indices, md.indices);
        EXPECT_EQ(a.objects[0].matrix_keys.keys.size(), d->objects[0].matrix_keys.keys.size());
    }
    // The external buffer is a file the scene read (watch mode reloads when it changes).
    ASSERT_EQ(b.files.size(), 1u);
    EXPECT_EQ(b.files[0], dir.file("b.bin"));
    EXPECT_EQ(scene_format_for("x.GLB").name, std::string("glTF"));
    // A JSON chunk with a byte-order mark and NUL padding (both "unexpected character" before)
    // reads as the clean one; a .glb without the magic says so.
    std::string glb = bytes_of(dir.file("c.glb"));
    uint32_t length = 0;
    std::memcpy(&length, glb.data() + 12, 4);
    std::string chunk = glb.substr(20, length);
    while (!chunk.empty() && chunk.back() == ' ') chunk.pop_back();
    chunk.insert(0, "\xEF\xBB\xBF");
    chunk.append(8 - chunk.size() % 4, '\0');
    const auto put = [](std::string& text, std::size_t at, uint32_t v) {
        std::memcpy(text.data() + at, &v, 4);
    };
    std::string mended = glb.substr(0, 20) + chunk + glb.substr(20 + length);
    put(mended, 8, static_cast<uint32_t>(mended.size()));
    put(mended, 12, static_cast<uint32_t>(chunk.size()));
    std::ofstream(dir.file("d.glb"), std::ios::binary) << mended;
    const SceneDescription d = read_scene(dir.file("d.glb"));
    ASSERT_EQ(d.objects.size(), a.objects.size());
    std::ofstream(dir.file("e.glb"), std::ios::binary) << "gltf" << glb.substr(4);
    try {
        read_scene(dir.file("e.glb"));
        ADD_FAILURE() << "a .glb without its magic was read";
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("not a binary glTF file"), std::string::npos)
            << e.what();
    }
    // A BIN chunk whose length runs past the file by no more than its 8-byte header, the buffer
    // as long (tinygltf let it through and copied bytes from past the file's memory: a fuzzer
    // found it under AddressSanitizer).
    uint32_t bin_length = 0;
    std::memcpy(&bin_length, glb.data() + 20 + length, 4);
    const std::string bin_data = glb.substr(20 + length + 8);
    ASSERT_EQ(bin_data.size(), bin_length);
    for (const uint32_t more : {4u, 8u}) {
        std::string json = glb.substr(20, length);
        const std::string key = R"("buffers":[{"byteLength":)";
        const std::size_t at = json.find(key);
        ASSERT_NE(at, std::string::npos);
        const std::size_t digits = json.find_first_not_of("0123456789", at + key.size());
        json.replace(at + key.size(), digits - at - key.size(), std::to_string(bin_length + more));
        while (json.size() % 4 != 0) json += ' ';
        std::string longer = glb.substr(0, 20) + json;
        longer.append(8, '\0');
        put(longer, 20 + json.size(), bin_length + more);
        put(longer, 20 + json.size() + 4, 0x004E4942u);
        longer += bin_data;
        put(longer, 8, static_cast<uint32_t>(longer.size()));
        put(longer, 12, static_cast<uint32_t>(json.size()));
        std::ofstream(dir.file("f.glb"), std::ios::binary) << longer;
        try {
            read_scene(dir.file("f.glb"));
            ADD_FAILURE() << "a BIN chunk " << more << " bytes longer than the file was read";
        } catch (const SpangleError& e) {
            EXPECT_NE(std::string(e.what()).find("the chunk after the JSON"), std::string::npos)
                << e.what();
        }
    }
    // Damaged lengths and types, each said in words of the .glb (tinygltf's were "Invalid
    // `byteLength'" at 1:1, or a chunk header read from inside the JSON text).
    const auto refused = [&](const std::string& name, const std::string& bytes,
                             const std::string& said) {
        std::ofstream(dir.file(name), std::ios::binary) << bytes;
        try {
            read_scene(dir.file(name));
            ADD_FAILURE() << name << " was read";
        } catch (const SpangleError& e) {
            EXPECT_NE(std::string(e.what()).find(said), std::string::npos)
                << name << ": " << e.what();
        }
    };
    refused("empty.glb", "", "a .glb file needs at least 20 bytes, this has 0");
    std::string bad = glb;
    put(bad, 12, 0);
    refused("json0.glb", bad, "the JSON chunk is empty");
    bad = glb;
    put(bad, 12, length + 1);
    refused("json_odd.glb", bad, "is not a multiple of 4");
    bad = glb;
    put(bad, 12, length - 4);
    refused("json_short.glb", bad, "is not a BIN chunk");
    bad = glb;
    put(bad, 20 + length + 4, 0x58585858u);
    refused("bin_type.glb", bad, "is not a BIN chunk (its type is 0x58585858");
    bad = glb;
    put(bad, 20 + length, bin_length - 4);
    bad.resize(bad.size() - 4);
    put(bad, 8, static_cast<uint32_t>(bad.size()));
    refused("bin_short.glb", bad, "more than the .glb's BIN chunk holds");
}

}  // namespace
}  // namespace spangle::test_gltf_materials
