#include "color/image_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfTestFile.h>
#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>

#include "color/exr_header.h"
#include "core/dynamic_library.h"
#include "core/error.h"
#include "core/files.h"
#include "core/text.h"

namespace fs = std::filesystem;

namespace spangle {

namespace {

/** The channels of an EXR to read, in order: R, G, B, A (those that exist) when it has R; else
 *  the first layer (in the file's order) with all of LAYER.R, LAYER.G and LAYER.B (Blender's and
 *  Nuke's multi-layer files: read alphabetically they came out B, G, R), and its LAYER.A; else
 *  Y (and A); else its channels in the file's (alphabetical) order. */
std::vector<std::string> exr_channels(const Imf::Header& header) {
    const Imf::ChannelList& list = header.channels();
    std::vector<std::string> out;
    const auto take = [&](const std::string& prefix) {
        for (const char* c : {"R", "G", "B", "A"})
            if (list.findChannel(prefix + c)) out.push_back(prefix + c);
    };
    if (list.findChannel("R")) {
        take("");
        return out;
    }
    for (auto it = list.begin(); it != list.end(); ++it) {
        const std::string name = it.name();
        if (name.size() < 3 || name.compare(name.size() - 2, 2, ".R") != 0) continue;
        const std::string prefix = name.substr(0, name.size() - 1);
        if (list.findChannel(prefix + "G") && list.findChannel(prefix + "B")) {
            take(prefix);
            return out;
        }
    }
    if (list.findChannel("Y")) {
        out.emplace_back("Y");
        if (list.findChannel("A")) out.emplace_back("A");
        return out;
    }
    for (auto it = list.begin(); it != list.end(); ++it) out.emplace_back(it.name());
    return out;
}

/** Luminance and chroma (Y, RY, BY: OpenEXR's subsampled YC images): read through RgbaInputFile,
 *  which rebuilds RGB (read as Y alone, they lost their colour). */
bool exr_is_yc(const Imf::Header& header) {
    const Imf::ChannelList& list = header.channels();
    return list.findChannel("Y") && (list.findChannel("RY") || list.findChannel("BY")) &&
           !list.findChannel("R");
}

/** The window an EXR's pixels fill: its display window where the caller places the data window
 *  in it (textures and maps span the display window, black outside the data), else the data
 *  window. */
Imath::Box2i exr_frame(const Imf::Header& header, bool in_display) {
    return in_display ? header.displayWindow() : header.dataWindow();
}

/** The data window's pixels (n channels each) put into `frame` (zeros elsewhere). */
std::vector<float> place_in_frame(const std::vector<float>& data, const Imath::Box2i& dw,
                                  const Imath::Box2i& frame, int n) {
    if (dw == frame) return data;
    const auto fw = static_cast<std::size_t>(frame.max.x - frame.min.x + 1);
    const auto fh = static_cast<std::size_t>(frame.max.y - frame.min.y + 1);
    const auto dwidth = static_cast<std::size_t>(dw.max.x - dw.min.x + 1);
    const auto nc = static_cast<std::size_t>(n);
    std::vector<float> out(fw * fh * nc, 0.0f);
    const int x0 = std::max(dw.min.x, frame.min.x), x1 = std::min(dw.max.x, frame.max.x);
    const int y0 = std::max(dw.min.y, frame.min.y), y1 = std::min(dw.max.y, frame.max.y);
    if (x0 > x1) return out;
    for (int y = y0; y <= y1; ++y)
        std::copy_n(&data[(static_cast<std::size_t>(y - dw.min.y) * dwidth +
                           static_cast<std::size_t>(x0 - dw.min.x)) *
                          nc],
                    static_cast<std::size_t>(x1 - x0 + 1) * nc,
                    &out[(static_cast<std::size_t>(y - frame.min.y) * fw +
                          static_cast<std::size_t>(x0 - frame.min.x)) *
                         nc]);
    return out;
}

bool is_exr(const std::string& path) {
    try {
        return Imf::isOpenExrFile(path.c_str());
    } catch (const std::exception&) {
        return false;
    }
}

// The OpenImageIO module.
using AbiFn = int (*)();
using HeaderFn = int (*)(const char*, int*, int*, int*, char*, std::size_t);
using ReadFn = int (*)(const char*, int, float*, char*, std::size_t);
using DescribeFn = int (*)(const char*, int*, char*, std::size_t, char*, std::size_t);

struct OiioModule {
    HeaderFn header = nullptr;
    ReadFn read = nullptr;
    DescribeFn describe = nullptr;
    OiioTextureApi texture;
    std::string error;  ///< why it could not be opened
};

const OiioModule& oiio_module() {
    static OiioModule module;
    static std::once_flag once;
    std::call_once(once, [] {
        std::string tried;
        for (const std::string& path : oiio_module_locations()) {
            std::error_code ec;
            if (!fs::is_regular_file(path, ec)) {
                tried += (tried.empty() ? "" : ", ") + path;
                continue;
            }
            void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
            if (!handle) {
                module.error = fmt::format("cannot open '{}': {}", path, dlerror());
                return;
            }
            AbiFn abi = nullptr;
            OiioTextureApi& t = module.texture;
            const bool complete =
                bind_symbol(handle, "spangle_oiio_abi", abi) && abi() == kOiioModuleAbi &&
                bind_symbol(handle, "spangle_oiio_header", module.header) &&
                bind_symbol(handle, "spangle_oiio_read", module.read) &&
                bind_symbol(handle, "spangle_oiio_describe", module.describe) &&
                bind_symbol(handle, "spangle_oiio_make_texture", t.make_texture) &&
                bind_symbol(handle, "spangle_oiio_texture_system", t.create) &&
                bind_symbol(handle, "spangle_oiio_texture_handle", t.handle) &&
                bind_symbol(handle, "spangle_oiio_texture_lookup", t.lookup);
            if (!complete) {
                module = OiioModule{};
                module.error = fmt::format("'{}' is not this version's OpenImageIO module", path);
            }
            return;  // kept open for the life of the process
        }
        module.error =
            fmt::format("its module libspangle_oiio.so was not found (looked at {})", tried);
    });
    return module;
}

const OiioModule& usable_oiio(const std::string& path, const char* what) {
    const OiioModule& m = oiio_module();
    if (!m.header)
        throw_error(
            "cannot read {} '{}': images other than OpenEXR are read through OpenImageIO, but "
            "{}; convert the image to EXR (oiiotool '{}' -o image.exr)",
            what, path, m.error, path);
    return m;
}

}  // namespace

const OiioTextureApi& oiio_texture_api(const std::string& path) {
    const OiioModule& m = oiio_module();
    if (!m.texture.lookup)
        throw_error(
            "cannot use texture '{}': textures are filtered by OpenImageIO's TextureSystem, but {}",
            path, m.error);
    return m.texture;
}

std::vector<std::string> oiio_module_locations() {
    std::vector<std::string> out;
    const std::string exe = executable_dir();
    if (!exe.empty()) {
        out.push_back((fs::path(exe) / "libspangle_oiio.so").string());
        out.push_back((fs::path(exe) / ".." / "lib" / "spangle" / "libspangle_oiio.so")
                          .lexically_normal()
                          .string());
    }
    return out;
}

namespace {

/** Throws when `path` is a PNG file whose chunks run past its end or that has no IEND chunk (a
 *  copy or download cut short): libpng printed its own lines for it on stderr beside the error
 *  ("libpng error: IDAT: Read error: hit end of file"). Chunk headers only; nothing decoded. */
void check_png_whole(const std::string& path, const char* what) {
    std::ifstream in(path, std::ios::binary);
    unsigned char b[8];
    static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    if (!in.read(reinterpret_cast<char*>(b), 8) || std::memcmp(b, kSignature, 8) != 0) return;
    std::error_code ec;
    const uintmax_t size = fs::file_size(path, ec);
    if (ec) return;
    uintmax_t at = 8;
    while (at + 8 <= size) {
        in.seekg(static_cast<std::streamoff>(at));
        if (!in.read(reinterpret_cast<char*>(b), 8)) return;
        const uintmax_t length = (uintmax_t{b[0]} << 24) | (uintmax_t{b[1]} << 16) |
                                 (uintmax_t{b[2]} << 8) | uintmax_t{b[3]};
        const std::string type(reinterpret_cast<const char*>(b + 4), 4);
        if (at + 12 + length > size)
            throw_error(
                "cannot read {} '{}': the PNG file is cut short ({} bytes; its {} chunk "
                "at byte {} needs {})",
                what, path, size, type, at, at + 12 + length);
        if (type == "IEND") return;
        at += 12 + length;
    }
    throw_error("cannot read {} '{}': the PNG file is cut short ({} bytes, and no IEND chunk)",
                what, path, size);
}

}  // namespace

/** Throws "cannot read <what> '<path>': <the system's reason>" when the file cannot be opened
 *  for reading (the readers said "Could not open file", not why: permission denied). */
void check_readable(const std::string& path, const char* what) {
    if (::access(path.c_str(), R_OK) != 0)
        throw_error("cannot read {} '{}': {}", what, path, std::strerror(errno));
}

ImageHeader read_image_header(const std::string& path, const char* what, bool display_window) {
    check_readable(path, what);
    ImageHeader h;
    if (is_exr(path)) {
        try {
            Imf::InputFile file(path.c_str());
            const Imath::Box2i dw = exr_frame(file.header(), display_window);
            h.width = dw.max.x - dw.min.x + 1;
            h.height = dw.max.y - dw.min.y + 1;
            h.channels = exr_is_yc(file.header())
                             ? (file.header().channels().findChannel("A") ? 4 : 3)
                             : static_cast<int>(exr_channels(file.header()).size());
        } catch (const std::exception& e) {
            throw_error("cannot read {} '{}': {}", what, path, e.what());
        }
        return h;
    }
    const OiioModule& m = usable_oiio(path, what);
    // A PNG cut before its first IDAT: its header reads, and libpng printed its own lines
    // beside the error (textures read the header first).
    check_png_whole(path, what);
    char error[1024] = "";
    if (m.header(path.c_str(), &h.width, &h.height, &h.channels, error, sizeof(error)) != 0)
        throw_error("cannot read {} '{}': {}", what, path, error);
    return h;
}

std::vector<float> read_image(const std::string& path, int max_channels, ImageHeader& header,
                              const char* what, bool display_window) {
    check_readable(path, what);
    std::vector<float> pixels;
    if (is_exr(path)) {
        try {
            Imf::InputFile file(path.c_str());
            const Imath::Box2i dw = file.header().dataWindow();
            const Imath::Box2i frame = exr_frame(file.header(), display_window);
            const int dwidth = dw.max.x - dw.min.x + 1, dheight = dw.max.y - dw.min.y + 1;
            header.width = frame.max.x - frame.min.x + 1;
            header.height = frame.max.y - frame.min.y + 1;
            if (dwidth < 1 || dheight < 1 || header.width < 1 || header.height < 1)
                throw_error("cannot read {} '{}': it has no pixels", what, path);
            const auto count = static_cast<std::size_t>(dwidth) * static_cast<std::size_t>(dheight);
            if (exr_is_yc(file.header())) {
                const bool alpha = file.header().channels().findChannel("A") != nullptr;
                header.channels = alpha ? 4 : 3;
                const int n = std::min(header.channels, max_channels);
                std::vector<Imf::Rgba> rgba(count);
                Imf::RgbaInputFile yc(path.c_str());
                yc.setFrameBuffer(
                    rgba.data() - dw.min.x - static_cast<std::ptrdiff_t>(dw.min.y) * dwidth, 1,
                    static_cast<std::size_t>(dwidth));
                yc.readPixels(dw.min.y, dw.max.y);
                pixels.resize(count * static_cast<std::size_t>(n));
                for (std::size_t i = 0; i < count; ++i) {
                    const float v[4] = {rgba[i].r, rgba[i].g, rgba[i].b, rgba[i].a};
                    for (int c = 0; c < n; ++c)
                        pixels[i * static_cast<std::size_t>(n) + static_cast<std::size_t>(c)] =
                            v[c];
                }
                return place_in_frame(pixels, dw, frame, n);
            }
            const std::vector<std::string> names = exr_channels(file.header());
            header.channels = static_cast<int>(names.size());
            const int n = std::min(header.channels, max_channels);
            if (n < 1) throw_error("cannot read {} '{}': it has no channels", what, path);
            pixels.assign(count * static_cast<std::size_t>(n), 0.0f);
            Imf::FrameBuffer fb;
            const std::size_t xs = sizeof(float) * static_cast<std::size_t>(n);
            const std::size_t ys = xs * static_cast<std::size_t>(dwidth);
            for (int c = 0; c < n; ++c)
                fb.insert(names[static_cast<std::size_t>(c)],
                          Imf::Slice::Make(Imf::FLOAT, pixels.data() + c, dw, xs, ys));
            file.setFrameBuffer(fb);
            file.readPixels(dw.min.y, dw.max.y);
            pixels = place_in_frame(pixels, dw, frame, n);
        } catch (const SpangleError&) {
            throw;
        } catch (const std::exception& e) {
            throw_error("cannot read {} '{}': {}", what, path, e.what());
        }
        return pixels;
    }
    const OiioModule& m = usable_oiio(path, what);
    check_png_whole(path, what);
    char error[1024] = "";
    if (m.header(path.c_str(), &header.width, &header.height, &header.channels, error,
                 sizeof(error)) != 0)
        throw_error("cannot read {} '{}': {}", what, path, error);
    const int n = std::min(header.channels, max_channels);
    if (header.width < 1 || header.height < 1 || n < 1)
        throw_error("cannot read {} '{}': it has no pixels or no channels", what, path);
    pixels.assign(
        static_cast<std::size_t>(header.width) * header.height * static_cast<std::size_t>(n), 0.0f);
    if (m.read(path.c_str(), n, pixels.data(), error, sizeof(error)) != 0)
        throw_error("cannot read {} '{}': {}", what, path, error);
    return pixels;
}

void require_exr_file(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw_error("'{}' does not exist", path);
    if (!Imf::isOpenExrFile(path.c_str())) throw_error("'{}' is not an OpenEXR file", path);
}

std::string exr_named_space(const std::string& path) {
    try {
        if (!Imf::isOpenExrFile(path.c_str())) return "";
        Imf::InputFile in(path.c_str());
        for (const char* name : {"colorSpace", "oiio:ColorSpace"})
            if (std::string v = string_attribute(in.header(), name); !v.empty()) return v;
    } catch (const std::exception&) {
        // Unreadable here: the reader proper says why.
    }
    return "";
}

std::string default_image_space(const std::string& path,
                                const std::function<bool(const std::string&)>& known,
                                std::string& unknown) {
    unknown.clear();
    const std::string named = exr_named_space(path);
    if (!named.empty()) {
        if (known(named)) return named;
        unknown = named;
    }
    return usual_image_space(path);
}

std::string usual_image_space(const std::string& path) {
    // The file's own first bytes first: an EXR or a Radiance HDR is linear whatever it is
    // called (a PNG named .exr was read as linear, an EXR named .png sRGB-decoded).
    if (std::FILE* f = std::fopen(path.c_str(), "rb")) {
        char head[10] = {};
        const std::size_t got = std::fread(head, 1, sizeof(head), f);
        std::fclose(f);
        const bool exr = got >= 4 && static_cast<unsigned char>(head[0]) == 0x76 &&
                         head[1] == 0x2f && head[2] == 0x31 && head[3] == 0x01;
        const bool radiance = got >= 2 && head[0] == '#' && head[1] == '?';
        if (exr || radiance) return "lin_rec709";
        // Other formats by their pixels: floating-point values are linear (a float TIFF or PFM
        // map was sRGB-decoded: 22x too bright at 10), integers sRGB unless the file says
        // linear (OpenImageIO's name for it: a PNG of gamma 1, a .tx maketx was told is
        // linear).
        const OiioModule& m = oiio_module();
        if (got >= 4 && m.describe) {
            int floating = 0;
            char space[128] = {};
            char error[256] = {};
            if (m.describe(path.c_str(), &floating, space, sizeof(space), error, sizeof(error)) ==
                0) {
                if (floating != 0) return "lin_rec709";
                const std::string said = ascii_lower(space);
                return said == "linear" || said == "lin_rec709" || said == "scene_linear"
                           ? "lin_rec709"
                           : "srgb_texture";
            }
        }
        if (got >= 4) {
            const std::string ext = fs::path(path).extension().string();
            return ext == ".tx" || ext == ".TX" ? "lin_rec709" : "srgb_texture";
        }
    }
    const std::string ext = ascii_lower(fs::path(path).extension().string());
    return ext == ".exr" || ext == ".hdr" || ext == ".tx" ? "lin_rec709" : "srgb_texture";
}

}  // namespace spangle
