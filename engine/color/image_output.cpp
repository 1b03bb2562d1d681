#include "color/image_output.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFloatVectorAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <mutex>
#include <system_error>

#include "color/temporary_files.h"
#include "core/error.h"

namespace fs = std::filesystem;

namespace spangle {

const std::vector<std::string>& exr_compressions() {
    static const std::vector<std::string> names = {"none",  "rle", "zips", "zip",  "piz",
                                                   "pxr24", "b44", "b44a", "dwaa", "dwab"};
    return names;
}

bool lossy_for_floats(const std::string& compression) {
    return compression == "pxr24" || compression == "dwaa" || compression == "dwab";
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
InProgress in_progress[8];
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

}  // namespace

std::string output_target(const std::string& given) {
    // An output that is a symbolic link is written where it points (the rename replaced the
    // link with a file of its own and the target was never written), even a dangling one.
    fs::path target = given;
    std::error_code link_ec;
    for (int hops = 0; hops < 40 && fs::is_symlink(target, link_ec); ++hops) {
        const fs::path to = fs::read_symlink(target, link_ec);
        if (link_ec) break;
        target = to.is_absolute() ? to : target.parent_path() / to;
    }
    return target.string();
}

namespace {

/** Rows written per strip: images are converted and written a strip at a time, so writing
 *  needs a strip's worth of memory beside the film, not a converted copy of the whole image. */
constexpr int kStripRows = 256;

/** Lets write_file write a temporary file beside `path` (it throws SpangleError or any
 *  std::exception on failure), checks the file is not empty, and renames it onto `path`.
 *  Anything that fails removes the temporary file and throws SpangleError. */
void write_atomically(const std::string& given,
                      const std::function<void(const std::string&)>& write_file) {
    const std::string path = output_target(given);
    const fs::path dir = fs::path(path).parent_path();
    if (!dir.empty() && !fs::is_directory(dir))
        throw_error("cannot write '{}': directory '{}' does not exist", path, dir.string());
    const std::string tmp = temporary_path_for(path);
    const InProgressSlot slot(tmp);
    const TemporaryLock lock(tmp);
    std::error_code ec;
    try {
        write_file(tmp);
    } catch (const std::exception& e) {
        fs::remove(tmp, ec);
        const std::string why = e.what();
        // Messages of our own already name the file.
        if (dynamic_cast<const SpangleError*>(&e)) throw;
        throw_error("cannot write '{}': {}", path, why.empty() ? "unknown error" : why);
    }
    // A full disk can let every call succeed and still leave nothing: never rename that in.
    if (fs::file_size(tmp, ec) == 0 || ec) {
        fs::remove(tmp, ec);
        throw_error("cannot write '{}': the file came out empty (is the disk full?)", path);
    }
    fs::rename(tmp, path, ec);
    if (ec) {
        const std::string why = fs::is_directory(path) ? "it is a folder" : ec.message();
        fs::remove(tmp, ec);  // (overwrites ec: the reason is kept above)
        throw_error("cannot move the finished image onto '{}': {}", path, why);
    }
}

Imf::Compression exr_compression(const std::string& name) {
    static const std::pair<const char*, Imf::Compression> table[] = {
        {"none", Imf::NO_COMPRESSION},   {"rle", Imf::RLE_COMPRESSION},
        {"zips", Imf::ZIPS_COMPRESSION}, {"zip", Imf::ZIP_COMPRESSION},
        {"piz", Imf::PIZ_COMPRESSION},   {"pxr24", Imf::PXR24_COMPRESSION},
        {"b44", Imf::B44_COMPRESSION},   {"b44a", Imf::B44A_COMPRESSION},
        {"dwaa", Imf::DWAA_COMPRESSION}, {"dwab", Imf::DWAB_COMPRESSION}};
    for (const auto& [n, c] : table)
        if (name == n) return c;
    return Imf::ZIP_COMPRESSION;  // validated before
}

}  // namespace

void write_file_atomically(const std::string& path,
                           const std::function<void(const std::string&)>& write_file) {
    write_atomically(path, write_file);
}

TemporaryInProgress::TemporaryInProgress(const std::string& tmp) : slot_(new InProgressSlot(tmp)) {}

TemporaryInProgress::~TemporaryInProgress() {
    delete static_cast<InProgressSlot*>(slot_);
}

bool remove_image_in_progress() noexcept {
    bool any = false;
    for (const InProgress& s : in_progress)
        if (s.set.load()) any = ::unlink(s.path) == 0 || any;
    return any;
}

const std::vector<std::string>& sample_sum_channels() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> n;
        for (const char* c : {"R", "G", "B"})
            for (int word = 0; word < 4; ++word)
                n.push_back(fmt::format("spangle_sum.{}.{}", c, word));
        return n;
    }();
    return names;
}

