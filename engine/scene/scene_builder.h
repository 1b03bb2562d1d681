#pragma once
// The scene builder: SceneDescription + colour config + time -> Registry + SceneInfo, whatever
// format the description was read from. It resolves colour spaces (once each, noting the spaces
// that stood in for names the config lacks) and converts colours to the working space; resolves
// material references and light groups; fills in defaults that depend on other values; checks
// across values and elements (a camera that looks nowhere, unknown or duplicate materials,
// degenerate lights, keys out of order); and turns keyframes into motion (scene/keyed_motion.h).
// Its errors point at the places the description records.

#include <cstdint>

#include "color/color_config.h"
#include "core/files.h"
#include "ecs/registry.h"
#include "scene/scene_description.h"
#include "scene/scene_info.h"

namespace spangle {

/** The name an object goes by in the Cryptomatte layers: its `name`, else its mesh or cage
 *  file's name without the folder and ending, else "object<index + 1>". */
std::string object_name(const ObjectDesc& d, uint32_t index);

/** Builds `scene` as it stands at `time` (seconds) into `registry` (which should be empty):
 *  one entity of settings (Film, Camera, CameraMotion), then the environment, the materials,
 *  the objects and the lights, in the description's order. Sets `color`'s working space (one
 *  already set is kept when the scene names none). Throws SpangleError at file:line:col. */
SceneInfo build_scene(const SceneDescription& scene, ColorConfig& color, ecs::Registry& registry,
                      double time = 0.0);

}  // namespace spangle
