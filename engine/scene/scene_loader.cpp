#include "scene/scene_loader.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "scene/gltf/gltf_reader.h"
#include "scene/scene_builder.h"
#include "scene/scene_paths.h"
#include "scene/toml_scene_reader.h"

namespace spangle {

const std::vector<SceneFormat>& scene_formats() {
    static const std::vector<SceneFormat> formats = {
        {".toml", "TOML", &read_toml_scene},
        {".gltf", "glTF", &read_gltf_scene},
        {".glb", "glTF", &read_gltf_scene},
    };
    return formats;
}

const SceneFormat& scene_format_for(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    const std::vector<SceneFormat>& formats = scene_formats();
    for (const SceneFormat& f : formats)
        if (ext == f.extension) return f;
    return formats.front();
}

SceneDescription read_scene(const std::string& path, const SceneReadOptions& options) {
    check_scene_file(path);
    return scene_format_for(path).read(path, options);
}

SceneInfo load_scene(const std::string& path, ColorConfig& color, ecs::Registry& registry,
                     double time, const SceneReadOptions& options) {
    return build_scene(read_scene(path, options), color, registry, time);
}

}  // namespace spangle
