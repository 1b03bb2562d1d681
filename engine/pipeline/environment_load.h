#pragma once
// Reading a lat-long environment map (color/image_io.h) and converting it to the working space.

#include "color/color_config.h"
#include "render/lights.h"
#include "scene/components.h"

namespace spangle {

/** Loads the map; errors name the scene line that names the file. Throws SpangleError. */
EnvironmentMap load_environment_map(const EnvironmentMapFile& file, const ColorConfig& color);

}  // namespace spangle
