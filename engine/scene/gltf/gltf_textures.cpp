#include "scene/gltf/gltf_textures.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>

#include "scene/gltf/gltf_parts.h"

namespace spangle::gltf {
namespace {

/** Spangle's wrap mode (0 periodic, 1 clamp, 3 mirror) of a glTF sampler wrap. */
int wrap_mode(int gl) {
    if (gl == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return 1;
    if (gl == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return 3;
    return 0;
}

/** Member `key` of v as a finite number, else `fallback`. */
double number_or(const tinygltf::Value& v, const char* key, double fallback) {
    if (!v.IsObject() || !v.Has(key) || !v.Get(key).IsNumber()) return fallback;
    const double x = v.Get(key).GetNumberAsDouble();
    return std::isfinite(x) ? x : fallback;
}

/** Notes that the texture at `ref` reads another uv set than its material's (ctx.uv_set), which
 *  stands in. */
void note_uv_set(Context& ctx, const std::string& ref) {
    ctx.note("TEXCOORD_n", ctx.at(ref + "/texCoord"),
             fmt::format("a texture reads another uv set than its material's others: TEXCOORD_{} "
                         "stands in (Spangle meshes hold one)",
                         ctx.uv_set));
}

/** KHR_texture_transform's T R S (in glTF's (s, t), t down) as TextureDesc's uv matrix, in
 *  Spangle's (u, v) = (s, 1 - t): s = A00 u - A01 v + A01 + A02, and 1 - t likewise. */
void texture_transform(Context& ctx, const tinygltf::Value& x, const std::string& ref,
                       TextureDesc& tex) {
    double offset[2] = {0, 0}, scale[2] = {1, 1};
    for (const auto& [key, out] : {std::pair{"offset", offset}, std::pair{"scale", scale}}) {
        if (!x.Has(key)) continue;
        const tinygltf::Value& a = x.Get(key);
        if (!a.IsArray() || a.ArrayLen() != 2 || !a.Get(0).IsNumber() || !a.Get(1).IsNumber())
            throw_error(ctx.at(ref + "/" + key), "KHR_texture_transform '{}' must be two numbers",
                        key);
        out[0] = a.Get(0).GetNumberAsDouble();
        out[1] = a.Get(1).GetNumberAsDouble();
        if (!std::isfinite(out[0]) || !std::isfinite(out[1]))
            throw_error(ctx.at(ref + "/" + key), "KHR_texture_transform '{}' must be finite", key);
    }
    const double r = number_or(x, "rotation", 0.0), c = std::cos(r), s = std::sin(r);
    const double a00 = c * scale[0], a01 = s * scale[1], a02 = offset[0];
    const double a10 = -s * scale[0], a11 = c * scale[1], a12 = offset[1];
    const double m[6] = {a00, -a01, a01 + a02, -a10, a11, 1.0 - a11 - a12};
    for (int k = 0; k < 6; ++k) {
        tex.uv[k] = narrow(m[k]);
        if (!std::isfinite(tex.uv[k]))
            throw_error(ctx.at(ref), "KHR_texture_transform makes a uv transform beyond a float");
    }
    if (x.Has("texCoord") && number_or(x, "texCoord", 0) != ctx.uv_set) note_uv_set(ctx, ref);
}

/** Width x height from a PNG's IHDR or a JPEG's start-of-frame segment; 0 when not found. */
std::size_t pixel_count(const std::vector<unsigned char>& b) {
    const auto be16 = [&](std::size_t i) { return static_cast<std::size_t>(b[i] << 8 | b[i + 1]); };
    if (b.size() >= 24 && b[0] == 0x89 && b[1] == 'P')
        return (be16(16) << 16 | be16(18)) * (be16(20) << 16 | be16(22));
    for (std::size_t i = 2; i + 9 < b.size();) {
        if (b[i] != 0xFF) return 0;
        const unsigned char m = b[i + 1];
        if (m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC)
            return be16(i + 5) * be16(i + 7);
        i += 2 + be16(i + 2);
    }
    return 0;
}

}  // namespace

std::optional<TextureDesc> texture_desc(Context& ctx, const TextureUse& use, const std::string& ref,
                                        bool color) {
    check_index(ctx, ref + "/index", use.index, ctx.model.textures.size(), "texture");
    const tinygltf::Texture& t = ctx.model.textures[static_cast<std::size_t>(use.index)];
    const std::string tp = fmt::format("textures/{}", use.index);
    // EXT_texture_webp: a WebP image, read as any other (the core source, PNG or JPEG, is its
    // fallback and may be absent).
    int source = t.source;
    std::string source_ref = tp + "/source";
    if (const auto x = t.extensions.find("EXT_texture_webp"); x != t.extensions.end()) {
        const tinygltf::Value& v = x->second;
        if (v.IsObject() && v.Has("source") && v.Get("source").IsInt()) {
            source = v.Get("source").GetNumberAsInt();
            source_ref = tp + "/extensions/EXT_texture_webp/source";
        }
    }
    if (source < 0) {
        ctx.note("texture source", ctx.at(tp),
                 fmt::format("texture {} has no PNG, JPEG or WebP source (KTX2 images are not "
                             "read): the textures using it are dropped, their factors stand in",
                             use.index));
        return std::nullopt;
    }
    const std::string file = image_file(ctx, source, source_ref);
    if (file.empty()) return std::nullopt;
    TextureDesc tex;
    tex.path = file;
    tex.space = color ? "srgb_texture" : "raw";
    tex.space_loc = ctx.at(ref);
    if (t.sampler >= 0) {
        check_index(ctx, tp + "/sampler", t.sampler, ctx.model.samplers.size(), "sampler");
        const tinygltf::Sampler& s = ctx.model.samplers[static_cast<std::size_t>(t.sampler)];
        tex.wrap = wrap_mode(s.wrapS);
        // magFilter NEAREST: texels stay squares when magnified (pixel art, voxel models).
        if (s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST) tex.filter = 2;
        if (wrap_mode(s.wrapT) != tex.wrap)
            ctx.note("wrapT", ctx.at(fmt::format("samplers/{}/wrapT", t.sampler)),
                     "a sampler wraps s and t differently: Spangle wraps both as wrapS says");
    }
    if (use.tex_coord != ctx.uv_set) note_uv_set(ctx, ref);
    if (use.extensions)
        if (auto x = use.extensions->find("KHR_texture_transform"); x != use.extensions->end())
            texture_transform(ctx, x->second, ref + "/extensions/KHR_texture_transform", tex);
    return tex;
}

namespace {

/** Texture `index`'s image decoded to 8 bits per channel (at least 3 channels), or none. */
std::optional<tinygltf::Image> decoded(Context& ctx, int index) {
    if (index < 0 || static_cast<std::size_t>(index) >= ctx.model.textures.size()) return {};
    const int source = ctx.model.textures[static_cast<std::size_t>(index)].source;
    if (source < 0 || static_cast<std::size_t>(source) >= ctx.model.images.size()) return {};
    const std::string file = image_file(ctx, source, fmt::format("textures/{}/source", index));
    if (file.empty()) return {};
    std::vector<unsigned char> bytes = ctx.images[static_cast<std::size_t>(source)];
    if (bytes.empty()) {
        std::ifstream in(file, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    // Decoding holds 4 bytes a pixel: not worth more than 64 Mpixels here.
    const std::size_t pixels = pixel_count(bytes);
    if (pixels == 0 || pixels > (std::size_t{1} << 26) || bytes.size() > (std::size_t{1} << 30))
        return {};
    tinygltf::Image img;
    std::string err, warn;
    if (!tinygltf::LoadImageData(&img, source, &err, &warn, 0, 0, bytes.data(),
                                 static_cast<int>(bytes.size()), nullptr) ||
        img.width <= 0 || img.height <= 0 || img.component < 3 || img.bits != 8)
        return {};
    const std::size_t n =
        static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height);
    if (img.image.size() < n * static_cast<std::size_t>(img.component)) return {};
    return img;
}

}  // namespace

std::optional<Vec3> texture_mean(Context& ctx, int index) {
    const std::optional<tinygltf::Image> img = decoded(ctx, index);
    if (!img) return {};
    const auto decode = [](unsigned char c) { return srgb_to_linear(c / 255.0); };
    double sum[3] = {0, 0, 0};
    const std::size_t n =
        static_cast<std::size_t>(img->width) * static_cast<std::size_t>(img->height);
    const auto comp = static_cast<std::size_t>(img->component);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t c = 0; c < 3; ++c) sum[c] += decode(img->image[i * comp + c]);
    const auto mean = [&](int c) { return static_cast<float>(sum[c] / static_cast<double>(n)); };
    return Vec3{mean(0), mean(1), mean(2)};
}

std::optional<TextureDesc> roughness_from_gloss(Context& ctx, const TextureUse& use,
                                                const std::string& ref, double factor) {
    std::optional<TextureDesc> tex = texture_desc(ctx, use, ref, false);
    if (!tex) return {};
    const std::optional<tinygltf::Image> img = decoded(ctx, use.index);
    if (!img || img->component != 4) return {};
    // A binary PGM (P5) of 16-bit samples, big-endian: 1 - factor x alpha.
    const std::size_t n =
        static_cast<std::size_t>(img->width) * static_cast<std::size_t>(img->height);
    const std::string header = fmt::format("P5\n{} {}\n65535\n", img->width, img->height);
    std::vector<unsigned char> bytes(header.begin(), header.end());
    bytes.reserve(header.size() + 2 * n);
    for (std::size_t i = 0; i < n; ++i) {
        const double gloss = factor * img->image[4 * i + 3] / 255.0;
        const auto v =
            static_cast<uint32_t>(std::lround(std::clamp(1.0 - gloss, 0.0, 1.0) * 65535.0));
        bytes.push_back(static_cast<unsigned char>(v >> 8));
        bytes.push_back(static_cast<unsigned char>(v & 0xff));
    }
    tex->path = cached_image_file(ctx, bytes, ".pgm", ref);
    tex->space = "raw";
    return tex;
}

}  // namespace spangle::gltf
