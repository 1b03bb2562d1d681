#pragma once
// Small helpers every material plugin needs: reading the validated parameter set, reporting an
// error through the ABI's buffer, the linear Rec.709 -> working space matrix from the host's
// colour conversion, and a radical inverse for deterministic quadrature at create().

#include <spangle/plugin.h>

#include <algorithm>
#include <cstring>
#include <string>

namespace spangle::plugin_support {

/** Luminance of linear Rec.709 RGB (the Y row of its RGB to XYZ matrix); the plugins use it to
 *  steer sampling between lobes and flakes, where any fixed positive weights are correct. */
inline float rec709_luminance(const float c[3]) {
    return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

/** Copies msg into the caller's error buffer (truncated, NUL-terminated). */
inline void set_error(char* error, uint32_t capacity, const std::string& msg) {
    if (!error || capacity == 0) return;
    const std::size_t n = std::min<std::size_t>(msg.size(), capacity - 1);
    std::memcpy(error, msg.data(), n);
    error[n] = '\0';
}

/** The value of parameter `name`; the host passes the full schema, so it exists. */
inline const SpangleParamValue_v3* find_param(const SpangleParams_v3* p, const char* name) {
    for (uint32_t i = 0; i < p->count; ++i)
        if (std::strcmp(p->values[i].name, name) == 0) return &p->values[i];
    return nullptr;
}
inline double param_number(const SpangleParams_v3* p, const char* name, int c = 0) {
    const SpangleParamValue_v3* v = find_param(p, name);
    return v ? v->number[c] : 0.0;
}
inline std::string param_string(const SpangleParams_v3* p, const char* name) {
    const SpangleParamValue_v3* v = find_param(p, name);
    return v && v->string ? v->string : "";
}

/** Linear Rec.709 -> working space (row-major), from the host's conversion of the basis: for
 *  quantities given per Rec.709 band (a metal's Fresnel) carried into the working space. */
inline bool rec709_to_working(const SpangleHost_v3* host, float m[9], std::string& why) {
    float basis[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    char err[256] = {0};
    if (!host || !host->convert_to_working ||
        host->convert_to_working(host->context, "lin_rec709", basis, 3, err, sizeof(err)) != 0) {
        why = std::string("cannot convert colours to the working space: ") + err;
        return false;
    }
    for (int j = 0; j < 3; ++j)
        for (int r = 0; r < 3; ++r) m[3 * r + j] = basis[3 * j + r];
    return true;
}

/** Point i's path-regularisation floor on GGX alpha (SpangleShadingBatch_v3.roughness_floor),
 *  or 0 when the host gives none for it. */
inline float roughness_floor(const SpangleShadingBatch_v3* b, uint32_t i) {
    if (!(b->flags[i] & SPANGLE_SHADING_ROUGHNESS_FLOOR) || !b->roughness_floor) return 0.0f;
    const float f = b->roughness_floor[i];
    return f > 0.0f ? std::min(f, 1.0f) : 0.0f;  // NaN and nonsense read as no floor
}

/** Radical inverse in base 2 (van der Corput), for Hammersley quadrature. */
inline float radical_inverse2(uint32_t i) {
    i = (i << 16) | (i >> 16);
    i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
    i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
    i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
    i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
    return static_cast<float>(i) * 0x1p-32f;
}

}  // namespace spangle::plugin_support
