#pragma once
// Loading a scene file into a registry: the reader of the file's format turns it into a
// SceneDescription (scene/scene_description.h), then the builder turns that into components
// (scene/scene_builder.h). Colours are converted to the working space there, once; mesh files
// are only located (the mesh_load system reads them); plugin parameters are kept as written,
// with their locations, for the materials system to validate against the schema.

#include <string>
#include <vector>

#include "color/color_config.h"
#include "ecs/registry.h"
#include "scene/components.h"
#include "scene/scene_description.h"
#include "scene/scene_info.h"

namespace spangle {

/** A scene reader: a file of one format -> its description. Throws SpangleError at
 *  file:line:col for what is wrong in the file. */
using SceneReader = SceneDescription (*)(const std::string& path, const SceneReadOptions& options);

/** A scene file format, known by the file name's extension. */
struct SceneFormat {
    const char* extension;  ///< lower case, with the dot: ".toml"
    const char* name;       ///< for messages: "TOML"
    SceneReader read;       ///< its reader
};

/** The formats load_scene reads, by extension. A new format (.pbrt, .gltf/.glb) is a reader and
 *  one entry here. */
const std::vector<SceneFormat>& scene_formats();

/** The format of `path` by its extension (any case); TOML for a file whose extension is not
 *  listed, as scene files have always been read. */
const SceneFormat& scene_format_for(const std::string& path);

/** Throws SpangleError when `path`'s name says it is a mesh (.obj, .ply, .ply.gz) or another
 *  program's scene (.fbx, .usd, .blend, ...), saying what to do instead; does nothing for the
 *  names of scene formats and names it does not know. */
void check_scene_format(const std::string& path);

/** Reads `path` with the reader of its format. Throws SpangleError at file:line:col. */
SceneDescription read_scene(const std::string& path, const SceneReadOptions& options = {});

/** Reads `path` and builds it into `registry` (which should be empty). Sets `color`'s working
 * space. Throws SpangleError with file:line:col for every problem; never crashes on bad input. */
SceneInfo load_scene(const std::string& path, ColorConfig& color, ecs::Registry& registry,
                     double time = 0.0, const SceneReadOptions& options = {});

}  // namespace spangle
