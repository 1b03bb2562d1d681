#pragma once
// glTF accessors as numbers: the elements of a typed view into a buffer (strided, of any
// component type, normalised or not, sparse or not), every byte checked to lie inside its
// buffer. Internal to engine/scene/gltf/.

#include <cstdint>
#include <vector>

#include "scene/gltf/gltf_context.h"

namespace spangle::gltf {

/** Accessor `index` (the value of JSON path `ref`) as `components` floats per element: it must
 *  have that many components (`what` names it in messages); integer components are converted
 *  as the accessor's `normalized` says. Throws SpangleError at the accessor, also for a value
 *  that is not a finite float unless `finite` is false. */
std::vector<float> read_floats(const Context& ctx, int index, int components, const char* what,
                               const std::string& ref, bool finite = true);

/** read_floats() of an attribute of a primitive of nv vertices: an error at `ref` unless it
 *  has one element per vertex. */
std::vector<float> read_per_vertex(const Context& ctx, int index, int components, std::size_t nv,
                                   const char* what, const std::string& ref, bool finite = true);

/** Accessor `index` as unsigned integers (a scalar of unsigned byte, short or int: indices).
 *  Throws SpangleError at the accessor. */
std::vector<uint32_t> read_indices(const Context& ctx, int index, const std::string& ref);

/** The number of elements of accessor `index` (checked to exist). */
std::size_t accessor_count(const Context& ctx, int index, const std::string& ref);

}  // namespace spangle::gltf
