#pragma once
// Reading images. OpenEXR files are read with OpenEXR directly; any other format (Radiance HDR,
// PNG, TIFF, ...) through OpenImageIO, which lives in a module (libspangle_oiio.so) opened only
// when such a file is read: linking OpenImageIO costs every process about 120 MiB of resident
// memory (Debian's build pulls in every format library it knows), which a render whose inputs
// and outputs are EXR never needs.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace spangle {

/** What an image file's header may claim before its pixels are allocated: at most this many
 *  pixels per byte of the file (a 157-byte HDR claiming 32768x16384 took 6 GB before failing).
 *  Deflate packs at most about 1032 bytes into one and a 1-bit PNG 8 pixels into a byte, so a
 *  valid 1-bit mask reaches about 8000 (4096 refused one); WebP's and EXR's run lengths go
 *  further. Allocation is bounded by the memory check besides. */
inline constexpr double kMaxPixelsPerByte = 65536.0;

/** Size and channel count of an image file. */
struct ImageHeader {
    int width = 0, height = 0, channels = 0;
};

/** Reads the header only (cheap: for plausibility checks before pixels are allocated). Throws
 *  SpangleError "cannot read <what> '<path>': <the reader's message>". */
ImageHeader read_image_header(const std::string& path, const char* what = "image",
                              bool display_window = false);

/** Reads the first min(channels, max_channels) channels as floats, interleaved, row 0 at the
 *  top; `header` receives the file's size and its full channel count. An EXR's channels: R, G,
 *  B, A; a layer's LAYER.R, ...; Y (and A); or luminance-chroma (Y, RY, BY) as RGB. With
 *  `display_window` an EXR's image is its display window, black where its data window does not
 *  reach (as textures and environment maps take it: a crop part of a render spans the frame it
 *  came from); else its data window. Alpha is read as stored (straight, never multiplied into
 *  the colour). Throws SpangleError. */
std::vector<float> read_image(const std::string& path, int max_channels, ImageHeader& header,
                              const char* what = "image", bool display_window = false);

/** The colour space a file's values are usually in when a scene names none, from what it
 *  holds, not its name: lin_rec709 for OpenEXR and Radiance HDR files and for every file whose
 *  pixels are floating point (a float TIFF, a PFM, a half .tx); for files of 8- or 16-bit
 *  pixels, the space the file says through OpenImageIO's "oiio:ColorSpace" when it is sRGB
 *  (srgb_texture) or linear (lin_rec709), else srgb_texture. Without the OpenImageIO module, by
 *  extension (.tx linear). */
std::string usual_image_space(const std::string& path);

/** The colour space an OpenEXR file names in its header ("colorSpace", else
 *  "oiio:ColorSpace", as Spangle, OpenImageIO and others write them); empty for other files,
 *  files that name none, and files that cannot be read. */
std::string exr_named_space(const std::string& path);

/** The colour space to read `path` in when the scene names none: the one its EXR header names
 *  when `known(name)` (the config has it), else usual_image_space(path); `unknown` receives a
 *  name the header gives that the config lacks (else it is cleared). */
std::string default_image_space(const std::string& path,
                                const std::function<bool(const std::string&)>& known,
                                std::string& unknown);

/** Throws SpangleError unless `path` is an OpenEXR file ("does not exist" or "is not an OpenEXR
 *  file"), for the commands that read Spangle's EXRs back (merge, flicker). */
void require_exr_file(const std::string& path);

/** Version of the OpenImageIO module's C interface this build expects. */
inline constexpr int kOiioModuleAbi = 4;

/** The OpenImageIO module's texture functions (see engine/oiio/oiio_module.cpp for each). */
struct OiioTextureApi {
    int (*make_texture)(const float* pixels, int width, int height, int channels, const char* path,
                        char* error, std::size_t size) = nullptr;
    void* (*create)(int max_memory_mb) = nullptr;  ///< the process's texture system
    void* (*handle)(void* system, const char* path, int* channels, char* error,
                    std::size_t size) = nullptr;
    int (*lookup)(void* system, void* handle, int wrap, int filter, int count, const float* s,
                  const float* t, const float* dsdx, const float* dtdx, const float* dsdy,
                  const float* dtdy, int channels, float* out, float* ds_out, float* dt_out,
                  char* error, std::size_t size) = nullptr;
};

/** The module's texture functions, opening the module on first use. Throws SpangleError
 *  ("cannot use texture '<path>': ...") when it cannot be opened. */
const OiioTextureApi& oiio_texture_api(const std::string& path);

/** Where the OpenImageIO module is looked for (beside the binary, then ../lib/spangle). */
std::vector<std::string> oiio_module_locations();

}  // namespace spangle
