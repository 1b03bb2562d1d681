#pragma once
// The TOML scene reader: a .toml scene file -> SceneDescription. It knows TOML and nothing of
// the registry or the colour config: it reports syntax errors, wrong types, unknown keys (with
// "did you mean"), values out of range and unknown option names, each at file:line:col, and
// finds the files the scene names. Checks across elements are the builder's.

#include <string>

#include "scene/scene_description.h"

namespace spangle {

/** Reads the TOML scene file at `path` (which exists; load_scene checks) into a description.
 *  Throws SpangleError at file:line:col for every problem it can see in the file alone. */
SceneDescription read_toml_scene(const std::string& path, const SceneReadOptions& options = {});

}  // namespace spangle
