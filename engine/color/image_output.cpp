#include "color/image_output.h"

#include <Imath/half.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <functional>
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
/** The temporary files being written, for remove_image_in_progress() to unlink from a signal
 *  handler: a few fixed slots (images may be written concurrently), each claimed by one write. */
struct InProgress {
    std::atomic<bool> claimed{false};
    std::atomic<bool> set{false};
    char path[4096];
};
InProgress in_progress[4];
std::mutex slot_mutex;
std::condition_variable slot_freed;

/** Claims a slot for `tmp` (waiting while all are busy); released when it goes out of scope. */
class InProgressSlot {
public:
    explicit InProgressSlot(const std::string& tmp) {
        std::unique_lock<std::mutex> lock(slot_mutex);
        for (;;) {
            for (InProgress& s : in_progress)
                if (!s.claimed.load()) {
                    slot_ = &s;
                    break;
                }
            if (slot_) break;
            slot_freed.wait(lock);
        }
        slot_->claimed = true;
        if (tmp.size() < sizeof(slot_->path)) {
            std::memcpy(slot_->path, tmp.c_str(), tmp.size() + 1);
            slot_->set = true;
        }
    }
    ~InProgressSlot() {
        slot_->set = false;
        {
            std::lock_guard<std::mutex> lock(slot_mutex);
            slot_->claimed = false;
        }
        slot_freed.notify_one();
    }
    InProgressSlot(const InProgressSlot&) = delete;
    InProgressSlot& operator=(const InProgressSlot&) = delete;

private:
    InProgress* slot_ = nullptr;
};

/** Temporary name beside `path`, unique to this process. */
std::string temp_path_for(const std::string& path) {
    static std::atomic<unsigned> counter{0};
    const fs::path p(path);
    return (p.parent_path() /
            fmt::format(".{}.tmp{}.{}", p.filename().string(), ::getpid(), counter++))
        .string();
}

/** Rows written per strip: images are converted and written a strip at a time, so writing
 *  needs a strip's worth of memory beside the film, not a converted copy of the whole image. */
constexpr int kStripRows = 256;

/** Opens a temporary file beside `path` with `format`, lets write_pixels fill it (it returns
 *  false on an OpenImageIO error), closes it, checks it is not empty, and renames it onto
 *  `path`. Anything that fails removes the temporary file and throws SpangleError. */
void write_atomically(const std::string& path, const char* format, const OIIO::ImageSpec& spec,
                      const std::function<bool(OIIO::ImageOutput&)>& write_pixels) {
    const fs::path dir = fs::path(path).parent_path();
    if (!dir.empty() && !fs::is_directory(dir))
        throw_error("cannot write '{}': directory '{}' does not exist", path, dir.string());
    const std::string tmp = temp_path_for(path);
    const InProgressSlot slot(tmp);
    auto out = OIIO::ImageOutput::create(format);
    if (!out) throw_error("cannot write '{}': {}", path, OIIO::geterror());
    bool ok = out->open(tmp, spec) && write_pixels(*out) && out->close();
    std::error_code ec;
    if (!ok) {
        const std::string why = out->geterror();
        out.reset();
        fs::remove(tmp, ec);
        throw_error("cannot write '{}': {}", path, why.empty() ? "unknown OpenImageIO error" : why);
    }
    out.reset();
    // A full disk can let every call succeed and still leave nothing: never rename that in.
    if (fs::file_size(tmp, ec) == 0 || ec) {
        fs::remove(tmp, ec);
        throw_error("cannot write '{}': the file came out empty (is the disk full?)", path);
    }
    fs::rename(tmp, path, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw_error("cannot move the finished image onto '{}': {}", path, ec.message());
    }
}

}  // namespace

void remove_image_in_progress() noexcept {
    for (const InProgress& s : in_progress)
        if (s.set.load()) ::unlink(s.path);
}

std::size_t write_exr(const std::string& path, const std::vector<float>& rgb, int width, int height,
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
    std::atomic<std::size_t> overflow{0};
    const auto w = static_cast<std::size_t>(width);
    write_atomically(path, "openexr", spec, [&](OIIO::ImageOutput& out) {
        std::vector<Imath::half> halves;
        for (int y0 = 0; y0 < height; y0 += kStripRows) {
            const int y1 = std::min(height, y0 + kStripRows);
            const float* rows = rgb.data() + static_cast<std::size_t>(y0) * w * 3;
            if (!options.half) {
                if (!out.write_scanlines(y0, y1, 0, OIIO::TypeDesc::FLOAT, rows)) return false;
                continue;
            }
            // Converted here, in parallel, rather than by OpenImageIO one value at a time.
            halves.resize(static_cast<std::size_t>(y1 - y0) * w * 3);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, halves.size(), 1 << 16),
                              [&](const tbb::blocked_range<std::size_t>& r) {
                                  std::size_t over = 0;
                                  for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                      halves[i] = Imath::half(rows[i]);
                                      over += std::isfinite(rows[i]) && halves[i].isInfinity();
                                  }
                                  overflow += over;
                              });
            if (!out.write_scanlines(y0, y1, 0, OIIO::TypeDesc::HALF, halves.data())) return false;
        }
        return true;
    });
    return overflow;
}

