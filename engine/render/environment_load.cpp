#include "render/environment_load.h"

#include <OpenImageIO/imageio.h>

#include <cmath>

#include "core/error.h"

namespace spangle {

EnvironmentMap load_environment_map(const EnvironmentMapFile& file, const ColorConfig& color) {
    auto in = OIIO::ImageInput::open(file.path);
    if (!in)
        throw_error(file.loc, "cannot read environment map '{}': {}", file.path, OIIO::geterror());
    const OIIO::ImageSpec spec = in->spec();
    if (spec.width < 2 || spec.height < 1 || spec.width > 32768 || spec.height > 16384)
        throw_error(file.loc, "environment map '{}' is {}x{}; expected between 2x1 and 32768x16384",
                    file.path, spec.width, spec.height);
    if (spec.nchannels < 1)
        throw_error(file.loc, "environment map '{}' has no channels", file.path);
    std::vector<float> pixels(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels.data()))
        throw_error(file.loc, "cannot read environment map '{}': {}", file.path, in->geterror());
    const std::size_t n = static_cast<std::size_t>(spec.width) * spec.height;
    std::vector<float> rgb(3 * n);
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            const float v = pixels[i * static_cast<std::size_t>(spec.nchannels) +
                                   static_cast<std::size_t>(std::min(c, spec.nchannels - 1))];
            if (!std::isfinite(v))
                throw_error(file.loc,
                            "environment map '{}' has a non-finite value at pixel ({}, {})",
                            file.path, i % static_cast<std::size_t>(spec.width),
                            i / static_cast<std::size_t>(spec.width));
            rgb[3 * i + static_cast<std::size_t>(c)] = v;
        }
    color.to_working(file.color_space, rgb.data(), n);
    for (float& v : rgb) v = std::max(0.0f, v) * file.intensity;  // gamut clipping of negatives
    return EnvironmentMap(std::move(rgb), spec.width, spec.height, file.rotation_deg);
}

}  // namespace spangle
