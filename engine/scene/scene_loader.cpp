#include "scene/scene_loader.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "scene/pbrt/pbrt_reader.h"
#include "scene/scene_builder.h"
#include "scene/scene_paths.h"
#include "scene/toml_scene_reader.h"

namespace spangle {

const std::vector<SceneFormat>& scene_formats() {
    static const std::vector<SceneFormat> formats = {
        {".toml", "TOML", &read_toml_scene},
        {".pbrt", "pbrt", &read_pbrt_scene},
        {".pbrt.gz", "pbrt", &read_pbrt_scene},
    };
    return formats;
}

const SceneFormat& scene_format_for(const std::string& path) {
    // The file name's ending, so that a double extension (".pbrt.gz") is one.
    std::string name = std::filesystem::path(path).filename().string();
    std::transform(name.begin(), name.end(), name.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    const std::vector<SceneFormat>& formats = scene_formats();
    for (const SceneFormat& f : formats) {
        const std::string_view ext = f.extension;
        if (name.size() > ext.size() &&
            name.compare(name.size() - ext.size(), ext.size(), ext) == 0)
            return f;
    }
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