std::size_t write_exr(const std::string& path, const std::vector<float>& rgb, int width, int height,
                      const ColorConfig& color, const ExrOptions& options) {
    const auto& names = exr_compressions();
    // OIIO silently falls back to zip for an unknown name, so it is checked here.
    if (std::find(names.begin(), names.end(), options.compression) == names.end())
        throw_error("unknown EXR compression '{}' (valid: {})", options.compression,
                    fmt::join(names, ", "));
    const int dw = options.display_width > 0 ? options.display_width : width;
    const int dh = options.display_height > 0 ? options.display_height : height;
    const int ox = options.display_width > 0 ? options.origin_x : 0;
    const int oy = options.display_height > 0 ? options.origin_y : 0;
    if (ox < 0 || oy < 0 || ox + width > dw || oy + height > dh)
        throw_error("cannot write '{}': a {}x{} image at ({}, {}) is not inside a {}x{} frame",
                    path, width, height, ox, oy, dw, dh);
    Imf::Header header(
        Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(dw - 1, dh - 1)),
        Imath::Box2i(Imath::V2i(ox, oy), Imath::V2i(ox + width - 1, oy + height - 1)));
    header.compression() = exr_compression(options.compression);
    const Imf::PixelType type = options.half ? Imf::HALF : Imf::FLOAT;
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(type));
    const std::size_t lc = options.layers ? options.layer_names.size() : 0;
    if (options.layers && options.layers->size() != lc * static_cast<std::size_t>(width) *
                                                        static_cast<std::size_t>(height))
        throw_error("cannot write '{}': {} layer values for {} channels of {}x{} pixels", path,
                    options.layers->size(), lc, width, height);
    // Data channels (positions, ids) are 32-bit floats whatever the beauty's precision.
    const auto layer_type = [&](std::size_t c) {
        return c < options.layer_full_float.size() && options.layer_full_float[c] ? Imf::FLOAT
                                                                                  : type;
    };
    for (std::size_t c = 0; c < lc; ++c)
        header.channels().insert(options.layer_names[c], Imf::Channel(layer_type(c)));
    if (options.sums) {
        if (options.sums->size() != 3 * static_cast<std::size_t>(width) * height)
            throw_error("cannot write '{}': {} sums for {}x{} pixels", path, options.sums->size(),
                        width, height);
        for (const std::string& n : sample_sum_channels())
            header.channels().insert(n, Imf::Channel(Imf::UINT));
    }
    // The colour space by name (OpenImageIO's and the OpenEXR convention's attribute), and as
    // chromaticities when the config lets us derive them.
    header.insert("oiio:ColorSpace", Imf::StringAttribute(color.working_space()));
    header.insert("colorSpace", Imf::StringAttribute(color.working_space()));
    if (auto c = color.working_chromaticities()) {
        const auto& xy = c->xy;
        Imf::addChromaticities(
            header, Imf::Chromaticities(Imath::V2f(xy[0], xy[1]), Imath::V2f(xy[2], xy[3]),
                                        Imath::V2f(xy[4], xy[5]), Imath::V2f(xy[6], xy[7])));
    }
    header.insert("Software", Imf::StringAttribute("Spangle"));
    for (const auto& [key, value] : options.metadata)
        header.insert(key, Imf::StringAttribute(value));
    for (const auto& [key, value] : options.floats) header.insert(key, Imf::FloatAttribute(value));
    for (const auto& [key, values] : options.float_vectors)
        header.insert(key, Imf::FloatVectorAttribute(values));
    for (const auto& [key, m] : options.matrices)
        header.insert(key, Imf::M44fAttribute(Imath::M44f(m[0], m[1], m[2], m[3], m[4], m[5], m[6],
                                                          m[7], m[8], m[9], m[10], m[11], m[12],
                                                          m[13], m[14], m[15])));
    std::atomic<std::size_t> overflow{0};
    const auto w = static_cast<std::size_t>(width);
    write_atomically(path, [&](const std::string& tmp) {
        Imf::OutputFile out(tmp.c_str(), header);
        std::vector<Imath::half> halves, layer_halves;
        std::vector<uint32_t> words;
        for (int y0 = 0; y0 < height; y0 += kStripRows) {
            const int y1 = std::min(height, y0 + kStripRows);
            const float* rows = rgb.data() + static_cast<std::size_t>(y0) * w * 3;
            // The strip as a frame buffer whose first row is y0.
            const Imath::Box2i strip(Imath::V2i(ox, oy + y0),
                                     Imath::V2i(ox + width - 1, oy + y1 - 1));
            Imf::FrameBuffer fb;
            if (!options.half) {
                for (std::size_t c = 0; c < 3; ++c)
                    fb.insert(std::string(1, "RGB"[c]),
                              Imf::Slice::Make(Imf::FLOAT, rows + c, strip, 3 * sizeof(float),
                                               3 * sizeof(float) * w));
            } else {
                // Converted here, in parallel, rather than by OpenEXR one value at a time.
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
                for (std::size_t c = 0; c < 3; ++c)
                    fb.insert(
                        std::string(1, "RGB"[c]),
                        Imf::Slice::Make(Imf::HALF, halves.data() + c, strip,
                                         3 * sizeof(Imath::half), 3 * sizeof(Imath::half) * w));
            }
            // The layers, a strip at a time (converted to half here when the image is half).
            if (lc > 0) {
                const float* lrows = options.layers->data() + static_cast<std::size_t>(y0) * w * lc;
                if (options.half) {
                    layer_halves.resize(static_cast<std::size_t>(y1 - y0) * w * lc);
                    std::size_t over = 0;
                    for (std::size_t i = 0; i < layer_halves.size(); ++i) {
                        layer_halves[i] = Imath::half(lrows[i]);
                        // Counted where the channel is written as half (the warning counted the
                        // beauty's values alone: a layered file held twice as many).
                        over += std::isfinite(lrows[i]) && layer_halves[i].isInfinity() &&
                                layer_type(i % lc) == Imf::HALF;
                    }
                    overflow += over;
                }
                for (std::size_t c = 0; c < lc; ++c) {
                    if (layer_type(c) == Imf::FLOAT)
                        fb.insert(options.layer_names[c],
                                  Imf::Slice::Make(Imf::FLOAT, lrows + c, strip, lc * sizeof(float),
                                                   lc * sizeof(float) * w));
                    else
                        fb.insert(options.layer_names[c],
                                  Imf::Slice::Make(Imf::HALF, layer_halves.data() + c, strip,
                                                   lc * sizeof(Imath::half),
                                                   lc * sizeof(Imath::half) * w));
                }
            }
            // The exact sums: 12 words per pixel (R0..R3, G0..G3, B0..B3).
            if (options.sums) {
                words.resize(static_cast<std::size_t>(y1 - y0) * w * 12);
                const SampleSum* srows =
                    options.sums->data() + static_cast<std::size_t>(y0) * w * 3;
                for (std::size_t i = 0; i < static_cast<std::size_t>(y1 - y0) * w * 3; ++i)
                    sample_sum_words(srows[i], &words[4 * i]);
                const auto& sum_names = sample_sum_channels();
                for (std::size_t c = 0; c < 12; ++c)
                    fb.insert(sum_names[c],
                              Imf::Slice::Make(Imf::UINT, words.data() + c, strip,
                                               12 * sizeof(uint32_t), 12 * sizeof(uint32_t) * w));
            }
            out.setFrameBuffer(fb);
            out.writePixels(y1 - y0);
        }
    });
    return overflow;
}

