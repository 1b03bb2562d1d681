#pragma once
// A render session: the one pipeline every mode renders through (a one-shot render, --frames,
// --watch, MPI ranks, spangle bench, the accuracy report). It owns the live scene (its Registry
// and everything the systems built from it) and applies edits incrementally: load() reads a scene
// file into a candidate Registry, diffs it component by component against the live one, and runs
// only the systems whose reads changed (components, products of systems that ran, files they
// read); the others hand what they wrote over from the live scene, as their declarations say
// (pipeline/systems.h). What the running systems build is cached by what produced it (file
// identities, parameters), so an unchanged mesh, material or environment map is reused, not
// rebuilt. A load that fails leaves the live scene as it was.

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "ecs/registry.h"
#include "ecs/schedule.h"
#include "pipeline/world.h"
#include "render/render_scene.h"

namespace spangle {

/** What one load() changed, ran and reused. */
struct ReloadReport {
    bool first = true;                  ///< the first load: everything was built
    std::vector<std::string> changed;   ///< component types and files that changed
    std::vector<std::string> ran;       ///< systems that ran
    std::vector<std::string> skipped;   ///< systems whose inputs did not change
    std::vector<std::string> built;     ///< what the running systems built
    std::map<std::string, int> reused;  ///< what they took from the cache, by kind
    /** Every system of the schedule: ran (with its time), or why not ("no QuadLight, ...",
     *  "nothing it reads changed"). */
    std::vector<ecs::SystemReport> systems;
    double seconds = 0.0;  ///< parse + apply

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

    /** Reads `scene` and makes it the live scene, rebuilding only what changed. Throws
     *  SpangleError (file:line) and then leaves the live scene untouched. `time`: seconds after
     *  the scene's frame_start, where its keyframes are evaluated (an animation renders frame
     *  after frame through one session: only what moved is rebuilt). */
    ReloadReport load(const std::string& scene, double time = 0.0);
    /** Reads `scene` and makes frame `frame` of its animation live: its keys and its
     *  sequences' files at that frame's time, (frame - frame_start) / fps after frame_start,
     *  from the file's own frame range (read once: no first load at another time). */
    ReloadReport load_frame(const std::string& scene, int64_t frame);
    /** The same for a scene already read (or made by a program: no file behind it but the
     *  ones it names). */
    ReloadReport load(const SceneDescription& scene, double time = 0.0);

    bool has_scene() const { return world_ != nullptr; }
    /** Renders the live scene into result() (progressively; see RenderOptions). The report
     *  says why not when the scene has no camera or film (result() is then empty). */
    ecs::SystemReport render();
    /** The last render's image, sums, layers and counters. */
    const RenderResult& result() const { return result_; }
    /** Moves the last render's result out (result() is empty afterwards). */
    RenderResult take_result() { return std::move(result_); }
    /** The live scene's film with the options' size and spp overrides applied; false when the
     *  scene has no camera or film. */
    bool film(Film& out) const;

    /** The live scene as the systems built it (its products). */
    const World& world() const { return *world_; }
    const ecs::Registry& registry() const { return *live_; }
    const SceneInfo& info() const { return *info_; }
    const ColorConfig& color() const { return *color_; }
    RenderOptions& options() { return options_; }
    PluginLoader& plugins() { return *plugins_; }
    /** Called by load() with an OCIO config reloaded after an edit (its working space set),
     *  before it becomes live: a throw refuses the load and keeps the live scene and config (the
     *  watch loop checks its display and view: an edit that removed them deleted the preview). */
    std::function<void(const ColorConfig&)> check_reloaded_config;

    /** Every file the live scene was built from: the scene, meshes, cages, environment maps,
     *  textures, the OCIO config and the plugin libraries it opened. */
    std::vector<std::string> watched_files() const;
    /** Whether `path` is a file the live scene's systems read (a mesh, a texture, a plugin) and
     *  holds the bytes it held then: a touch, or a save of the same bytes. False for a file not
     *  read, changed since, or larger than file_content_hash() reads whole. */
    bool holds_what_was_read(const std::string& path) const;
    /** The content hashes of the files the live scene's systems read, but those in `except`,
     *  sorted: the same wherever a machine mounts the same bytes (an MPI rank's check). */
    std::vector<uint64_t> read_content_hashes(const std::vector<std::string>& except) const;

private:
    /** Throws SpangleError (at the scene's size, where it writes one) when the whole frame of the
     *  candidate scene `cand` needs more memory than is available (render/render_options.h). */
    void check_memory(const ecs::Registry& cand, const SceneInfo& info) const;
    /** The options' size and spp, where given, in place of a scene's film's. */
    void apply_overrides(Film& f) const;
    /** The live scene as the path tracer reads it. */
    RenderScene render_scene() const;

    /** How scene files are read under these options (camera, environment, a size given). */
    SceneReadOptions read_options() const {
        SceneReadOptions r{options_.camera, options_.environment};
        r.size_given = options_.width_override != 0 || options_.height_override != 0;
        r.texture_cache = options_.texture_cache;
        return r;
    }

    const Logger& log_;
    bool adaptive_warned_ = false;  ///< the --min-spp/--max-spp without adaptive warning given
    bool panorama_warned_ = false;  ///< the stretched-panorama warning given
    RenderOptions options_;
    std::string ocio_request_;
    std::unique_ptr<ColorConfig> color_;
    std::unique_ptr<HostServices> host_;
    std::unique_ptr<PluginLoader> plugins_;
    BuildCache cache_;
    std::unique_ptr<ecs::Registry> live_;
    std::unique_ptr<SceneInfo> info_;
    std::unique_ptr<World> world_;
    std::string ocio_identity_;  ///< file_identity of the OCIO config when loaded
    uint64_t ocio_bytes_ = 0;    ///< file_content_hash of it then
    /** The files the live scene's systems read: path -> (identity, file_content_hash), so that
     *  a reload hashes only files that changed. */
    std::map<std::string, std::pair<std::string, uint64_t>> file_hashes_;
    RenderResult result_;
    /** Colour configs and host services replaced by an OCIO edit: material instances made with
     *  them may still point at them. */
    std::vector<std::unique_ptr<ColorConfig>> old_colors_;
    std::vector<std::unique_ptr<HostServices>> old_hosts_;
};

}  // namespace spangle
