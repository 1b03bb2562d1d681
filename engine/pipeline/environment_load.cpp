#include "pipeline/environment_load.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>

#include "color/image_io.h"
#include "core/error.h"
#include "core/memory.h"

namespace spangle {

namespace {

/** Negative values of a map as read: how many, their sum against the positive ones', the lowest
 *  and where. */
struct NegativeValues {
    std::size_t count = 0;
    double negative = 0.0, positive = 0.0;
    float lowest = 0.0f;
    std::size_t at = 0;  ///< pixel index of the lowest
    void add(float v, std::size_t pixel) {
        if (v >= 0.0f) {
            positive += static_cast<double>(v);
            return;
        }
        ++count;
        negative -= static_cast<double>(v);
        if (v < lowest) {
            lowest = v;
            at = pixel;
        }
    }
};

/** Negatives worth a warning: more than this share of the map's positive light (a resampled or
 *  compressed map rings a little below 0; that is not worth a line). */
constexpr double kNegativeShare = 1e-4;

}  // namespace

EnvironmentMap load_environment_map(const EnvironmentMapFile& file, const ColorConfig& color,
                                    const Logger* log) {
    ImageHeader spec;
    try {
        spec = read_image_header(file.path, "environment map", true);
    } catch (const SpangleError& e) {
        throw_error(file.loc, "{}", e.what());
    }
    if (spec.width < 2 || spec.height < 1 || spec.width > 32768 || spec.height > 16384)
        throw_error(file.loc, "environment map '{}' is {}x{}; expected between 2x1 and 32768x16384",
                    file.path, spec.width, spec.height);
    if (spec.channels < 1) throw_error(file.loc, "environment map '{}' has no channels", file.path);
    // An equal-area (octahedral) map is square: another shape would wrap as garbage.
    if (file.projection == MapProjection::EqualArea && spec.width != spec.height)
        throw_error(file.loc,
                    "environment map '{}' is {}x{}: an equal-area map is square (a 2:1 map is "
                    "lat-long: projection = \"latlong\")",
                    file.path, spec.width, spec.height);
    // What the header claims must be plausible for the file's size before anything is
    // allocated: no image format packs more than a few thousand pixels into a byte (a 157-byte
    // HDR claiming 32768x16384 took 6 GB before failing).
    std::error_code ec;
    const auto bytes = static_cast<double>(std::filesystem::file_size(file.path, ec));
    const double pixels_claimed = static_cast<double>(spec.width) * spec.height;
    if (!ec && pixels_claimed > kMaxPixelsPerByte * std::max(bytes, 1.0))
        throw_error(file.loc,
                    "environment map '{}' claims {}x{} pixels in a file of {} bytes: it is "
                    "damaged or truncated",
                    file.path, spec.width, spec.height, bytes);
    // At the peak: the pixels as read, the working-space copy and the sampling distribution.
    constexpr double kBytesPerPixel = 32.0;
    if (const uint64_t have = memory_short_for(pixels_claimed * kBytesPerPixel))
        throw_error(file.loc,
                    "environment map '{}' ({}x{}) needs about {} to load, but only {} of memory "
                    "is available: use a smaller map (oiiotool --resize)",
                    file.path, spec.width, spec.height,
                    format_bytes(pixels_claimed * kBytesPerPixel),
                    format_bytes(static_cast<double>(have)));
    // Only the first three channels are used (and read).
    std::vector<float> pixels;
    ImageHeader read;
    try {
        pixels = read_image(file.path, 3, read, "environment map", true);
    } catch (const SpangleError& e) {
        throw_error(file.loc, "{}", e.what());
    }
    if (read.width != spec.width || read.height != spec.height)
        throw_error(file.loc, "environment map '{}' changed while it was read", file.path);
    const int channels = std::min(read.channels, 3);
    const std::size_t n = static_cast<std::size_t>(spec.width) * spec.height;
    std::vector<float> rgb(3 * n);
    NegativeValues neg;
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            // A grey map (and a grey + alpha one: its grey, not grey, alpha, alpha) in every
            // channel.
            const int from = channels == 2 ? 0 : std::min(c, channels - 1);
            const float v =
                pixels[i * static_cast<std::size_t>(channels) + static_cast<std::size_t>(from)];
            if (!std::isfinite(v))
                throw_error(file.loc,
                            "environment map '{}' has a non-finite value at pixel ({}, {})",
                            file.path, i % static_cast<std::size_t>(spec.width),
                            i / static_cast<std::size_t>(spec.width));
            rgb[3 * i + static_cast<std::size_t>(c)] = v;
            neg.add(v, i);
        }
    if (log && neg.count > 0 && neg.negative > kNegativeShare * neg.positive) {
        // Against what the map sums to: a map of (nearly) nothing but negatives is said as such
        // (a percentage of its near-zero net light was 6e28%).
        const double net = neg.positive - neg.negative;
        const std::string effect =
            net > 0.01 * neg.positive
                ? fmt::format("adding {:.2g}% to the map's light", 100.0 * neg.negative / net)
                : std::string(
                      "and the map's light is in its positive values alone (the "
                      "negatives outweigh them)");
        log->warn(
            "{}: environment map '{}' has {} negative values (the lowest {:.4g}, at pixel ({}, "
            "{})): light cannot be negative, so they are taken as 0, {}",
            file.loc.str(), file.path, neg.count, neg.lowest,
            neg.at % static_cast<std::size_t>(spec.width),
            neg.at / static_cast<std::size_t>(spec.width), effect);
    }
    // Pixels whose own values are negative (said above): not counted again below.
    std::vector<uint8_t> own_negative(n, 0);
    for (std::size_t i = 0; i < n; ++i)
        own_negative[i] =
            static_cast<uint8_t>(std::min({rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]}) < 0.0f);
    color.to_working(file.color_space, rgb.data(), n);
    // Colours outside the working space's gamut come out with negative parts, clipped below:
    // said, as a colour's are (a map's were clipped without a word).
    NegativeValues gamut;
    for (std::size_t i = 0; i < 3 * n; ++i)
        if (!own_negative[i / 3]) gamut.add(rgb[i], i / 3);
    if (log && gamut.count > 0 && gamut.negative > kNegativeShare * gamut.positive)
        log->warn(
            "{}: environment map '{}' holds colours outside the working space '{}' ({} values "
            "negative once converted from '{}', the lowest {:.4g} at pixel ({}, {})): their "
            "negative parts are clipped to 0, which shifts their hue; a working space whose gamut "
            "holds them keeps them",
            file.loc.str(), file.path, color.working_space(), gamut.count, file.color_space,
            gamut.lowest, gamut.at % static_cast<std::size_t>(spec.width),
            gamut.at / static_cast<std::size_t>(spec.width));
    // Gamut clipping of negatives; the brightest value times the intensity within the 1e18 a
    // sample can carry, as a colour's is (a map at intensity 1e30 came out one flat 1.15e18,
    // a map with a 1e9 texel all black).
    float most = 0.0f;
    for (const float v : rgb) most = std::max(most, v);
    const double brightest = static_cast<double>(most) * static_cast<double>(file.intensity);
    if (!(brightest <= 1e18))
        throw_error(file.loc,
                    "environment map '{}': its brightest value {:.4g} times intensity {:.4g} is "
                    "{:.4g}, beyond 1e18, the most a sample can carry",
                    file.path, most, file.intensity, brightest);
    for (float& v : rgb) v = std::max(0.0f, v) * file.intensity;
    return EnvironmentMap(std::move(rgb), spec.width, spec.height, file.rotation_deg,
                          file.projection, file.to_map);
}

}  // namespace spangle
