#pragma once
// The glTF 2.0 scene reader (.gltf with its buffers, or .glb), through tinygltf: the node tree
// and its animations, mesh primitives, cameras, metallic-roughness materials and their
// extensions, KHR_lights_punctual and SPANGLE_materials_flakes, as a SceneDescription.
// docs/gltf.md says what maps onto what and what is dropped with a note.

#include <string>

#include "scene/scene_description.h"

namespace spangle {

/** Reads the glTF file `path`. Throws SpangleError at file:line:col (lines and columns of the
 *  JSON; of a .glb's JSON chunk) for what is wrong in it; notes what it drops. */
SceneDescription read_gltf_scene(const std::string& path, const SceneReadOptions& options);

/** The folders a glTF's embedded images (data URIs, a .glb's buffer views) are written to for
 *  the texture system, in the order tried (gltf_parts.h: embedded_image_dirs). `spangle convert`
 *  copies them out of these. */
std::vector<std::string> gltf_embedded_image_dirs(const std::string& texture_cache = "");

}  // namespace spangle
