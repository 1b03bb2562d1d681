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

/** The mean linear Rec.709 colour of texture `index`'s image (sRGB decoded), or none when it
 *  cannot be decoded. */
std::optional<Vec3> texture_mean(Context& ctx, int index);

/** KHR_materials_pbrSpecularGlossiness's glossiness (the alpha channel of the texture `use`
 *  at `ref`, times `factor`) as a roughness texture, 1 - glossiness per texel (a 16-bit
 *  greyscale image written once into the embedded-image cache), with the texture's sampler
 *  and uv transform. None when the image cannot be decoded or has no alpha channel (then the
 *  factor alone holds). */
std::optional<TextureDesc> roughness_from_gloss(Context& ctx, const TextureUse& use,
                                                const std::string& ref, double factor);

}  // namespace spangle::gltf
