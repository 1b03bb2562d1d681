// libspangle_oiio.so: the part of Spangle that links OpenImageIO, opened with dlopen only when
// an image in a format other than OpenEXR is read or a scene uses a texture
// (engine/color/image_io.cpp, engine/shading/texture.cpp). A C interface, so that nothing of
// OpenImageIO's C++ ABI crosses the boundary.
//
// Interface version 2: version 1 (image headers and pixels) plus textures: writing a tiled,
// mip-mapped texture file from pixels (what maketx does) and filtered lookups through
// OpenImageIO's TextureSystem, whose tile cache is bounded in memory.

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>

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
    return 4;  // 3: the lookup's wrap holds s's mode + 4 x t's; 4: spangle_oiio_describe
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

/** What the image's values are: *floating = 1 when its pixels are stored as floating point
 *  (half, float, double: a float TIFF, a PFM, a half .tx), 0 for integers; `space` receives the
 *  colour space the file (or OpenImageIO reading it) names ("oiio:ColorSpace": "sRGB" for an
 *  sRGB-tagged PNG or a .tx maketx made from one, "Linear", ...; empty when none). 0 on success,
 *  else an error message. */
__attribute__((visibility("default"))) int spangle_oiio_describe(const char* path, int* floating,
                                                                 char* space,
                                                                 std::size_t space_size,
                                                                 char* error, std::size_t size) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        set_error(error, size, OIIO::geterror());
        return 1;
    }
    const OIIO::ImageSpec& spec = in->spec();
    // Per-channel formats: floating when the colour channels are (the first one stands for
    // them).
    const OIIO::TypeDesc t = spec.channelformats.empty() ? spec.format : spec.channelformats[0];
    *floating = t.is_floating_point() ? 1 : 0;
    set_error(space, space_size, spec.get_string_attribute("oiio:ColorSpace"));
    return 0;
}

/** The first `channels` channels of the image as floats, interleaved, into out (width x height x
 *  channels values, sized from spangle_oiio_header); 0 on success. */
