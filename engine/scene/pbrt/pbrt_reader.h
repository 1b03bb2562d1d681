#pragma once
// The pbrt-v3 and pbrt-v4 scene reader: a .pbrt file (gzip'd too) and the files it includes or
// imports, into a SceneDescription. The version is told from the file's directives and spellings
// (v4: ColorSpace, Option, Attribute, Import, Film "rgb", its material names, bilinear meshes,
// one-number blackbodies; v3: WorldEnd, TransformBegin, Film "image", its material names, "area"
// lights); where a spelling means different things in the two, the version decides. What Spangle
// cannot render is dropped with one warning (SceneDescription::notes) naming what stands in.
// docs/pbrt.md lists what maps onto what.

#include <string>

#include "core/error.h"
#include "scene/scene_description.h"

namespace spangle {

/** Which pbrt a file is written for. */
enum class PbrtVersion { Unknown, V3, V4 };

/** What the reader told about a file besides its description (for tests and messages). */
struct PbrtReadInfo {
    PbrtVersion version = PbrtVersion::Unknown;  ///< V4 when any v4 sign was seen
    std::string v3_sign, v4_sign;                ///< the first sign of each, "file:line: what"
    std::size_t shapes = 0;                      ///< Shape directives read (instanced ones once)
    std::size_t instances = 0;                   ///< ObjectInstance directives placed
};

/** Reads the pbrt scene `path`. Throws SpangleError at file:line:col for a syntax error, a
 *  missing file or a value that cannot stand. */
SceneDescription read_pbrt_scene(const std::string& path, const SceneReadOptions& options);

/** read_pbrt_scene that also tells what it found. */
SceneDescription read_pbrt_scene(const std::string& path, const SceneReadOptions& options,
                                 PbrtReadInfo& info);

/** Reads pbrt text held in memory as if it were the file `name` (the fuzz target, tests):
 *  included files are found against `name`'s folder. */
SceneDescription read_pbrt_text(const std::string& name, std::string text, PbrtReadInfo& info);

}  // namespace spangle
