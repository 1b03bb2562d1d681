#pragma once
// A long-lived render session: it owns the live scene (its Registry and everything built from
// it) and applies edits incrementally. load() parses a scene file into a candidate Registry,
// diffs it component by component against the live one, and runs only the systems whose inputs
// changed (components, or files they read); the others hand their results over from the live
// scene. What the running systems build is cached by what produced it (file identities,
// parameters), so an unchanged mesh, material or environment map is reused, not rebuilt. A load
// that fails leaves the live scene as it was. Watch mode is built on this.

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "ecs/registry.h"
#include "render/world.h"

namespace spangle {

/** What one load() changed, ran and reused. */
struct ReloadReport {
    bool first = true;                  ///< the first load: everything was built
    std::vector<std::string> changed;   ///< component types and files that changed
    std::vector<std::string> ran;       ///< systems that ran
    std::vector<std::string> skipped;   ///< systems whose inputs did not change
    std::vector<std::string> built;     ///< what the running systems built
    std::map<std::string, int> reused;  ///< what they took from the cache, by kind
    double seconds = 0.0;               ///< parse + apply

    /** One line: "changed ...; ran ...; rebuilt ...; reused ...". */
    std::string summary() const;
};

class Session {
public:
    /** Loads the OCIO config (`ocio` or $OCIO or the shipped one); throws SpangleError. */
    Session(std::vector<std::string> plugin_dirs, const std::string& ocio, RenderOptions options,
            const Logger& log);
    ~Session();
    Session(const Session&) = delete;
    Session& operator=(const Session&) = delete;

    /** Parses `scene` and makes it the live scene, rebuilding only what changed. Throws
     *  SpangleError (file:line) and then leaves the live scene untouched. `time`: seconds after
     *  the scene's frame_start, where its keyframes are evaluated (an animation renders frame
     *  after frame through one session: only what moved is rebuilt). */
    ReloadReport load(const std::string& scene, double time = 0.0);

    bool has_scene() const { return world_ != nullptr; }
    /** Renders the live scene into world().image (progressively; see RenderOptions). */
    void render();
    /** The live scene's film with the options' size and spp overrides applied; false when the
     *  scene has no camera or film. */
    bool film(Film& out) const;

    World& world() { return *world_; }
    const SceneInfo& info() const { return *info_; }
    const ColorConfig& color() const { return *color_; }
    RenderOptions& options() { return options_; }
    PluginLoader& plugins() { return *plugins_; }

    /** Every file the live scene was built from: the scene, meshes, cages, environment maps,
     *  the OCIO config and the plugin libraries it opened. */
    std::vector<std::string> watched_files() const;

private:
    const Logger& log_;
    RenderOptions options_;
    std::string ocio_request_;
    std::unique_ptr<ColorConfig> color_;
    std::unique_ptr<HostServices> host_;
    std::unique_ptr<PluginLoader> plugins_;
    BuildCache cache_;
    std::unique_ptr<ecs::Registry> live_;
    std::unique_ptr<SceneInfo> info_;
    std::unique_ptr<World> world_;
    /** File identities of the live scene's inputs, by kind ("mesh", "cage", "env", "plugin",
     *  "ocio"). */
    std::map<std::string, std::map<std::string, std::string>> files_;
    /** Colour configs and host services replaced by an OCIO edit: material instances made with
     *  them may still point at them. */
    std::vector<std::unique_ptr<ColorConfig>> old_colors_;
    std::vector<std::unique_ptr<HostServices>> old_hosts_;
};

}  // namespace spangle
