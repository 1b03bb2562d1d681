#pragma once
// Imports ([[import]] in a TOML scene): other scene files, of any format Spangle reads, brought
// into a scene -- the look-development workflow of taking a car somebody else modelled and
// replacing its paint. For each import in order:
//   objects    are added (before the importing file's own), placed by the import's placement
//              after their own placement and motion;
//   materials  are added, except those the importing file defines under the same name: its
//              own replace them (the imported objects then wear the override); of two imports
//              with a material of one name, the first's is used (noted);
//   lights     are added, placed by the import's placement (lights = false drops them);
//   camera     the importing file's [camera] wins; without one, the first import's camera
//              (camera = true) is used;
//   environment  likewise: the importing file's, else the first import's;
//   render     each [render] key the importing file writes wins; the others come from the
//              first import's settings (Spangle's defaults where it has none).
// Bare colours and keys in frames of an imported file are made explicit first (its colour space,
// its frame range), so that they mean in the importing scene what they meant in their own.

#include <functional>
#include <string>

#include "scene/scene_description.h"

namespace spangle {

/** Reads one scene file (with its own imports resolved). */
using ReadImport = std::function<SceneDescription(const std::string& path, const FileLoc& at)>;

/** Merges every import of `scene` into it, reading each with `read`, and clears
 *  scene.imports. Throws SpangleError when the scene ends without a camera. */
void resolve_imports(SceneDescription& scene, const ReadImport& read);

}  // namespace spangle
