// libspangle_oiio.so: the part of Spangle that links OpenImageIO, opened with dlopen only when
// an image in a format other than OpenEXR is read (engine/color/image_io.cpp). A C interface,
// so that nothing of OpenImageIO's C++ ABI crosses the boundary.

#include <OpenImageIO/imageio.h>

#include <cstddef>
#include <cstdio>
#include <string>

namespace {

void set_error(char* error, std::size_t size, const std::string& message) {
    if (size == 0) return;
    std::snprintf(error, size, "%s", message.c_str());
}

}  // namespace

extern "C" {

/** Version of this interface; the host refuses a module with another one. */
__attribute__((visibility("default"))) int spangle_oiio_abi() {
    return 1;
}

/** Size and channel count of the image at path; 0 on success, else an error message. */
__attribute__((visibility("default"))) int spangle_oiio_header(const char* path, int* width,
                                                               int* height, int* channels,
                                                               char* error, std::size_t size) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        set_error(error, size, OIIO::geterror());
        return 1;
    }
    const OIIO::ImageSpec& spec = in->spec();
    *width = spec.width;
    *height = spec.height;
    *channels = spec.nchannels;
    return 0;
}

/** The first `channels` channels of the image as floats, interleaved, into out (width x height x
 *  channels values, sized from spangle_oiio_header); 0 on success. */
__attribute__((visibility("default"))) int spangle_oiio_read(const char* path, int channels,
                                                             float* out, char* error,
                                                             std::size_t size) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        set_error(error, size, OIIO::geterror());
        return 1;
    }
    if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, out)) {
        set_error(error, size, in->geterror());
        return 1;
    }
    return 0;
}
}
