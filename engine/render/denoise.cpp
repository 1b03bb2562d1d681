// The denoiser: see denoise.h. OIDN's C API is declared here (the few functions used, with the
// values of its enumerations as its header defines them), not included: its header is not in
// Debian 12, and the library is optional.

#include "render/denoise.h"

#include <dlfcn.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include "core/check.h"
#include "core/dynamic_library.h"
#include "core/error.h"
#include "core/log.h"
#include "render/render_options.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

using Device = void*;
using Filter = void*;
constexpr int kDeviceCpu = 1;                            // OIDN_DEVICE_TYPE_CPU
constexpr int kFormatFloat3 = 3;                         // OIDN_FORMAT_FLOAT3
constexpr int kQualityHigh = 6;                          // OIDN_QUALITY_HIGH
constexpr int kErrorNone = 0;                            // OIDN_ERROR_NONE
constexpr int kErrorCancelled = 6;                       // OIDN_ERROR_CANCELLED
using ProgressMonitor = bool (*)(void* user, double n);  // OIDNProgressMonitorFunction

/** The OIDN functions Spangle calls, bound from the library. */
struct OidnApi {
    Device (*new_device)(int) = nullptr;
    void (*commit_device)(Device) = nullptr;
    void (*release_device)(Device) = nullptr;
    void (*set_device_int)(Device, const char*, int) = nullptr;
    int (*device_error)(Device, const char**) = nullptr;
    Filter (*new_filter)(Device, const char*) = nullptr;
    void (*set_image)(Filter, const char*, void*, int, std::size_t, std::size_t, std::size_t,
                      std::size_t, std::size_t) = nullptr;
    void (*set_bool)(Filter, const char*, bool) = nullptr;
    void (*set_int)(Filter, const char*, int) = nullptr;
    void (*commit_filter)(Filter) = nullptr;
    void (*execute)(Filter) = nullptr;
    void (*release_filter)(Filter) = nullptr;
    /** Optional: a filter's progress, and a way to cancel it (null: neither). */
    void (*set_progress)(Filter, ProgressMonitor, void*) = nullptr;
    std::string error;  ///< why it could not be opened (empty: it was)
};

/** The library files to try, in order. */
std::vector<std::string> library_candidates() {
    constexpr const char* kName = "libOpenImageDenoise.so.2";
    std::vector<std::string> out;
    if (const char* env = std::getenv("SPANGLE_OIDN"); env && *env) {
        std::error_code ec;
        if (fs::is_directory(env, ec)) {
            out.push_back((fs::path(env) / kName).string());
            out.push_back((fs::path(env) / "lib" / kName).string());
        } else {
            out.emplace_back(env);
        }
        return out;  // an explicit choice: nothing else is tried
    }
    out.push_back(std::string("/opt/spangle/oidn/lib/") + kName);
    out.emplace_back(kName);  // the dynamic linker's search path
    return out;
}

const OidnApi& oidn() {
    static OidnApi api;
    static std::once_flag once;
    std::call_once(once, [] {
        std::string tried;
        for (const std::string& path : library_candidates()) {
            void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
            if (!handle) {
                const char* why = dlerror();
                tried += fmt::format("{}{} ({})", tried.empty() ? "" : "; ", path,
                                     why ? why : "not found");
                continue;
            }
            const bool complete = bind_symbol(handle, "oidnNewDevice", api.new_device) &&
                                  bind_symbol(handle, "oidnCommitDevice", api.commit_device) &&
                                  bind_symbol(handle, "oidnReleaseDevice", api.release_device) &&
                                  bind_symbol(handle, "oidnSetDeviceInt", api.set_device_int) &&
                                  bind_symbol(handle, "oidnGetDeviceError", api.device_error) &&
                                  bind_symbol(handle, "oidnNewFilter", api.new_filter) &&
                                  bind_symbol(handle, "oidnSetSharedFilterImage", api.set_image) &&
                                  bind_symbol(handle, "oidnSetFilterBool", api.set_bool) &&
                                  bind_symbol(handle, "oidnSetFilterInt", api.set_int) &&
                                  bind_symbol(handle, "oidnCommitFilter", api.commit_filter) &&
                                  bind_symbol(handle, "oidnExecuteFilter", api.execute) &&
                                  bind_symbol(handle, "oidnReleaseFilter", api.release_filter);
            if (complete)
                bind_symbol(handle, "oidnSetFilterProgressMonitorFunction", api.set_progress);
            if (complete) return;  // kept open for the life of the process
            api = OidnApi{};
            tried += fmt::format("{}{} (not Open Image Denoise 2: a function is missing)",
                                 tried.empty() ? "" : "; ", path);
        }
        const char* env = std::getenv("SPANGLE_OIDN");
        api.error = env && *env
                        ? fmt::format(
                              "Intel Open Image Denoise 2 could not be opened from SPANGLE_OIDN "
                              "(tried {}): point SPANGLE_OIDN at the library (or its folder), "
                              "or unset it to use /opt/spangle/oidn or the system's",
                              tried)
                        : fmt::format(
                              "Intel Open Image Denoise 2 could not be opened (tried {}): run "
                              "scripts/install-deps.sh, which unpacks it into "
                              "/opt/spangle/oidn, or set SPANGLE_OIDN to the library",
                              tried);
    });
    return api;
}

