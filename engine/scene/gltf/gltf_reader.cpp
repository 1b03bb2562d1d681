#include "scene/gltf/gltf_reader.h"

#include "scene/gltf/gltf_parts.h"

namespace spangle {

SceneDescription read_gltf_scene(const std::string& path, const SceneReadOptions& options) {
    SceneDescription scene;
    scene.path = path;
    gltf::Context ctx;
    ctx.path = path;
    ctx.dir = std::filesystem::path(path).parent_path();
    ctx.scene = &scene;
    ctx.texture_cache = options.texture_cache;
    gltf::load_document(ctx);
    gltf::read_nodes(ctx, options);
    ctx.finish_notes();
    return scene;
}

}  // namespace spangle
