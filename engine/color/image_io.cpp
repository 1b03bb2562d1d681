#include "color/image_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfTestFile.h>
#include <dlfcn.h>

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <mutex>

#include "core/dynamic_library.h"
#include "core/error.h"
#include "core/files.h"

namespace fs = std::filesystem;

namespace spangle {

namespace {

/** The channels of an EXR to read, in order: R, G, B (as many as exist) when it has R, else Y,
 *  else its channels in the file's (alphabetical) order. */
std::vector<std::string> exr_channels(const Imf::Header& header) {
    const Imf::ChannelList& list = header.channels();
    std::vector<std::string> out;
    if (list.findChannel("R")) {
        for (const char* c : {"R", "G", "B", "A"})
            if (list.findChannel(c)) out.emplace_back(c);
        return out;
    }
    if (list.findChannel("Y")) {
        out.emplace_back("Y");
        if (list.findChannel("A")) out.emplace_back("A");
        return out;
    }
    for (auto it = list.begin(); it != list.end(); ++it) out.emplace_back(it.name());
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

struct OiioModule {
    HeaderFn header = nullptr;
    ReadFn read = nullptr;
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

ImageHeader read_image_header(const std::string& path, const char* what) {
    ImageHeader h;
    if (is_exr(path)) {
        try {
            Imf::InputFile file(path.c_str());
            const Imath::Box2i dw = file.header().dataWindow();
            h.width = dw.max.x - dw.min.x + 1;
            h.height = dw.max.y - dw.min.y + 1;
            h.channels = static_cast<int>(exr_channels(file.header()).size());
        } catch (const std::exception& e) {
            throw_error("cannot read {} '{}': {}", what, path, e.what());
        }
        return h;
    }
    char error[1024] = "";
    if (usable_oiio(path, what)
            .header(path.c_str(), &h.width, &h.height, &h.channels, error, sizeof(error)) != 0)
        throw_error("cannot read {} '{}': {}", what, path, error);
    return h;
}

std::vector<float> read_image(const std::string& path, int max_channels, ImageHeader& header,
                              const char* what) {
    std::vector<float> pixels;
    if (is_exr(path)) {
        try {
            Imf::InputFile file(path.c_str());
            const Imath::Box2i dw = file.header().dataWindow();
            const std::vector<std::string> names = exr_channels(file.header());
            header.width = dw.max.x - dw.min.x + 1;
            header.height = dw.max.y - dw.min.y + 1;
            header.channels = static_cast<int>(names.size());
            const int n = std::min(header.channels, max_channels);
            if (header.width < 1 || header.height < 1 || n < 1)
                throw_error("cannot read {} '{}': it has no pixels or no channels", what, path);
            pixels.assign(static_cast<std::size_t>(header.width) * header.height *
                              static_cast<std::size_t>(n),
                          0.0f);
            Imf::FrameBuffer fb;
            const std::size_t xs = sizeof(float) * static_cast<std::size_t>(n);
            const std::size_t ys = xs * static_cast<std::size_t>(header.width);
            for (int c = 0; c < n; ++c)
                fb.insert(names[static_cast<std::size_t>(c)],
                          Imf::Slice::Make(Imf::FLOAT, pixels.data() + c, dw, xs, ys));
            file.setFrameBuffer(fb);
            file.readPixels(dw.min.y, dw.max.y);
        } catch (const SpangleError&) {
            throw;
        } catch (const std::exception& e) {
            throw_error("cannot read {} '{}': {}", what, path, e.what());
        }
        return pixels;
    }
    const OiioModule& m = usable_oiio(path, what);
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

}  // namespace spangle
