// Deliberately broken material plugins for the loader tests. One source, one variant per
// compile definition; each builds libspangle_<variant>.so in the test plugin directory.

#include <spangle/plugin.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace {

#if defined(BROKEN_BADSCHEMA)
// Its default outside its own range: create() would be handed a value the schema forbids.
const SpangleParamDesc_v3 kParams[] = {
    {"x", SPANGLE_PARAM_FLOAT, {5.0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "a number", 0},
};
#else
const SpangleParamDesc_v3 kParams[] = {
    {"x", SPANGLE_PARAM_FLOAT, {0.5, 0, 0}, nullptr, 0.0, 1.0, nullptr, "a number", 0},
};
#endif

void* create_fails(const SpangleParams_v3*, const SpangleHost_v3*, char* error, uint32_t capacity) {
    std::strncpy(error, "x and y cannot both be set", capacity - 1);
    error[capacity - 1] = '\0';
    return nullptr;
}
void destroy(void*) {}
void prepare(const void*, const SpangleShadingBatch_v3*, void*, SpangleArena_v3*) {}
void eval(const void*, const void*, SpangleEvalBatch_v3*) {}
void sample(const void*, const void*, SpangleSampleBatch_v3*) {}

#if defined(BROKEN_MALFORMED)
constexpr uint32_t kClosureSize = 0;  // invalid: the host must reject it
#else
constexpr uint32_t kClosureSize = 16;
#endif

#if defined(BROKEN_KERNELS)
// A diffuse model of albedo 0.5 whose kernels misbehave as parameter `x` asks (x = mode / 10):
// the host must drop or clamp what it cannot use, name the plugin when one throws or crashes.
enum Mode {
    kGood = 0,
    kNanDirection = 1,  // sample(): wi NaN
    kZeroPdf = 2,       // sample(): pdf 0 with f > 0
    kNegativeF = 3,     // sample(): one channel of f negative
    kWrongSide = 4,     // sample(): a reflection under the surface
    kBigGlint = 5,      // sample() and eval(): a glint 100 times f
    kEvalNan = 6,       // eval(): f NaN
    kNoSample = 7,      // sample(): flags 0 (what the bad samples above must amount to)
    kEvalThrows = 8,    // eval(): throws
    kEvalCrashes = 9,   // eval(): writes through a null pointer
    kEvalZero = 10      // eval(): f 0, pdf 0 (what kEvalNan must amount to)
};
struct Instance {
    int mode;
};
void* create_kernels(const SpangleParams_v3* p, const SpangleHost_v3*, char*, uint32_t) {
    return new Instance{static_cast<int>(p->values[0].number[0] * 10.0 + 0.5)};
}
void destroy_kernels(void* i) {
    delete static_cast<Instance*>(i);
}
void eval_kernels(const void* inst, const void*, SpangleEvalBatch_v3* q) {
    const int mode = static_cast<const Instance*>(inst)->mode;
    if (mode == kEvalThrows && q->count > 0) throw std::runtime_error("boom from eval");
    if (mode == kEvalCrashes && q->count > 0) *static_cast<volatile int*>(nullptr) = 1;
    for (uint32_t i = 0; i < q->count; ++i) {
        const float c = q->wi_z[i] > 0.0f ? q->wi_z[i] : 0.0f;
        const float f = mode == kEvalNan    ? std::nanf("")
                        : mode == kEvalZero ? 0.0f
                                            : 0.5f / 3.14159265f;
        q->f_r[i] = q->f_g[i] = q->f_b[i] = c > 0.0f ? f : 0.0f;
        q->pdf[i] = mode == kEvalZero ? 0.0f : c / 3.14159265f;
        if (q->glint_r && mode == kBigGlint)
            q->glint_r[i] = q->glint_g[i] = q->glint_b[i] = 100.0f * f;
    }
}
void sample_kernels(const void* inst, const void*, SpangleSampleBatch_v3* q) {
    const int mode = static_cast<const Instance*>(inst)->mode;
    for (uint32_t i = 0; i < q->count; ++i) {
        // Cosine-weighted (Malley): a disc point lifted to the hemisphere.
        const float r = std::sqrt(q->u0[i]), phi = 6.2831853f * q->u1[i];
        const float z = std::sqrt(std::max(0.0f, 1.0f - q->u0[i]));
        q->wi_x[i] = r * std::cos(phi);
        q->wi_y[i] = r * std::sin(phi);
        q->wi_z[i] = mode == kWrongSide ? -z : z;
        const float f = 0.5f / 3.14159265f;
        q->f_r[i] = q->f_g[i] = q->f_b[i] = f;
        q->pdf[i] = z / 3.14159265f;
        q->flags[i] = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_DIFFUSE;
        if (mode == kNanDirection) q->wi_x[i] = std::nanf("");
        if (mode == kZeroPdf) q->pdf[i] = 0.0f;
        if (mode == kNegativeF) q->f_g[i] = -f;
        if (mode == kNoSample) {
            q->flags[i] = 0;
            q->f_r[i] = q->f_g[i] = q->f_b[i] = q->pdf[i] = 0.0f;
        }
        if (q->glint_r && mode == kBigGlint)
            q->glint_r[i] = q->glint_g[i] = q->glint_b[i] = 100.0f * f;
    }
}
const SpangleMaterialModel_v3 kModels[] = {
    {"broken", "a diffuse model whose kernels misbehave as x asks", kParams, 1, kClosureSize,
     create_kernels, destroy_kernels, prepare, eval_kernels, sample_kernels, nullptr, nullptr},
};
#else
const SpangleMaterialModel_v3 kModels[] = {
    {"broken", "a model whose create() always fails", kParams, 1, kClosureSize, create_fails,
     destroy, prepare, eval, sample, nullptr, nullptr},
};
#endif

#if defined(BROKEN_ABI)
constexpr uint32_t kAbi = 999;
#else
constexpr uint32_t kAbi = SPANGLE_MATERIAL_ABI_VERSION;
#endif

#if defined(BROKEN_MISNAMED)
constexpr const char* kName = "someone_else";
#else
constexpr const char* kName = PLUGIN_NAME;
#endif

const SpangleMaterialPlugin_v3 kPlugin = {
    kAbi, sizeof(SpangleMaterialPlugin_v3), kName, "a broken test plugin", kModels, 1};

}  // namespace

#if defined(BROKEN_DATAENTRY)
// The entry point's name exported as data: calling it would jump into the plugin table.
extern "C" SPANGLE_PLUGIN_EXPORT const SpangleMaterialPlugin_v3 spangle_material_plugin = kPlugin;
#elif !defined(BROKEN_NOENTRY)
extern "C" SPANGLE_PLUGIN_EXPORT const SpangleMaterialPlugin_v3* spangle_material_plugin(uint32_t) {
#if defined(BROKEN_REFUSES)
    return nullptr;
#elif defined(BROKEN_THROWENTRY)
    throw std::runtime_error("boom from the entry point");
#else
    return &kPlugin;
#endif
}
#else
extern "C" SPANGLE_PLUGIN_EXPORT int spangle_something_else() {
    return kPlugin.model_count;
}
#endif
