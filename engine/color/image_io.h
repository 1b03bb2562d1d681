#pragma once
// Reading images. OpenEXR files are read with OpenEXR directly; any other format (Radiance HDR,
// PNG, TIFF, ...) through OpenImageIO, which lives in a module (libspangle_oiio.so) opened only
// when such a file is read: linking OpenImageIO costs every process about 120 MiB of resident
// memory (Debian's build pulls in every format library it knows), which a render whose inputs
// and outputs are EXR never needs.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace spangle {

/** Size and channel count of an image file. */
struct ImageHeader {
    int width = 0, height = 0, channels = 0;
};

/** Reads the header only (cheap: for plausibility checks before pixels are allocated). Throws
 *  SpangleError "cannot read <what> '<path>': <the reader's message>". */
ImageHeader read_image_header(const std::string& path, const char* what = "image");

/** Reads the first min(channels, max_channels) channels as floats, interleaved, row 0 at the
 *  top; `header` receives the file's size and its full channel count. Throws SpangleError. */
std::vector<float> read_image(const std::string& path, int max_channels, ImageHeader& header,
                              const char* what = "image");

/** Version of the OpenImageIO module's C interface this build expects. */
inline constexpr int kOiioModuleAbi = 2;

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
