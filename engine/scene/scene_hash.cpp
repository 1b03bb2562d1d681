// What a scene's hash is made of: see scene_hash.h.

#include "scene/scene_hash.h"

#include <bit>

#include "core/files.h"
#include "core/hash.h"

namespace spangle {

uint64_t scene_content_hash(const std::string& path, const std::vector<std::string>& files) {
    uint64_t h = 0x5ce9e5ull;
    h = hash2(h, file_content_hash(path));
    for (const std::string& f : files) h = hash2(h, file_content_hash(f));
    return h;
}

uint64_t camera_hash(const CameraDesc& c) {
    uint64_t h = 0xca3e7a;
    const auto num = [&h](double x) { h = hash2(h, std::bit_cast<uint64_t>(x)); };
    const auto vec = [&](const Vec3& v) {
        num(static_cast<double>(v.x));
        num(static_cast<double>(v.y));
        num(static_cast<double>(v.z));
    };
    vec(c.position);
    vec(c.look_at);
    vec(c.up);
    num(c.fov_deg);
    num(c.aperture);
    num(c.focus_distance.value_or(-1.0));
    num(c.ortho_height);
    h = hash4(h, c.mirror, c.fov_shorter, c.equirect);
    if (c.screen)
        for (const double x : *c.screen) num(x);
    h = hash2(h, c.keys.smooth ? c.keys.keys.size() : ~c.keys.keys.size());
    for (const CameraKey& k : c.keys.keys) {
        num(k.time.seconds);
        h = hash2(h, k.time.frame ? static_cast<uint64_t>(*k.time.frame) : ~0ull);
        for (const std::optional<Vec3>& v : {k.position, k.look_at, k.up}) {
            h = hash2(h, v.has_value());
            if (v) vec(*v);
        }
        num(k.fov_deg.value_or(-1.0));
    }
    return h;
}

}  // namespace spangle
