#pragma once
// Checks of a glTF file's JSON against what glTF 2.0's schema says of the properties Spangle
// reads, made before tinygltf reads them (it skips what it does not expect without a word).

#include "scene/gltf/gltf_parts.h"

namespace spangle::gltf {

/** Refuses a property of another kind (object, array, number, ...) than the schema gives it, at
 *  its place; the first in the file is said. */
void check_kinds(const Context& ctx);

/** Refuses a material's texture index written negative (tinygltf reads -1 as none written). */
void check_texture_indices(const Context& ctx);

}  // namespace spangle::gltf
