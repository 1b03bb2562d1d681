#pragma once
// The context the schedule's systems share: borrowed services (colour, log, plugins, textures),
// the products the systems make (pipeline/products.h), and the files each system read.

#include <map>
#include <string>

#include "color/color_config.h"
#include "core/log.h"
#include "ecs/products.h"
#include "pipeline/build_cache.h"
#include "pipeline/products.h"
#include "render/render_options.h"
#include "scene/scene_loader.h"
#include "shading/plugin_loader.h"

namespace spangle {

/** A file a system read, as it was when read. */
struct FileRead {
    std::string kind;      ///< what it is, for reload reports ("mesh", "texture", ...)
    std::string identity;  ///< file_identity() when read
};

/** The kind of a plugin file that was not there when the scene loaded, in a folder searched
 *  before the one its plugin was opened from: watched (its appearance reloads, "new plugin file
 *  PATH"), but not part of the scene's content hash (nodes with other plugin folders merge). */
inline constexpr const char* kAbsentPluginKind = "new plugin";

/** Shared state of one scene's build. */
struct World {
    ColorConfig* color = nullptr;        ///< borrowed
    const Logger* log = nullptr;         ///< borrowed
    PluginLoader* plugins = nullptr;     ///< borrowed
    const HostServices* host = nullptr;  ///< borrowed
    const SceneInfo* info = nullptr;     ///< borrowed
    RenderOptions options;
    BuildCache* cache = nullptr;  ///< borrowed from the session
    /** During a reload, the live scene's world (accelerate rebuilds its BVHs in place); null on
     *  a first load. */
    const World* previous = nullptr;

    ecs::Products products;  ///< what the systems made
    /** Per system: the files it read (path -> kind and identity); an edit of one reruns it. */
    std::map<std::string, std::map<std::string, FileRead>> files;
    std::string system;  ///< the system now running (set by the session)

    /** Records that the running system read `path` (a file of `kind`). */
    void read_file(const char* kind, const std::string& path);
};

}  // namespace spangle