namespace {

/** 8-bit display values of rows [row0, row1) of the image (row0 a multiple of the block)
 *  through the config's default display and view. */
std::vector<unsigned char> display_bytes(const std::vector<float>& rgb, int width, int height,
                                         int row0, int row1, const ColorConfig& color,
                                         uint32_t block_size) {
    const std::string disp = color.default_display();
    const std::string view = color.default_view(disp);
    const auto w = static_cast<std::size_t>(width);
    const auto block = static_cast<std::size_t>(std::max(1u, block_size));
    // Converted in bands of rows, a few at a time per thread: the preview needs its 3 bytes per
    // pixel and a band's floats, not a float copy of the whole image. Block-constant images
    // (preview passes) convert one pixel per block.
    const std::size_t band = std::max<std::size_t>(block, (32 / block) * block);
    const auto first = static_cast<std::size_t>(row0), last = static_cast<std::size_t>(row1);
    const auto bands = (last - first + band - 1) / band;
    std::vector<unsigned char> bytes((last - first) * w * 3);
    tbb::parallel_for(std::size_t{0}, bands, [&](std::size_t b) {
        const std::size_t y0 = first + b * band, y1 = std::min(y0 + band, last);
        std::vector<float> buf;
        std::vector<std::size_t> from;  // source pixel of each converted value
        for (std::size_t y = y0; y < y1; y += block) {
            const std::size_t sy = std::min(y + block / 2, static_cast<std::size_t>(height) - 1);
            for (std::size_t x = 0; x < w; x += block) {
                from.push_back(sy * w + std::min(x + block / 2, w - 1));
            }
        }
        buf.resize(3 * from.size());
        for (std::size_t i = 0; i < from.size(); ++i)
            for (std::size_t c = 0; c < 3; ++c) buf[3 * i + c] = rgb[3 * from[i] + c];
        color.to_display(disp, view, buf.data(), from.size());
        for (float& v : buf) v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
        const std::size_t blocks_x = (w + block - 1) / block;
        for (std::size_t y = y0; y < y1; ++y) {
            const std::size_t row = (y - y0) / block;
            for (std::size_t x = 0; x < w; ++x) {
                const float* v = &buf[3 * (row * blocks_x + x / block)];
                for (std::size_t c = 0; c < 3; ++c)
                    bytes[3 * ((y - first) * w + x) + c] =
                        static_cast<unsigned char>(std::lround(v[c] * 255.0f));
            }
        }
    });
    return bytes;
}

OIIO::ImageSpec png_spec(int width, int height, const PngOptions& options) {
    OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    spec.attribute("png:compressionLevel", std::clamp(options.compression_level, 0, 9));
    return spec;
}

}  // namespace

void write_png_preview(const std::string& path, const std::vector<float>& rgb, int width,
                       int height, const ColorConfig& color, const PngOptions& options) {
    write_atomically(path, "png", png_spec(width, height, options), [&](OIIO::ImageOutput& out) {
        for (int y0 = 0; y0 < height; y0 += kStripRows) {
            const int y1 = std::min(height, y0 + kStripRows);
            const std::vector<unsigned char> bytes =
                display_bytes(rgb, width, height, y0, y1, color, options.block);
            if (!out.write_scanlines(y0, y1, 0, OIIO::TypeDesc::UINT8, bytes.data())) return false;
        }
        return true;
    });
}

std::string encode_png_preview(const std::vector<float>& rgb, int width, int height,
                               const ColorConfig& color, const PngOptions& options) {
    const std::vector<unsigned char> bytes =
        display_bytes(rgb, width, height, 0, height, color, options.block);
    std::vector<unsigned char> file;
    OIIO::Filesystem::IOVecOutput proxy(file);
    auto out = OIIO::ImageOutput::create("png");
    if (!out) throw_error("cannot encode a PNG: {}", OIIO::geterror());
    const bool ok = out->set_ioproxy(&proxy) &&
                    out->open("preview.png", png_spec(width, height, options)) &&
                    out->write_image(OIIO::TypeDesc::UINT8, bytes.data()) && out->close();
    if (!ok) throw_error("cannot encode a PNG: {}", out->geterror());
    return std::string(file.begin(), file.end());
}

}  // namespace spangle
