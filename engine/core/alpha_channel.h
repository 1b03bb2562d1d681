#pragma once
// Which channel of an image an alpha texture reads (TextureDesc::channel, TextureRef::channel):
// 0 to 3 for R, G, B, A, or one of these.

namespace spangle {

/** Its A when the image has one (grey + alpha, RGBA), else its first channel (a grey mask). */
constexpr int kAlphaAuto = -1;
/** Its A when the image has one, else none: the surface is opaque (glTF's base colour). */
constexpr int kAlphaOrOpaque = 4;
/** pbrt-v4's float image: its A when the image has one that is not 1 everywhere, else the mean
 *  of its colour channels (a grey image's grey). `channel = "pbrt"` in a scene file. */
constexpr int kAlphaPbrt = 5;
/** A number parameter's texture: the luminance of its colour (Blender's colour-to-number
 *  conversion). `channel = "luminance"` in a scene file. */
constexpr int kLuminance = 6;

}  // namespace spangle
