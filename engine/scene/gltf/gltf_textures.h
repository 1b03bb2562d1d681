#pragma once
// glTF texture references (textureInfo, its sampler, KHR_texture_transform) as TextureDescs, and
// the mean colour of an image (what stands in for an emissive texture). Internal to
// engine/scene/gltf/.

#include <optional>
#include <string>

#include "core/math.h"
#include "scene/gltf/gltf_context.h"

namespace spangle::gltf {

/** A textureInfo's fields, whichever glTF structure holds them. */
struct TextureUse {
    int index = -1;                                      ///< the texture
    int tex_coord = 0;                                   ///< its TEXCOORD set
    const tinygltf::ExtensionMap* extensions = nullptr;  ///< KHR_texture_transform lives here
};

/** The TextureDesc of the textureInfo at JSON path `ref`: its image as a file, colour
 *  (`color`: sRGB-encoded, glTF 2.0, 3.9.2) or data, its sampler's wrap mode and its uv
 *  transform (glTF's t runs down, Spangle's v up). None (with a note) when its image cannot be
 *  had. */
std::optional<TextureDesc> texture_desc(Context& ctx, const TextureUse& use, const std::string& ref,
                                        bool color);

/** The uv set KHR_texture_transform (in a texture reference's `extensions`, null: none) makes it
 *  read, overriding the reference's own texCoord; none when it gives no texCoord. */
std::optional<int> uv_set_override(const tinygltf::ExtensionMap* extensions);

/** The mean linear Rec.709 colour of texture `index`'s image (sRGB decoded), or none when it
 *  cannot be decoded. */
std::optional<Vec3> texture_mean(Context& ctx, int index);

/** The glTF converter's solve from specular-glossiness to metallic-roughness for one colour
 *  pair (linear Rec.709): the metalness whose dielectric and metal mix best reproduces both
 *  the diffuse and the specular brightness, and the base colour of that mix. */
void spec_gloss_to_metal(Vec3 diffuse, Vec3 specular, double& metallic, Vec3& base);

/** KHR_materials_pbrSpecularGlossiness's textures (`diffuse` at `dref`, `sg` at `sref`, either
 *  absent) times their factors, converted texel by texel by spec_gloss_to_metal: a linear
 *  base-colour image and a packed metallic-roughness image (G roughness = 1 - glossiness, B
 *  metallic), 16 bits a channel, written once into the embedded-image cache, at the larger
 *  image's size, with the textures' sampler and uv transform. None when an image cannot be
 *  decoded or the two textures are mapped differently (uv set, transform or wrap). */
struct MetalRoughImages {
    TextureDesc base, packed;
};
std::optional<MetalRoughImages> metal_rough_from_spec_gloss(
    Context& ctx, const std::optional<TextureUse>& diffuse, const std::string& dref,
    const std::optional<TextureUse>& sg, const std::string& sref, Vec3 diffuse_factor,
    Vec3 specular_factor, double gloss_factor);

/** KHR_materials_pbrSpecularGlossiness's glossiness (the alpha channel of the texture `use`
 *  at `ref`, times `factor`) as a roughness texture, 1 - glossiness per texel (a 16-bit
 *  greyscale image written once into the embedded-image cache), with the texture's sampler
 *  and uv transform. None when the image cannot be decoded or has no alpha channel (then the
 *  factor alone holds). */
std::optional<TextureDesc> roughness_from_gloss(Context& ctx, const TextureUse& use,
                                                const std::string& ref, double factor);

}  // namespace spangle::gltf
