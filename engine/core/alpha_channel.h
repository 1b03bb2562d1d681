#pragma once
// Which channel of an image an alpha texture reads (TextureDesc::channel, TextureRef::channel):
// 0 to 3 for R, G, B, A, or one of these.

namespace spangle {

/** Its A when the image has one (grey + alpha, RGBA), else its first channel (a grey mask). */
constexpr int kAlphaAuto = -1;
/** Its A when the image has one, else none: the surface is opaque (glTF's base colour). */
constexpr int kAlphaOrOpaque = 4;

}  // namespace spangle
