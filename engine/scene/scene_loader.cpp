#include "scene/scene_loader.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include <fmt/format.h>

#include "core/text.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/pbrt/pbrt_reader.h"
#include "scene/scene_builder.h"
#include "scene/scene_import.h"
#include "scene/scene_paths.h"
#include "scene/toml_scene_reader.h"

namespace spangle {

const std::vector<SceneFormat>& scene_formats() {
    static const std::vector<SceneFormat> formats = {
        {".toml", "TOML", &read_toml_scene},    {".pbrt", "pbrt", &read_pbrt_scene},
        {".pbrt.gz", "pbrt", &read_pbrt_scene}, {".gltf", "glTF", &read_gltf_scene},
        {".glb", "glTF", &read_gltf_scene},
    };
    return formats;
}

const SceneFormat& scene_format_for(const std::string& path) {
    // The file name's ending, so that a double extension (".pbrt.gz") is one.
    const std::string name = ascii_lower(std::filesystem::path(path).filename().string());
    const std::vector<SceneFormat>& formats = scene_formats();
    for (const SceneFormat& f : formats) {
        const std::string_view ext = f.extension;
        if (name.size() > ext.size() &&
            name.compare(name.size() - ext.size(), ext.size(), ext) == 0)
            return f;
    }
    return formats.front();
}

namespace {

constexpr std::size_t kMaxImportDepth = 16;

/** Reads `path` and, recursively, what it imports; `chain` holds the files being read, to
 *  refuse a file that imports itself. */
SceneDescription read_with_imports(const std::string& path, const SceneReadOptions& options,
                                   std::vector<std::string>& chain) {
    check_scene_file(path);
    check_scene_format(path);
    SceneDescription scene = scene_format_for(path).read(path, options);
    std::error_code ec;
    chain.push_back(std::filesystem::weakly_canonical(path, ec).string());
    resolve_imports(scene, [&](const std::string& imported, const FileLoc& at) {
        const std::string canonical = std::filesystem::weakly_canonical(imported, ec).string();
        if (std::find(chain.begin(), chain.end(), canonical) != chain.end())
            throw_error(at, "'{}' imports itself (through {})", imported, fmt::join(chain, " -> "));
        if (chain.size() >= kMaxImportDepth)
            throw_error(at, "imports nest deeper than {} files", kMaxImportDepth);
        SceneReadOptions as_import = options;
        as_import.imported = true;
        // The importing file's [render] width and height replace the size an import would set
        // (a glTF camera's aspect ratio), so the import says nothing of it.
        as_import.size_given =
            options.size_given || (scene.render.wrote("width") && scene.render.wrote("height"));
        return read_with_imports(imported, as_import, chain);
    });
    chain.pop_back();
    return scene;
}

}  // namespace

// (Read as TOML, the format of names Spangle does not know, such a file failed with a TOML
// syntax error at its first line.)
void check_scene_format(const std::string& path) {
    const std::filesystem::path file(path);
    const std::string ext = ascii_lower(file.extension().string());
    // A gzip'd PLY (".ply.gz", which the `mesh` key reads) is a mesh too.
    if (ext == ".gz") {
        if (ascii_lower(file.stem().extension().string()) == ".ply")
            throw_error(FileLoc{path, 0, 0},
                        "this is a mesh (ply.gz), not a scene: name it as the `mesh` of an "
                        "[[object]] in a TOML scene");
    }
    if (ext == ".obj" || ext == ".ply")
        throw_error(FileLoc{path, 0, 0},
                    "this is a mesh ({}), not a scene: `spangle new --mesh {}` writes a scene "
                    "around it (ground, light, camera, paint), or name it as the `mesh` of an "
                    "[[object]] in a TOML scene",
                    ext.substr(1), path);
    for (const char* other : {".stl", ".fbx", ".usd", ".usda", ".usdc", ".usdz", ".abc", ".blend",
                              ".dae", ".3ds", ".x3d", ".xml"})
        if (ext == other)
            throw_error(FileLoc{path, 0, 0},
                        "Spangle does not read {} files: it reads TOML (.toml), pbrt (.pbrt, "
                        ".pbrt.gz) and glTF (.gltf, .glb) scenes; export to glTF (from Blender, "
                        "or use its Spangle add-on)",
                        ext.substr(1));
}

SceneDescription read_scene(const std::string& path, const SceneReadOptions& options) {
    std::vector<std::string> chain;
    SceneDescription scene = read_with_imports(path, options, chain);
    // --camera that no reader used: the render would look through another camera than the
    // one asked for, without a word (a typo, or a TOML scene's own [camera]).
    if (!options.camera.empty() && !scene.camera_by_name)
        throw_error(FileLoc{path, 0, 0},
                    "--camera '{}': this scene does not choose its camera by name (--camera picks "
                    "among a glTF file's cameras, imported ones too when the scene has no "
                    "[camera] of its own); leave --camera out to render its camera",
                    options.camera);
    if (!options.environment.empty()) {
        // --env: the map lights the scene instead of what the file says (its colour space is
        // the default's, the file type's usual one, as for a map a scene names without one).
        EnvironmentDesc env;
        env.loc = FileLoc{"--env", 0, 0};
        EnvironmentDesc::Map map;
        map.path = options.environment;
        map.loc = env.loc;
        env.map = map;
        if (scene.environment) env.group = scene.environment->group;
        scene.environment = env;
    }
    return scene;
}

SceneInfo load_scene(const std::string& path, ColorConfig& color, ecs::Registry& registry,
                     double time, const SceneReadOptions& options) {
    return build_scene(read_scene(path, options), color, registry, time);
}

}  // namespace spangle
