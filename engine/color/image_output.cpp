#include "color/image_output.h"

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <system_error>

#include "core/error.h"

namespace fs = std::filesystem;

namespace spangle {

const std::vector<std::string>& exr_compressions() {
    static const std::vector<std::string> names = {"none",  "rle", "zips", "zip",  "piz",
                                                   "pxr24", "b44", "b44a", "dwaa", "dwab"};
    return names;
}

namespace {

// The temporary file being written, for remove_image_in_progress() (a signal handler): a fixed
// buffer and a flag, both safe to read there. One write at a time (write_mutex).
std::mutex write_mutex;
char in_progress[4096];
std::atomic<bool> in_progress_set{false};

/** Temporary name beside `path`, unique to this process. */
std::string temp_path_for(const std::string& path) {
    const fs::path p(path);
    return (p.parent_path() / fmt::format(".{}.tmp{}", p.filename().string(), ::getpid())).string();
}

/** Writes pixels with `format` to a temporary file, then renames it onto `path`. */
void write_atomically(const std::string& path, const char* format, const OIIO::ImageSpec& spec,
                      OIIO::TypeDesc pixel_type, const void* pixels) {
    const fs::path dir = fs::path(path).parent_path();
    if (!dir.empty() && !fs::is_directory(dir))
        throw_error("cannot write '{}': directory '{}' does not exist", path, dir.string());
    const std::string tmp = temp_path_for(path);
    std::lock_guard<std::mutex> lock(write_mutex);
    if (tmp.size() < sizeof(in_progress)) {
        std::memcpy(in_progress, tmp.c_str(), tmp.size() + 1);
        in_progress_set = true;
    }
    struct Clear {
        ~Clear() { in_progress_set = false; }
    } clear;
    auto out = OIIO::ImageOutput::create(format);
    if (!out) throw_error("cannot write '{}': {}", path, OIIO::geterror());
    bool ok = out->open(tmp, spec) && out->write_image(pixel_type, pixels) && out->close();
    if (!ok) {
        const std::string why = out->geterror();
        out.reset();
        std::error_code ec;
        fs::remove(tmp, ec);
        throw_error("cannot write '{}': {}", path, why.empty() ? "unknown OpenImageIO error" : why);
    }
    out.reset();
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw_error("cannot move the finished image onto '{}': {}", path, ec.message());
    }
}

}  // namespace

void remove_image_in_progress() noexcept {
    if (in_progress_set.load()) ::unlink(in_progress);
}

void write_exr(const std::string& path, const std::vector<float>& rgb, int width, int height,
               const ColorConfig& color, const ExrOptions& options) {
    const auto& names = exr_compressions();
    // OIIO silently falls back to zip for an unknown name, so it is checked here.
    if (std::find(names.begin(), names.end(), options.compression) == names.end())
        throw_error("unknown EXR compression '{}' (valid: {})", options.compression,
                    fmt::join(names, ", "));
    OIIO::ImageSpec spec(width, height, 3,
                         options.half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"R", "G", "B"};
    spec.attribute("compression", options.compression);
    spec.attribute("oiio:ColorSpace", color.working_space());
    spec.attribute("colorSpace", color.working_space());
    if (auto c = color.working_chromaticities())
        spec.attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), c->xy.data());
    spec.attribute("Software", "Spangle");
    for (const auto& [key, value] : options.metadata) spec.attribute(key, value);
    write_atomically(path, "openexr", spec, OIIO::TypeDesc::FLOAT, rgb.data());
}

void write_png_preview(const std::string& path, const std::vector<float>& rgb, int width,
                       int height, const ColorConfig& color) {
    std::vector<float> display(rgb);
    const std::string disp = color.default_display();
    color.to_display(disp, color.default_view(disp), display.data(), display.size() / 3);
    std::vector<unsigned char> bytes(display.size());
    for (std::size_t i = 0; i < display.size(); ++i) {
        const float v = std::isfinite(display[i]) ? std::clamp(display[i], 0.0f, 1.0f) : 0.0f;
        bytes[i] = static_cast<unsigned char>(std::lround(v * 255.0f));
    }
    OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    write_atomically(path, "png", spec, OIIO::TypeDesc::UINT8, bytes.data());
}

}  // namespace spangle
