#pragma once
// The large procedural scene `spangle bench` measures, so that the engine is measured on more
// than demo spheres: a closed room lit by a ceiling panel and the sun through a window, with 30
// distinct meshes (about 330,000 triangles, no instancing) in 14 materials of both plugins.

#include <string>

namespace spangle {

/** Writes the procedural interior scene (interior.toml and its PLY meshes) into dir, creating
 *  it; returns the scene file's path. Deterministic: the same files on every run. Throws
 *  SpangleError when a file cannot be written. */
std::string write_interior_scene(const std::string& dir);

}  // namespace spangle
