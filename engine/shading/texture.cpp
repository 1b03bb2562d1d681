#include "shading/texture.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include "core/files.h"
#include "core/hash.h"
#include "core/memory.h"

namespace fs = std::filesystem;

namespace spangle {

namespace {

/** Version of the converted files' recipe: a change makes new cache entries. */
constexpr const char* kRecipe = "spangle-texture-1|half|tile64|box";

/** Removes from cache folder d the partial conversions a killed render left: hidden files
 *  ".NAME.PID.tmp...exr" (this module's temporary name and the ones OpenImageIO's make_texture
 *  derives from it) not written for an hour, so that no conversion still under way, on this
 *  machine or another sharing the folder, is touched. (They stayed for good: 3 to 28 MB each.)
 *  Once per folder per process. Returns how many it removed. */
int remove_stale_conversions(const fs::path& d) {
    static std::mutex mutex;
    static std::vector<fs::path> done;
    {
        std::lock_guard<std::mutex> lock(mutex);
        if (std::find(done.begin(), done.end(), d) != done.end()) return 0;
        done.push_back(d);
    }
    std::error_code ec;
    int removed = 0;
    const auto now = fs::file_time_type::clock::now();
    for (fs::directory_iterator it(d, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string f = it->path().filename().string();
        if (f.size() < 9 || f[0] != '.' || f.find(".tmp") == std::string::npos ||
            f.compare(f.size() - 4, 4, ".exr") != 0)
            continue;
        std::error_code e2;
        if (!it->is_regular_file(e2)) continue;
        const auto written = fs::last_write_time(it->path(), e2);
        if (e2 || now - written < std::chrono::hours(1)) continue;
        if (fs::remove(it->path(), e2)) ++removed;
    }
    return removed;
}

}  // namespace

std::vector<std::string> texture_cache_dirs(const TextureSettings& settings) {
    if (!settings.cache_dir.empty()) return {settings.cache_dir};
    if (const char* env = std::getenv("SPANGLE_TEXTURE_CACHE"); env && *env) return {env};
    const std::string temporary =
        (fs::temp_directory_path() / fmt::format("spangle-textures-{}", ::getuid())).string();
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
        return {(fs::path(xdg) / "spangle" / "textures").string(), temporary};
    if (const char* home = std::getenv("HOME"); home && *home)
        return {(fs::path(home) / ".cache" / "spangle" / "textures").string(), temporary};
    return {temporary};
}

void texture_coordinates(const TextureRef& ref, const float* u, const float* v, const float* dudx,
                         const float* dudy, const float* dvdx, const float* dvdy, std::size_t n,
                         TextureQuery& q) {
    q.resize(n);
    const float* m = ref.uv;
    for (std::size_t i = 0; i < n; ++i) {
        // uv' = M uv + offset; the image's t runs down while v runs up.
        texture_st(ref, u[i], v[i], q.s[i], q.t[i]);
        q.dsdx[i] = m[0] * dudx[i] + m[1] * dvdx[i];
        q.dsdy[i] = m[0] * dudy[i] + m[1] * dvdy[i];
        q.dtdx[i] = -(m[3] * dudx[i] + m[4] * dvdx[i]);
        q.dtdy[i] = -(m[3] * dudy[i] + m[4] * dvdy[i]);
    }
}

TextureService::TextureService(const ColorConfig& color, const Logger& log,
                               TextureSettings settings)
    : color_(color), log_(log), settings_(std::move(settings)) {}

// The texture system is the process's (see the module): nothing to free.
TextureService::~TextureService() = default;

void* TextureService::system() {
    if (!system_) {
        system_ = api_->create(static_cast<int>(settings_.memory_mb));
        if (!system_) throw_error("cannot create OpenImageIO's texture system");
    }
    return system_;
}

std::shared_ptr<const Texture> TextureService::open(const TextureRef& ref, bool color,
                                                    const FileLoc& loc) {
    std::lock_guard<std::mutex> lock(mutex_);
    // What the converted file depends on: the source's content, the conversion, the config.
    std::string space = ref.space;
    if (space.empty() && !color) space = "raw";
    if (space.empty()) {
        // The space an EXR's header names (Spangle's own renders say theirs: an ACEScg plate
        // was read as lin_rec709), else the file type's usual one.
        std::string unknown;
        space = default_image_space(
            ref.path, [&](const std::string& s) { return color_.canonical_name(s).has_value(); },
            unknown);
        if (!unknown.empty())
            log_.warn(
                "{}: texture '{}' names colour space '{}' in its header, which the OCIO "
                "config does not have: read as {} (give 'space' to say otherwise)",
                loc.str(), ref.path, unknown, space);
    }
    if (space != "raw") {
        const auto resolved = color_.resolve(space);
        if (!resolved)
            throw_error(loc, "texture '{}': unknown colour space '{}'; {}", ref.path, space,
                        color_.how_to_fix());
        space = resolved->name;
    }
    const std::string working = space == "raw" ? std::string() : color_.working_space();
    // The conversion by what it does (the config's definition of both spaces), not by the
    // config's path: a config edited in place (a show's new version) kept the old colours.
    std::string conversion;
    if (space != "raw") try {
            conversion = color_.conversion_id(space, working);
        } catch (const SpangleError& e) {
            throw_error(loc, "texture '{}': {}", ref.path, e.what());
        }
    const std::string key =
        fmt::format("{}|{}|{}|{}|{}", kRecipe, file_identity(ref.path), space, working, conversion);
    for (const auto& [k, tex] : opened_)
        if (k == key) return tex;
    try {
        api_ = &oiio_texture_api(ref.path);
    } catch (const SpangleError& e) {
        throw_error(loc, "{}", e.what());
    }

    // The cache, or where the user's cannot be written (a read-only or missing home on a farm
    // node) the temporary directory's, said once (the render failed at the texture's line).
    const std::vector<std::string> dir_names = texture_cache_dirs(settings_);
    const std::vector<fs::path> dirs(dir_names.begin(), dir_names.end());
    const std::string name =
        fmt::format("{}-{:016x}.exr", fs::path(ref.path).stem().string(), hash_text(key));
    std::error_code ec;
    fs::path converted = dirs[0] / name;
    for (const fs::path& d : dirs)
        if (fs::is_regular_file(d / name, ec)) {
            converted = d / name;
            break;
        }
    if (!fs::is_regular_file(converted, ec)) {
        const auto t0 = std::chrono::steady_clock::now();
        ImageHeader h;
        std::vector<float> pixels;
        try {
            // The header first: a damaged file's claimed size must not allocate anything. No
            // image format packs more than a few thousand pixels into a byte.
            const ImageHeader claimed = read_image_header(ref.path, "texture", true);
            const double px = static_cast<double>(claimed.width) * claimed.height;
            const auto bytes = static_cast<double>(fs::file_size(ref.path, ec));
            if (!ec && px > kMaxPixelsPerByte * std::max(bytes, 1.0))
                throw_error(
                    "texture '{}' claims {}x{} pixels in a file of {} bytes: it is "
                    "damaged or truncated",
                    ref.path, claimed.width, claimed.height, bytes);
            // At the peak: 4 channels as read, the RGB copy, the converted copy, and what
            // OpenImageIO holds while it writes the levels (about as much again).
            constexpr double kBytesPerPixel = 64.0;
            if (const uint64_t have = memory_short_for(px * kBytesPerPixel))
                throw_error(
                    "texture '{}' ({}x{}) needs about {} to convert, but only {} of "
                    "memory is available: use a smaller image (oiiotool --resize)",
                    ref.path, claimed.width, claimed.height, format_bytes(px * kBytesPerPixel),
                    format_bytes(static_cast<double>(have)));
            pixels = read_image(ref.path, 4, h, "texture", true);
        } catch (const SpangleError& e) {
            throw_error(loc, "{}", e.what());
        }
        // NaN and infinite values are 0, and said (OpenImageIO's conversion made NaN a
        // neighbour's value and infinity 0, silently).
        std::size_t bad = 0;
        for (float& v : pixels)
            if (!std::isfinite(v)) {
                v = 0.0f;
                ++bad;
            }
        if (bad > 0)
            log_.warn("{}: texture '{}' has {} values that are NaN or infinite; they are read as 0",
                      loc.str(), ref.path, bad);
        int channels = std::min(h.channels, 4);
        if (space != "raw") {
            // Colour: grey (and grey + alpha) images become RGB, then the RGB goes through OCIO;
            // alpha stays as it is.
            const int out_channels = channels == 2 || channels == 4 ? 4 : 3;
            const std::size_t count = static_cast<std::size_t>(h.width) * h.height;
            std::vector<float> rgb(3 * count);
            for (std::size_t i = 0; i < count; ++i)
                for (int c = 0; c < 3; ++c)
                    rgb[3 * i + c] =
                        pixels[i * channels + static_cast<std::size_t>(channels >= 3 ? c : 0)];
            try {
                color_.convert(space, color_.working_space(), rgb.data(), count);
            } catch (const SpangleError& e) {
                throw_error(loc, "texture '{}': {}", ref.path, e.what());
            }
            std::vector<float> out(static_cast<std::size_t>(out_channels) * count);
            for (std::size_t i = 0; i < count; ++i) {
                for (int c = 0; c < 3; ++c) out[i * out_channels + c] = rgb[3 * i + c];
                if (out_channels == 4) out[i * 4 + 3] = pixels[i * channels + channels - 1];
            }
            pixels.swap(out);
            channels = out_channels;
        }
        // Written under a temporary name and renamed: a render beside this one never sees half
        // a file, and an interrupted conversion leaves nothing behind that looks complete.
        std::string why;
        bool written = false;
        for (const fs::path& d : dirs) {
            converted = d / name;
            fs::create_directories(d, ec);
            if (ec) {
                why = fmt::format("cannot create the texture cache directory '{}': {}", d.string(),
                                  ec.message());
                continue;
            }
            if (const int n = remove_stale_conversions(d); n > 0)
                log_.info(
                    "removed {} partial texture conversion{} left in '{}' by a render that "
                    "was stopped",
                    n, n == 1 ? "" : "s", d.string());
            const fs::path tmp =
                d / fmt::format(".{}.{}.tmp.exr", name, static_cast<long>(::getpid()));
            char error[1024] = "";
            if (api_->make_texture(pixels.data(), h.width, h.height, channels, tmp.c_str(), error,
                                   sizeof(error)) != 0) {
                fs::remove(tmp, ec);
                why = fmt::format("cannot write its converted copy in '{}': {}", d.string(), error);
                continue;
            }
            fs::rename(tmp, converted, ec);
            if (ec) {
                fs::remove(tmp, ec);
                why = fmt::format("cannot write '{}': {}", converted.string(), ec.message());
                continue;
            }
            written = true;
            if (d != dirs[0] && !fallback_said_) {
                log_.warn(
                    "the texture cache '{}' cannot be written ({}): converted textures go "
                    "to '{}' (choose a folder with --texture-cache DIR or "
                    "$SPANGLE_TEXTURE_CACHE)",
                    dirs[0].string(), why, d.string());
                fallback_said_ = true;
            }
            break;
        }
        if (!written)
            throw_error(loc,
                        "texture '{}': {} (choose another folder with --texture-cache DIR or "
                        "$SPANGLE_TEXTURE_CACHE)",
                        ref.path, why);
        log_.info("texture {} ({}x{}, {}) converted in {:.2f} s to {}", ref.path, h.width, h.height,
                  space == "raw" ? std::string("data") : space + " -> " + working,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                  converted.string());
    }
    auto tex = std::make_shared<Texture>();
    tex->source = ref.path;
    tex->converted = converted.string();
    char error[1024] = "";
    tex->handle =
        api_->handle(system(), tex->converted.c_str(), &tex->channels, error, sizeof(error));
    if (!tex->handle)
        throw_error(loc, "texture '{}': cannot open its converted copy '{}': {}", ref.path,
                    tex->converted, error);
    opened_.emplace_back(key, tex);
    return tex;
}

void TextureService::lookup(const Texture& tex, const TextureRef& ref, const TextureQuery& q,
                            std::size_t n, int channels, float* out, float* ds, float* dt) const {
    if (n == 0) return;
    const int have = std::min(channels, tex.channels);
    thread_local std::vector<float> buf, buf_ds, buf_dt;
    const bool direct = have == channels;
    float* o = out;
    float* ods = ds;
    float* odt = dt;
    if (!direct) {
        buf.resize(n * static_cast<std::size_t>(have));
        o = buf.data();
        if (ds) {
            buf_ds.resize(buf.size());
            buf_dt.resize(buf.size());
            ods = buf_ds.data();
            odt = buf_dt.data();
        }
    }
    char error[1024] = "";
    if (api_->lookup(system_, tex.handle, ref.wraps(), ref.filter, static_cast<int>(n), q.s.data(),
                     q.t.data(), q.dsdx.data(), q.dtdx.data(), q.dsdy.data(), q.dtdy.data(), have,
                     o, ods, odt, error, sizeof(error)) != 0)
        throw_error("texture '{}': lookup failed: {}", tex.source, error);
    if (direct) return;
    // Fewer channels than asked for: a grey map's value in every colour channel (a grey + alpha
    // map's grey, its alpha only as a fourth; it gave grey, alpha, alpha), else the last repeats.
    const auto source = [&](int c) {
        if (have == 2) return c < 3 ? 0 : 1;
        return std::min(c, have - 1);
    };
    for (std::size_t i = n; i-- > 0;)
        for (int c = 0; c < channels; ++c) {
            const std::size_t from =
                i * static_cast<std::size_t>(have) + static_cast<std::size_t>(source(c));
            const std::size_t to =
                i * static_cast<std::size_t>(channels) + static_cast<std::size_t>(c);
            out[to] = buf[from];
            if (ds) {
                ds[to] = buf_ds[from];
                dt[to] = buf_dt[from];
            }
        }
}

}  // namespace spangle