__attribute__((visibility("default"))) int spangle_oiio_read(const char* path, int channels,
                                                             float* out, char* error,
                                                             std::size_t size) {
    // Alpha as stored: by default OpenImageIO multiplies a PNG's, TGA's or TIFF's straight
    // alpha into its (still sRGB-encoded) colour, so half-transparent texels came out 4x too
    // dark, transparent ones black, and a normal map with height in alpha turned black.
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(path, &config);
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

/** Writes width x height x channels float pixels (row 0 at the top) to `path` as a tiled (64 x 64),
 *  mip-mapped half-float OpenEXR texture. 0 on success. */
__attribute__((visibility("default"))) int spangle_oiio_make_texture(const float* pixels, int width,
                                                                     int height, int channels,
                                                                     const char* path, char* error,
                                                                     std::size_t size) {
    OIIO::ImageSpec spec(width, height, channels, OIIO::TypeDesc::FLOAT);
    OIIO::ImageBuf src(spec, const_cast<float*>(pixels));
    OIIO::ImageSpec config;
    config.tile_width = 64;
    config.tile_height = 64;
    config.tile_depth = 1;
    config.format = OIIO::TypeDesc::HALF;
    config.attribute("compression", "zip");
    // Each level the box-filtered average of the one above: the mean of the image is kept at
    // every level (a sharper filter rings below zero and above one at hard edges, and
    // highlight compression darkens the coarse levels of high-contrast maps).
    config.attribute("maketx:filtername", "box");
    config.attribute("maketx:fixnan", "box3");
    if (!OIIO::ImageBufAlgo::make_texture(OIIO::ImageBufAlgo::MakeTxTexture, src, path, config)) {
        set_error(error, size, OIIO::geterror());
        return 1;
    }
    return 0;
}

/** The process's TextureSystem, made on the first call and kept until the process ends (one
 *  tile cache for every scene a watch session loads; and OpenImageIO 2.4's
 *  TextureSystem::destroy frees it with a mismatched delete, which AddressSanitizer reports).
 *  Its tile cache holds at most max_memory_mb (the latest call's value). NULL on failure. */
__attribute__((visibility("default"))) void* spangle_oiio_texture_system(int max_memory_mb) {
    static OIIO::TextureSystem* const ts = [] {
        OIIO::TextureSystem* t = OIIO::TextureSystem::create(false);
        if (t) {
            t->attribute("autotile", 64);
            t->attribute("automip", 1);
            t->attribute("accept_untiled", 1);
            t->attribute("accept_unmipped", 1);
        }
        return t;
    }();
    if (ts) ts->attribute("max_memory_MB", static_cast<float>(max_memory_mb));
    return ts;
}

/** A handle for the texture file at path and its channel count; NULL with a message on
 *  failure. */
__attribute__((visibility("default"))) void* spangle_oiio_texture_handle(void* system,
                                                                         const char* path,
                                                                         int* channels, char* error,
                                                                         std::size_t size) {
    auto* ts = static_cast<OIIO::TextureSystem*>(system);
    const OIIO::ustring name(path);
    OIIO::TextureSystem::TextureHandle* h = ts->get_texture_handle(name);
    int n = 0;
    if (!h || !ts->get_texture_info(name, 0, OIIO::ustring("channels"), OIIO::TypeDesc::INT, &n) ||
        n < 1) {
        set_error(error, size, ts->geterror());
        return nullptr;
    }
    *channels = n;
    return h;
}

/** Filtered lookups of `count` points: texture coordinates s, t (0 at the left and top edges,
 *  1 at the right and bottom) and their screen-space derivatives; writes `channels` values per
 *  point to out and, when not NULL, their derivatives along s and t. wrap: 0 periodic,
 *  1 clamp, 2 black, 3 mirror, s's mode + 4 x t's; filter: 0 trilinear, 1 anisotropic, 2 closest. 0
 * on success. */
__attribute__((visibility("default"))) int spangle_oiio_texture_lookup(
    void* system, void* handle, int wrap, int filter, int count, const float* s, const float* t,
    const float* dsdx, const float* dtdx, const float* dsdy, const float* dtdy, int channels,
    float* out, float* ds_out, float* dt_out, char* error, std::size_t size) {
    auto* ts = static_cast<OIIO::TextureSystem*>(system);
    auto* h = static_cast<OIIO::TextureSystem::TextureHandle*>(handle);
    OIIO::TextureSystem::Perthread* thread = ts->get_perthread_info();
    OIIO::TextureOpt opt;
    const OIIO::TextureOpt::Wrap modes[] = {
        OIIO::TextureOpt::WrapPeriodic, OIIO::TextureOpt::WrapClamp, OIIO::TextureOpt::WrapBlack,
        OIIO::TextureOpt::WrapMirror};
    // wrap: s's mode + 4 x t's (TextureRef::wraps).
    opt.swrap = modes[wrap & 3];
    opt.twrap = modes[(wrap >> 2) & 3];
    opt.interpmode = OIIO::TextureOpt::InterpBilinear;
    // filter 0: trilinear (one isotropic footprint, the longer axis); 1: anisotropic, up to 8
    // probes along the longer axis (sharper at grazing angles, ~20% more render time on the
    // textured beetle than trilinear, whose cost is that of an untextured material).
    // 2: closest, the texel the point falls in at the finest level (glTF's NEAREST: pixel art).
    if (filter == 1) {
        opt.mipmode = OIIO::TextureOpt::MipModeAniso;
        opt.anisotropic = 8;
    } else if (filter == 2) {
        opt.interpmode = OIIO::TextureOpt::InterpClosest;
        opt.mipmode = OIIO::TextureOpt::MipModeNoMIP;
    } else {
        opt.mipmode = OIIO::TextureOpt::MipModeTrilinear;
    }
    for (int i = 0; i < count; ++i) {
        const std::size_t o = static_cast<std::size_t>(i) * static_cast<std::size_t>(channels);
        if (!ts->texture(h, thread, opt, s[i], t[i], dsdx[i], dtdx[i], dsdy[i], dtdy[i], channels,
                         out + o, ds_out ? ds_out + o : nullptr, dt_out ? dt_out + o : nullptr)) {
            set_error(error, size, ts->geterror());
            return 1;
        }
    }
    return 0;
}
}
