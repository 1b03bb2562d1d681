#pragma once
// A render request for a copy of one of tests/scenes/ (its paths made absolute), for the tests
// that render a shipped test scene at a size and sample count of their own.

#include <cstdint>
#include <fstream>
#include <string>

#include "pipeline/frame.h"
#include "test_support.h"

namespace spangle::test {

/** A quiet render of the scene file `scene` through the shipped OCIO config. */
inline FrameRequest quiet_request(const std::string& scene) {
    FrameRequest req;
    req.scene = scene;
    req.ocio_config = shipped_ocio();
    req.log = &quiet_log();
    return req;
}

/** tests/scenes/`name` copied into `dir`, to render at w x h with `spp` samples, quietly, with
 *  the shipped OCIO config and a texture cache in `dir`. */
inline FrameRequest scene_request(const TempDir& dir, const std::string& name, uint32_t w,
                                  uint32_t h, uint32_t spp) {
    std::ofstream(dir.file(name)) << scene_text(name);
    FrameRequest req = quiet_request(dir.file(name));
    req.options.width_override = w;
    req.options.height_override = h;
    req.options.spp_override = spp;
    req.options.texture_cache = dir.file("cache");
    return req;
}

/** `text` written to `dir`/`name`, to render quietly with the shipped OCIO config and a texture
 *  cache in `dir`. */
inline FrameRequest text_request(const TempDir& dir, const std::string& name,
                                 const std::string& text) {
    { std::ofstream(dir.file(name)) << text; }
    FrameRequest req = quiet_request(dir.file(name));
    req.options.texture_cache = dir.file("cache");
    return req;
}

/** The mean RGB of the w x h block at (x0, y0) of a render. */
inline Vec3 block_mean(const FrameResult& r, uint32_t x0, uint32_t y0, uint32_t w, uint32_t h) {
    Vec3 sum(0.0f);
    for (uint32_t y = y0; y < y0 + h; ++y)
        for (uint32_t x = x0; x < x0 + w; ++x) {
            const float* p = &r.image[3 * (static_cast<std::size_t>(y) * r.width + x)];
            sum += Vec3(p[0], p[1], p[2]);
        }
    return sum / static_cast<float>(w * h);
}

}  // namespace spangle::test
