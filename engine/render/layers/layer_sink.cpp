#include "render/layers/layer_sink.h"

#include <fmt/format.h>

namespace spangle {

std::vector<std::string> layer_channel_names(const std::vector<std::string>& light_groups) {
    std::vector<std::string> out = {"A",        "albedo.R", "albedo.G", "albedo.B", "N.X",
                                    "N.Y",      "N.Z",      "Z",        "P.X",      "P.Y",
                                    "P.Z",      "Pobj.X",   "Pobj.Y",   "Pobj.Z",   "object",
                                    "glints.R", "glints.G", "glints.B"};
    for (const std::string& g : light_groups)
        for (const char* c : {"R", "G", "B"}) out.push_back(fmt::format("lightgroup_{}.{}", g, c));
    return out;
}

void finish_layers(std::vector<float>& film, std::size_t channels, uint32_t samples,
                   const uint32_t* counts) {
    float inv_spp = samples > 0 ? 1.0f / static_cast<float>(samples) : 0.0f;
    // Depth, position, object-space position and object number: averages over the samples whose
    // camera ray hit something (0 where none did: alpha 0), so that edges are not pulled
    // towards the origin (an object number between two integers marks a pixel shared by
    // objects).
    for (std::size_t p = 0; p < film.size(); p += channels) {
        float* v = &film[p];
        if (counts) {
            const uint32_t n = counts[p / channels];
            inv_spp = n > 0 ? 1.0f / static_cast<float>(n) : 0.0f;
        }
        const float hits = v[kAovA];
        const float inv_hits = hits > 0.0f ? 1.0f / hits : 0.0f;
        for (std::size_t c = 0; c < channels; ++c) {
            const bool per_hit = c == kAovZ || (c >= kAovP && c <= kAovObject);
            const bool normal = c >= kAovN && c < kAovN + 3;
            if (!normal) v[c] *= per_hit ? inv_hits : inv_spp;
        }
        // The normal: the direction of the summed normals of the shaded hits (a camera ray that
        // hit a light adds none), unit length, 0 where none was shaded.
        const float len = std::sqrt(v[kAovN] * v[kAovN] + v[kAovN + 1] * v[kAovN + 1] +
                                    v[kAovN + 2] * v[kAovN + 2]);
        const float inv_len = len > 0.0f && std::isfinite(len) ? 1.0f / len : 0.0f;
        for (std::size_t c = kAovN; c < kAovN + 3; ++c) v[c] *= inv_len;
    }
}

}  // namespace spangle
