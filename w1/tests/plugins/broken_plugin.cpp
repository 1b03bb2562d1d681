// Deliberately broken material plugins for the loader tests. One source, one variant per
// compile definition; each builds libspangle_<variant>.so in the test plugin directory.

#include <spangle/plugin.h>

#include <cstring>

namespace {

const SpangleParamDesc_v3 kParams[] = {
    {"x", SPANGLE_PARAM_FLOAT, {0.5, 0, 0}, nullptr, 0.0, 1.0, nullptr, "a number", 0},
};

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

const SpangleMaterialModel_v3 kModels[] = {
    {"broken", "a model whose create() always fails", kParams, 1, kClosureSize, create_fails,
     destroy, prepare, eval, sample, nullptr, nullptr},
};

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
#else
    return &kPlugin;
#endif
}
#else
extern "C" SPANGLE_PLUGIN_EXPORT int spangle_something_else() {
    return kPlugin.model_count;
}
#endif
