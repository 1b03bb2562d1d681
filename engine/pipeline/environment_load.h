#pragma once
// Reading a lat-long environment map (color/image_io.h) and converting it to the working space.

#include "color/color_config.h"
#include "core/log.h"
#include "render/lights.h"
#include "scene/components.h"

namespace spangle {

/** Loads the map; errors name the scene line that names the file. Throws SpangleError. Negative
 *  values (light cannot be negative) are taken as 0, said through `log` where they held more
 *  than a trace of the map's light. */
EnvironmentMap load_environment_map(const EnvironmentMapFile& file, const ColorConfig& color,
                                    const Logger* log = nullptr);

}  // namespace spangle
