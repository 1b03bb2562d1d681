// The smooth material plugin: microfacet and diffuse models behind the Spangle material ABI.
//
// Models and parameters (the schema below is the authority; `spangle plugins` prints it):
//
//   diffuse   Lambertian reflection.
//     albedo   color  [0.8, 0.8, 0.8] in [0, 1]   fraction of light reflected diffusely
//
// Conventions: directions in the local shading frame (z = normal); f excludes the cosine.
// Invalid samples return f = 0, pdf = 0 and flags = 0, never NaN.

#include <spangle/plugin.h>

#include <cmath>
#include <cstring>
#include <new>

namespace {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 0.31830988618379067154f;

/** Copies msg into a caller's error buffer. */
void set_error(char* error, uint32_t capacity, const char* msg) {
    if (!error || capacity == 0) return;
    std::strncpy(error, msg, capacity - 1);
    error[capacity - 1] = '\0';
}

// ------------------------------------------------------------------------------------ diffuse

const SpangleParamDesc_v1 kDiffuseParams[] = {
    {"albedo",
     SPANGLE_PARAM_COLOR,
     {0.8, 0.8, 0.8},
     nullptr,
     0.0,
     1.0,
     nullptr,
     "fraction of light reflected diffusely (RGB)"},
};

/** A diffuse instance: its albedo in the working space. */
struct Diffuse {
    float albedo[3];
};

/** Per-shading-point closure. */
struct DiffuseClosure {
    float albedo[3];
    float pad;
};

void* diffuse_create(const SpangleParams_v1* params, const SpangleHost_v1*, char* error,
                     uint32_t capacity) {
    if (!params || params->count != 1) {
        set_error(error, capacity, "expected exactly the schema's parameters");
        return nullptr;
    }
    auto* d = new (std::nothrow) Diffuse;
    if (!d) {
        set_error(error, capacity, "out of memory");
        return nullptr;
    }
    for (int c = 0; c < 3; ++c) d->albedo[c] = static_cast<float>(params->values[0].number[c]);
    return d;
}

void diffuse_destroy(void* instance) {
    delete static_cast<Diffuse*>(instance);
}

void diffuse_prepare(const void* instance, const SpangleShadingBatch_v1* batch, void* closures,
                     SpangleArena_v1*) {
    const auto* d = static_cast<const Diffuse*>(instance);
    auto* out = static_cast<DiffuseClosure*>(closures);
    for (uint32_t i = 0; i < batch->count; ++i)
        out[i] = {{d->albedo[0], d->albedo[1], d->albedo[2]}, 0.0f};
}

void diffuse_eval(const void*, const void* closures, SpangleEvalBatch_v1* q) {
    const auto* cl = static_cast<const DiffuseClosure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const DiffuseClosure& c = cl[q->closure_index ? q->closure_index[i] : i];
        const float cos_i = q->wi_z[i];
        if (cos_i <= 0.0f) {
            q->f_r[i] = q->f_g[i] = q->f_b[i] = q->pdf[i] = 0.0f;
            continue;
        }
        q->f_r[i] = c.albedo[0] * kInvPi;
        q->f_g[i] = c.albedo[1] * kInvPi;
        q->f_b[i] = c.albedo[2] * kInvPi;
        q->pdf[i] = cos_i * kInvPi;
    }
}

/** Cosine-weighted direction from the concentric disk mapping (Shirley and Chiu 1997). */
void cosine_hemisphere(float u0, float u1, float& x, float& y, float& z) {
    const float a = 2.0f * u0 - 1.0f, b = 2.0f * u1 - 1.0f;
    float r, phi;
    if (a == 0.0f && b == 0.0f) {
        r = 0.0f;
        phi = 0.0f;
    } else if (std::fabs(a) > std::fabs(b)) {
        r = a;
        phi = (kPi / 4.0f) * (b / a);
    } else {
        r = b;
        phi = kPi / 2.0f - (kPi / 4.0f) * (a / b);
    }
    x = r * std::cos(phi);
    y = r * std::sin(phi);
    z = std::sqrt(std::fmax(0.0f, 1.0f - x * x - y * y));
}

void diffuse_sample(const void*, const void* closures, SpangleSampleBatch_v1* q) {
    const auto* cl = static_cast<const DiffuseClosure*>(closures);
    for (uint32_t i = 0; i < q->count; ++i) {
        const DiffuseClosure& c = cl[q->closure_index ? q->closure_index[i] : i];
        float x, y, z;
        cosine_hemisphere(q->u0[i], q->u1[i], x, y, z);
        q->wi_x[i] = x;
        q->wi_y[i] = y;
        q->wi_z[i] = z;
        if (z <= 0.0f) {
            q->f_r[i] = q->f_g[i] = q->f_b[i] = q->pdf[i] = 0.0f;
            q->flags[i] = 0;
            continue;
        }
        q->f_r[i] = c.albedo[0] * kInvPi;
        q->f_g[i] = c.albedo[1] * kInvPi;
        q->f_b[i] = c.albedo[2] * kInvPi;
        q->pdf[i] = z * kInvPi;
        q->flags[i] = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_DIFFUSE;
    }
}

// ------------------------------------------------------------------------------------ the table

const SpangleMaterialModel_v1 kModels[] = {
    {"diffuse", "Lambertian diffuse reflection", kDiffuseParams,
     sizeof(kDiffuseParams) / sizeof(kDiffuseParams[0]), sizeof(DiffuseClosure), diffuse_create,
     diffuse_destroy, diffuse_prepare, diffuse_eval, diffuse_sample, nullptr},
};

const SpangleMaterialPlugin_v1 kPlugin = {
    SPANGLE_MATERIAL_ABI_VERSION,
    sizeof(SpangleMaterialPlugin_v1),
    "smooth",
    "smooth microfacet and diffuse materials",
    kModels,
    sizeof(kModels) / sizeof(kModels[0]),
};

}  // namespace

extern "C" SPANGLE_PLUGIN_EXPORT const SpangleMaterialPlugin_v1* spangle_material_plugin(
    uint32_t host_abi_version) {
    return host_abi_version == SPANGLE_MATERIAL_ABI_VERSION ? &kPlugin : nullptr;
}
