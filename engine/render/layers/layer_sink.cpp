#include "render/layers/layer_sink.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>

namespace spangle {
namespace {

/** The Cryptomatte layers' names, in the order they are written. */
constexpr std::array<const char*, 2> kCryptoLayers = {"CryptoObject", "CryptoMaterial"};

/** Ranks pixel slots (kCryptoSlots id/weight pairs) by weight and writes the first
 *  kCryptoRanks as (id, coverage) pairs into `out`; empty ranks are (0, 0). */
void rank_ids(const float* slots, float inv_spp, float* out) {
    std::array<std::pair<float, float>, kCryptoSlots> s;
    for (uint32_t i = 0; i < kCryptoSlots; ++i) s[i] = {slots[2 * i], slots[2 * i + 1]};
    // Highest coverage first; ties by id, so that the order does not depend on which sample
    // came first.
    std::sort(s.begin(), s.end(), [](const auto& a, const auto& b) {
        return a.second != b.second ? a.second > b.second : a.first < b.first;
    });
    for (uint32_t r = 0; r < kCryptoRanks; ++r) {
        const bool used = s[r].second > 0.0f;
        out[2 * r] = used ? s[r].first : 0.0f;
        out[2 * r + 1] = used ? s[r].second * inv_spp : 0.0f;
    }
}

}  // namespace

LayerLayout layer_layout(uint32_t groups) {
    LayerLayout l;
    l.groups = groups;
    l.glints = kAovCount;
    l.group_light = l.glints + 3;
    l.group_glints = l.group_light + 3 * groups;
    l.background = l.group_glints + 3 * groups;
    l.catcher = l.background + 3;
    l.crypto_object = l.catcher + 3;
    l.crypto_material = l.crypto_object + 2 * kCryptoSlots;
    l.channels = l.crypto_material + 2 * kCryptoSlots;
    return l;
}

std::vector<std::string> layer_channel_names(const LayerPlan& plan) {
    std::vector<std::string> out = {"A",        "albedo.R", "albedo.G", "albedo.B", "N.X",
                                    "N.Y",      "N.Z",      "Z",        "P.X",      "P.Y",
                                    "P.Z",      "Pobj.X",   "Pobj.Y",   "Pobj.Z",   "object",
                                    "glints.R", "glints.G", "glints.B"};
    for (const std::string& g : plan.groups)
        for (const char* c : {"R", "G", "B"}) out.push_back(fmt::format("lightgroup_{}.{}", g, c));
    for (const std::string& g : plan.groups)
        for (const char* c : {"R", "G", "B"}) out.push_back(fmt::format("glints_{}.{}", g, c));
    if (plan.background)
        for (const char* c : {"R", "G", "B"}) out.push_back(fmt::format("background.{}", c));
    if (plan.catcher) out.emplace_back("shadow");
    for (const char* layer : kCryptoLayers)
        for (uint32_t k = 0; k < kCryptoRanks / 2; ++k)
            for (const char* c : {"R", "G", "B", "A"})
                out.push_back(fmt::format("{}{:02}.{}", layer, k, c));
    return out;
}

bool layer_channel_is_data(const std::string& name) {
    for (const char* prefix : {"N.", "P.", "Pobj.", "Crypto"})
        if (name.rfind(prefix, 0) == 0) return true;
    return name == "Z" || name == "object" || name == "spp";
}

void finish_layers(std::vector<float>& film, const LayerLayout& layout, const LayerPlan& plan,
                   uint32_t samples, const uint32_t* counts) {
    const std::size_t channels = layout.channels;
    const std::size_t written = layer_channel_names(plan).size();
    const std::size_t groups = layout.groups;
    const std::size_t pixels = channels ? film.size() / channels : 0;
    std::vector<float> out(written);
    for (std::size_t p = 0; p < pixels; ++p) {
        const float* v = &film[p * channels];
        const uint32_t n = counts ? counts[p] : samples;
        const float inv_spp = n > 0 ? 1.0f / static_cast<float>(n) : 0.0f;
        // Depth, position, object-space position and object number: averages over the samples
        // whose camera ray hit something (0 where none did: alpha 0), so that edges are not
        // pulled towards the origin (an object number between two integers marks a pixel
        // shared by objects).
        const float hits = v[kAovA];
        const float inv_hits = hits > 0.0f ? 1.0f / hits : 0.0f;
        for (std::size_t c = 0; c < kAovCount; ++c) {
            const bool per_hit = c == kAovZ || (c >= kAovP && c <= kAovObject);
            out[c] = v[c] * (per_hit ? inv_hits : inv_spp);
        }
        // The normal: the direction of the summed normals of the shaded hits (a camera ray that
        // hit a light adds none), unit length, 0 where none was shaded.
        const float len = std::sqrt(v[kAovN] * v[kAovN] + v[kAovN + 1] * v[kAovN + 1] +
                                    v[kAovN + 2] * v[kAovN + 2]);
        const float inv_len = len > 0.0f && std::isfinite(len) ? 1.0f / len : 0.0f;
        for (std::size_t c = kAovN; c < kAovN + 3; ++c) out[c] = v[c] * inv_len;
        // A shadow catcher's samples are as opaque as the shadow others cast on it: the share of
        // its light (next-event estimation, by luminance) that their shadows took away.
        const float catcher_n = v[layout.catcher], free = v[layout.catcher + 1];
        const float lit_share = free > 0.0f ? std::min(1.0f, v[layout.catcher + 2] / free) : 1.0f;
        out[kAovA] = std::max(0.0f, hits - catcher_n * lit_share) * inv_spp;
        std::size_t o = kAovCount;
        for (std::size_t c = 0; c < 3 + 6 * groups; ++c) out[o++] = v[layout.glints + c] * inv_spp;
        if (plan.background)
            for (std::size_t c = 0; c < 3; ++c) out[o++] = v[layout.background + c] * inv_spp;
        if (plan.catcher) out[o++] = catcher_n * (1.0f - lit_share) * inv_spp;
        rank_ids(v + layout.crypto_object, inv_spp, &out[o]);
        rank_ids(v + layout.crypto_material, inv_spp, &out[o + 2 * kCryptoRanks]);
        std::copy(out.begin(), out.end(), film.begin() + static_cast<std::ptrdiff_t>(p * written));
    }
    film.resize(pixels * written);
}

}  // namespace spangle
