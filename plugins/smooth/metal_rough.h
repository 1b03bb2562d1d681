#pragma once
// The smooth plugin's metal_rough model: glTF 2.0's metallic-roughness BRDF (glTF 2.0,
// Appendix B) with KHR_materials_ior, _specular and _clearcoat, made energy-preserving by
// albedo scaling. See metal_rough.cpp.

#include <spangle/plugin.h>

namespace spangle::smooth {

/** requirements() of every model of the plugin: none reads a footprint (each is the same
 *  smooth lobe over any area), so a scene of them alone gets none computed. */
inline uint32_t smooth_requirements(const void*) {
    return SPANGLE_IGNORES_FOOTPRINT;
}

/** The model's table entry (schema, closure size, entry points). */
const SpangleMaterialModel_v3& metal_rough_model();

}  // namespace spangle::smooth