namespace {

/** 8-bit display values of rows [row0, row1) of the image (row0 a multiple of the block)
 *  through the config's default display and view. */
std::vector<unsigned char> display_bytes(const std::vector<float>& rgb, int width, int height,
                                         int row0, int row1, const ColorConfig& color,
                                         uint32_t block_size, std::string disp, std::string view) {
    color.resolve_view(disp, view);
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

/** Removes the chunks of `type` from the PNG `file` (the others, each with its own CRC, are
 *  kept as they are). */
void drop_chunk(std::string& file, const char* type) {
    std::string out = file.substr(0, std::min<std::size_t>(8, file.size()));
    std::size_t at = 8;
    while (at + 12 <= file.size()) {
        const auto byte = [&](std::size_t i) {
            return static_cast<uint32_t>(static_cast<unsigned char>(file[i]));
        };
        const uint32_t length =
            byte(at) << 24 | byte(at + 1) << 16 | byte(at + 2) << 8 | byte(at + 3);
        const std::size_t whole = 12 + static_cast<std::size_t>(length);
        if (at + whole > file.size()) break;
        if (file.compare(at + 4, 4, type) != 0) out.append(file, at, whole);
        at += whole;
    }
    out.append(file, at, std::string::npos);
    file = std::move(out);
}

/** Encodes 8-bit RGB rows as a PNG in memory (libpng's simplified API: errors come back as
 *  a message, not a longjmp). */
std::string encode_png(const std::vector<unsigned char>& bytes, int width, int height,
                       const PngOptions& options, bool srgb) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(width);
    image.height = static_cast<png_uint_32>(height);
    image.format = PNG_FORMAT_RGB;
    // libpng's simplified API knows two levels: its default, or fast (for pass outputs).
    if (options.compression_level <= 3) image.flags |= PNG_IMAGE_FLAG_FAST;
    // libpng tags the file sRGB unless told otherwise: only a view of an sRGB display is. (Told
    // otherwise, it writes a gamma of 1/2.2 instead, taken out below: no tag at all.)
    if (!srgb) image.flags |= PNG_IMAGE_FLAG_COLORSPACE_NOT_sRGB;
    png_alloc_size_t size = 0;
    if (!png_image_write_to_memory(&image, nullptr, &size, 0, bytes.data(), 0, nullptr))
        throw_error("cannot encode a PNG: {}", image.message);
    std::string file(size, '\0');
    if (!png_image_write_to_memory(&image, file.data(), &size, 0, bytes.data(), 0, nullptr))
        throw_error("cannot encode a PNG: {}", image.message);
    file.resize(size);
    if (!srgb) drop_chunk(file, "gAMA");
    return file;
}

}  // namespace

void write_png_preview(const std::string& path, const std::vector<float>& rgb, int width,
                       int height, const ColorConfig& color, const PngOptions& options) {
    const std::string file = encode_png_preview(rgb, width, height, color, options);
    write_atomically(path, [&](const std::string& tmp) {
        std::FILE* f = std::fopen(tmp.c_str(), "wb");
        if (!f) throw_error("cannot write '{}': {}", path, std::strerror(errno));
        const bool ok = std::fwrite(file.data(), 1, file.size(), f) == file.size();
        if (std::fclose(f) != 0 || !ok)
            throw_error("cannot write '{}': {}", path, std::strerror(errno));
    });
}

std::string encode_png_preview(const std::vector<float>& rgb, int width, int height,
                               const ColorConfig& color, const PngOptions& options) {
    const std::vector<unsigned char> bytes = display_bytes(
        rgb, width, height, 0, height, color, options.block, options.display, options.view);
    return encode_png(bytes, width, height, options,
                      color.view_is_srgb(options.display, options.view));
}

}  // namespace spangle