/** Who a filter tells how far it is, and asks whether to stop (DenoiseStopped then). */
struct FilterWatch {
    const DenoiseControl* control = nullptr;
    double from = 0.0, span = 1.0;  ///< the share of the whole this filter is
};

/** One OIDN device for a denoise; released with it. */
class OidnDevice {
public:
    OidnDevice(const OidnApi& api, int threads) : api_(api), device_(api.new_device(kDeviceCpu)) {
        if (!device_) throw_error("Open Image Denoise has no CPU device");
        if (threads > 0) api_.set_device_int(device_, "numThreads", threads);
        api_.commit_device(device_);
        check("starting its CPU device");
    }
    ~OidnDevice() { api_.release_device(device_); }
    OidnDevice(const OidnDevice&) = delete;
    OidnDevice& operator=(const OidnDevice&) = delete;

    /** Runs OIDN's "RT" filter: `main` (color, albedo or normal) into `out`, with guides. */
    void filter(const char* main, std::vector<float>& in, std::vector<float>* albedo,
                std::vector<float>* normal, std::vector<float>& out, uint32_t w, uint32_t h,
                bool hdr, FilterWatch watch = FilterWatch()) {
        Filter f = api_.new_filter(device_, "RT");
        if (!f) throw_error("Open Image Denoise has no RT filter");
        const auto set = [&](const char* name, std::vector<float>& v) {
            api_.set_image(f, name, v.data(), kFormatFloat3, w, h, 0, 0, 0);
        };
        set(main, in);
        if (albedo) set("albedo", *albedo);
        if (normal) set("normal", *normal);
        set("output", out);
        if (hdr) api_.set_bool(f, "hdr", true);
        if (albedo || normal) api_.set_bool(f, "cleanAux", true);  // the guides are filtered
        api_.set_int(f, "quality", kQualityHigh);
        if (watch.control && api_.set_progress)
            api_.set_progress(
                f,
                [](void* user, double n) {
                    const FilterWatch& fw = *static_cast<const FilterWatch*>(user);
                    if (fw.control->progress) fw.control->progress(fw.from + fw.span * n);
                    return !(fw.control->stop && fw.control->stop());
                },
                &watch);
        api_.commit_filter(f);
        api_.execute(f);
        api_.release_filter(f);
        // (Reading the device's error clears it: once.)
        const char* message = nullptr;
        const int error = api_.device_error(device_, &message);
        if (error == kErrorCancelled) throw DenoiseStopped();
        if (error != kErrorNone)
            throw_error("Open Image Denoise failed ({}): {}", main,
                        message ? message : "no message");
    }

private:
    void check(const char* what) {
        const char* message = nullptr;
        if (api_.device_error(device_, &message) != kErrorNone)
            throw_error("Open Image Denoise failed ({}): {}", what,
                        message ? message : "no message");
    }
    const OidnApi& api_;
    Device device_;
};

/** Channel `name`'s index in the layers; throws when it is missing. */
std::size_t channel(const std::vector<std::string>& names, const char* name) {
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end())
        throw_error("the denoiser needs the layer channel '{}' (render with --layers)", name);
    return static_cast<std::size_t>(it - names.begin());
}

/** The noisy beauty becomes the layer `noisy` (after the others); `result` the image. */
void keep_noisy(DenoiseImage im, std::vector<float>& result) {
    std::vector<std::string>& names = *im.layer_names;
    const std::size_t lc = names.size(), pixels = static_cast<std::size_t>(im.width) * im.height;
    std::vector<float> layers(pixels * (lc + 3));
    for (std::size_t p = 0; p < pixels; ++p) {
        std::copy_n(im.layers->begin() + static_cast<std::ptrdiff_t>(p * lc), lc,
                    layers.begin() + static_cast<std::ptrdiff_t>(p * (lc + 3)));
        for (std::size_t c = 0; c < 3; ++c) layers[p * (lc + 3) + lc + c] = (*im.image)[3 * p + c];
    }
    im.layers->swap(layers);
    for (const char* c : {"noisy.R", "noisy.G", "noisy.B"}) names.emplace_back(c);
    if (&result != im.image) im.image->swap(result);
}

