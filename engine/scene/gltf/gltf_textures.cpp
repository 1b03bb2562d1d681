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
    ctx.note("texture uv set", ctx.at(ref + "/texCoord"),
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

std::optional<int> uv_set_override(const tinygltf::ExtensionMap* extensions) {
    if (!extensions) return std::nullopt;
    const auto x = extensions->find("KHR_texture_transform");
    if (x == extensions->end() || !x->second.IsObject() || !x->second.Has("texCoord") ||
        !x->second.Get("texCoord").IsNumber())
        return std::nullopt;
    return static_cast<int>(x->second.Get("texCoord").GetNumberAsDouble());
}

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
        if (wrap_mode(s.wrapT) != tex.wrap) tex.wrap_t = wrap_mode(s.wrapT);
        // magFilter NEAREST: texels stay squares when magnified (pixel art, voxel models).
        if (s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST) tex.filter = 2;
    }
    // The uv set it reads: KHR_texture_transform's texCoord overrides the reference's.
    const std::string transform_ref = ref + "/extensions/KHR_texture_transform";
    if (const std::optional<int> set = uv_set_override(use.extensions)) {
        if (*set != ctx.uv_set) note_uv_set(ctx, transform_ref);
    } else if (use.tex_coord != ctx.uv_set) {
        note_uv_set(ctx, ref);
    }
    if (use.extensions)
        if (auto x = use.extensions->find("KHR_texture_transform"); x != use.extensions->end())
            texture_transform(ctx, x->second, transform_ref, tex);
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

void spec_gloss_to_metal(Vec3 diffuse, Vec3 specular, double& metallic, Vec3& base) {
    const auto perceived = [](Vec3 c) {
        const double cr = c.x, cg = c.y, cb = c.z;
        return std::sqrt(0.299 * cr * cr + 0.587 * cg * cg + 0.114 * cb * cb);
    };
    const double one_minus_spec =
        1.0 - static_cast<double>(std::max({specular.x, specular.y, specular.z}));
    const double ps = perceived(specular), pd = perceived(diffuse);
    metallic = 0.0;
    if (ps >= 0.04) {
        const double qa = 0.04, qb = pd * one_minus_spec / 0.96 + ps - 0.08, qc = 0.04 - ps;
        const double disc = std::max(0.0, qb * qb - 4.0 * qa * qc);
        metallic = std::clamp((-qb + std::sqrt(disc)) / (2.0 * qa), 0.0, 1.0);
    }
    const auto mf = static_cast<float>(metallic);
    const Vec3 from_diffuse =
        diffuse * static_cast<float>(one_minus_spec / 0.96 / std::max(1.0 - metallic, 1e-6));
    const Vec3 from_spec = (specular - Vec3(0.04f * (1.0f - mf))) * (1.0f / std::max(mf, 1e-6f));
    const Vec3 mixed = from_diffuse + (from_spec - from_diffuse) * (mf * mf);
    base = {std::clamp(mixed.x, 0.0f, 1.0f), std::clamp(mixed.y, 0.0f, 1.0f),
            std::clamp(mixed.z, 0.0f, 1.0f)};
}

std::optional<MetalRoughImages> metal_rough_from_spec_gloss(
    Context& ctx, const std::optional<TextureUse>& diffuse, const std::string& dref,
    const std::optional<TextureUse>& sg, const std::string& sref, Vec3 diffuse_factor,
    Vec3 specular_factor, double gloss_factor) {
    std::optional<TextureDesc> dtex, stex;
    if (diffuse) dtex = texture_desc(ctx, *diffuse, dref, true);
    if (sg) stex = texture_desc(ctx, *sg, sref, true);
    if ((diffuse && !dtex) || (sg && !stex) || (!dtex && !stex)) return {};
    // One mapping for both (the images are combined texel by texel).
    if (dtex && stex &&
        (diffuse->tex_coord != sg->tex_coord || dtex->wrap != stex->wrap ||
         dtex->wrap_t != stex->wrap_t ||
         !std::equal(std::begin(dtex->uv), std::end(dtex->uv), std::begin(stex->uv))))
        return {};
    std::optional<tinygltf::Image> di, si;
    if (diffuse && !(di = decoded(ctx, diffuse->index))) return {};
    if (sg && !(si = decoded(ctx, sg->index))) return {};
    const int w = std::max(di ? di->width : 0, si ? si->width : 0);
    const int h = std::max(di ? di->height : 0, si ? si->height : 0);
    // The texel of img nearest to (x, y) of the output, as linear Rec.709 and its alpha.
    const auto texel = [&](const tinygltf::Image& img, int x, int y, Vec3& rgb, double& a) {
        const int sx = std::min(img.width - 1, x * img.width / w);
        const int sy = std::min(img.height - 1, y * img.height / h);
        const auto at = static_cast<std::size_t>(sy) * static_cast<std::size_t>(img.width) +
                        static_cast<std::size_t>(sx);
        const auto comp = static_cast<std::size_t>(img.component);
        const unsigned char* p = &img.image[at * comp];
        rgb = {static_cast<float>(srgb_to_linear(p[0] / 255.0)),
               static_cast<float>(srgb_to_linear(p[1] / 255.0)),
               static_cast<float>(srgb_to_linear(p[2] / 255.0))};
        a = comp == 4 ? p[3] / 255.0 : 1.0;
    };
    const std::string header = fmt::format("P6\n{} {}\n65535\n", w, h);
    std::vector<unsigned char> base(header.begin(), header.end()),
        packed(header.begin(), header.end());
    const auto put = [](std::vector<unsigned char>& out, double v) {
        const auto q = static_cast<uint32_t>(std::lround(std::clamp(v, 0.0, 1.0) * 65535.0));
        out.push_back(static_cast<unsigned char>(q >> 8));
        out.push_back(static_cast<unsigned char>(q & 0xff));
    };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            Vec3 d = diffuse_factor, sp = specular_factor;
            double gloss = gloss_factor, unused = 1.0;
            if (di) {
                Vec3 c;
                texel(*di, x, y, c, unused);
                d = d * c;
            }
            if (si) {
                Vec3 c;
                double a = 1.0;
                texel(*si, x, y, c, a);
                sp = sp * c;
                gloss *= a;
            }
            double metallic = 0.0;
            Vec3 bc;
            spec_gloss_to_metal(d, sp, metallic, bc);
            put(base, bc.x);
            put(base, bc.y);
            put(base, bc.z);
            put(packed, 0.0);
            put(packed, 1.0 - gloss);
            put(packed, metallic);
        }
    MetalRoughImages out{dtex ? *dtex : *stex, dtex ? *dtex : *stex};
    const std::string& ref = dtex ? dref : sref;
    out.base.path = cached_image_file(ctx, base, ".ppm", ref);
    out.base.space = "lin_rec709";
    out.packed.path = cached_image_file(ctx, packed, ".ppm", ref);
    out.packed.space = "raw";
    return out;
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
