#pragma once
// What a scene's hash is made of (SceneInfo::content_hash, which `spangle merge` compares): the
// bytes of its files, and the camera it is seen through.

#include <cstdint>
#include <string>
#include <vector>

#include "scene/scene_description.h"

namespace spangle {

/** The hash of a scene file and the files it includes or imports (`files`); the session adds
 *  the files its systems read (meshes, textures, maps) to make SceneInfo::content_hash. */
uint64_t scene_content_hash(const std::string& path, const std::vector<std::string>& files);

/** Hash of the camera looked through, by what it is (place, view, lens, projection, keys), not
 *  by the name it was picked by: `--camera NAME` naming the camera a file looks through anyway
 *  is the same render (crop parts of the two were refused as different scenes). */
uint64_t camera_hash(const CameraDesc& c);

}  // namespace spangle