/** Channels `of` of each pixel of the interleaved layers, three per pixel. */
std::vector<float> three(const std::vector<float>& layers, const std::vector<std::string>& names,
                         const std::array<const char*, 3>& of) {
    const std::size_t lc = names.size(), pixels = layers.size() / lc;
    // Each by its name: the channels of a layer need not sit side by side in R, G, B order (a
    // file's channels come sorted by name: B, G, R).
    const std::array<std::size_t, 3> at = {channel(names, of[0]), channel(names, of[1]),
                                           channel(names, of[2])};
    std::vector<float> out(3 * pixels);
    for (std::size_t p = 0; p < pixels; ++p)
        for (std::size_t c = 0; c < 3; ++c) out[3 * p + c] = layers[p * lc + at[c]];
    return out;
}

}  // namespace

bool denoiser_available(std::string* why) {
    const OidnApi& api = oidn();
    if (why) *why = api.error;
    return api.error.empty();
}

bool denoise(DenoiseImage im, GlintDenoise glints, int threads, const DenoiseControl& control) {
    const OidnApi& api = oidn();
    if (!api.error.empty()) throw_error("{}", api.error);
    std::vector<std::string>& names = *im.layer_names;
    const std::size_t lc = names.size(), pixels = static_cast<std::size_t>(im.width) * im.height;
    SPANGLE_CHECK(im.image->size() == 3 * pixels && im.layers->size() == lc * pixels,
                  "the denoiser's image and layers must match its size");

    std::vector<float> albedo = three(*im.layers, names, {"albedo.R", "albedo.G", "albedo.B"});
    std::vector<float> normal = three(*im.layers, names, {"N.X", "N.Y", "N.Z"});
    const std::vector<float> glint = three(*im.layers, names, {"glints.R", "glints.G", "glints.B"});
    // (The guides are checked first: a small image without them is still an error.)
    if (im.width < kMinDenoiseSide || im.height < kMinDenoiseSide) {
        keep_noisy(im, *im.image);
        return false;
    }
    // The beauty without its glints (never below 0: the layers are float sums, the beauty
    // fixed-point ones), denoised; then the glints added back as rendered.
    std::vector<float> base = *im.image;
    if (glints != GlintDenoise::Filter)
        for (std::size_t i = 0; i < base.size(); ++i) base[i] = std::max(0.0f, base[i] - glint[i]);
    OidnDevice device(api, threads);
    // The filters' shares of the time: the guides a tenth each, the beauty (and the glints
    // apart) the rest.
    const double beauty = glints == GlintDenoise::Apart ? 0.4 : 0.8;
    using Watch = FilterWatch;
    std::vector<float> clean_albedo(albedo.size()), clean_normal(normal.size());
    device.filter("albedo", albedo, nullptr, nullptr, clean_albedo, im.width, im.height, false,
                  Watch{&control, 0.0, 0.1});
    device.filter("normal", normal, nullptr, nullptr, clean_normal, im.width, im.height, false,
                  Watch{&control, 0.1, 0.1});
    std::vector<float> out(base.size());
    device.filter("color", base, &clean_albedo, &clean_normal, out, im.width, im.height, true,
                  Watch{&control, 0.2, beauty});
    std::vector<float> glint_out = glint;
    if (glints == GlintDenoise::Apart) {
        std::vector<float> in = glint;
        device.filter("color", in, &clean_albedo, &clean_normal, glint_out, im.width, im.height,
                      true, Watch{&control, 0.2 + beauty, beauty});
    }
    if (control.progress) control.progress(1.0);
    if (glints != GlintDenoise::Filter)
        for (std::size_t i = 0; i < out.size(); ++i) out[i] += glint_out[i];
    // Where no camera ray hit anything the beauty is what it was (0 when the environment is a
    // layer of its own): nothing spreads into the transparent pixels.
    const auto a = std::find(names.begin(), names.end(), "A");
    if (a != names.end()) {
        const std::size_t ai = static_cast<std::size_t>(a - names.begin());
        for (std::size_t p = 0; p < pixels; ++p)
            if ((*im.layers)[p * lc + ai] == 0.0f)
                for (std::size_t c = 0; c < 3; ++c) out[3 * p + c] = (*im.image)[3 * p + c];
    }
    keep_noisy(im, out);
    return true;
}

DenoiseControl denoise_control(const RenderOptions& o) {
    DenoiseControl control;
    control.stop = o.stop;
    if (o.work_progress) control.progress = [&o](double f) { o.work_progress("denoising", f); };
    return control;
}

void denoise_and_record(DenoiseImage im, GlintDenoise glints, int threads,
                        const DenoiseControl& control, const Logger& log, RenderStats& st) {
    try {
        if (denoise(im, glints, threads, control))
            mark_denoised(st, glints);
        else
            log.warn("{}", not_denoised_warning(im.width, im.height));
    } catch (const DenoiseStopped&) {
        st.denoise_stopped = true;  // stopped before it changed the image
    }
}

}  // namespace spangle
