#pragma once
// The Python module's session: a Spangle Session plus the scene description it was loaded from,
// so that materials, transforms, the camera and lights can be edited and the scene reloaded
// incrementally (only what an edit changes is rebuilt). Plain C++: python/module.cpp binds it.

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "core/log.h"
#include "pipeline/session.h"
#include "scene/scene_description.h"

namespace spangle::python {

/** A material parameter's value as Python gives it: a number, a flag, a name or a colour. */
using ParamValue = std::variant<bool, long long, double, std::string, std::array<double, 3>>;

/** A render's output: the beauty and every layer, and how far it got. */
struct RenderedImage {
    RenderResult result;
    uint32_t spp = 0;      ///< samples per pixel reached
    bool stopped = false;  ///< stop() ended it before its samples
    std::string scene;     ///< the scene file it came from
    /** Every file the scene read (its file, meshes, textures, maps, plugins, OCIO config):
     *  write() refuses to write over one, as spangle render does. */
    std::vector<std::string> inputs;
    /** The scene as rendered (camera, objects, colour space) and its colour config: write()
     *  labels the image with these, not with the session's state when it is written (an image
     *  written after a later edit or load took that scene's camera, space and names). */
    std::shared_ptr<const SceneInfo> info;
    std::shared_ptr<const ColorConfig> color;
};

/** Progress callbacks, called from render threads with the GIL not held (the bindings take it). */
struct RenderCallbacks {
    std::function<void(uint64_t, uint64_t)> progress;
    std::function<void(const PassImage&)> on_pass;
};

/** Adaptive sampling for one render, as `spangle render --noise-threshold --min-spp --max-spp`
 *  (none: the scene's [render] values). */
struct AdaptiveArgs {
    std::optional<double> noise_threshold;
    std::optional<uint32_t> min_spp, max_spp;
};

/** render()'s denoiser, as `spangle render --denoise --denoise-glints`: off unless `glints` is
 *  given ("keep", "apart" or "filter"). */
struct DenoiseArgs {
    std::optional<std::string> glints;
};

class PySession {
public:
    PySession(std::vector<std::string> plugin_path, const std::string& ocio, int threads,
              bool verbose);

    /** Reads a scene file (any format Spangle reads) and makes it the live scene, built for
     *  `size` (width, height) when given (the scene's own size otherwise). */
    void load(const std::string& path, double time,
              const std::optional<std::pair<uint32_t, uint32_t>>& size);
    bool loaded() const { return loaded_; }
    SceneDescription description() const;

    std::vector<std::string> materials() const;
    /** Sets parameters of material `name` (validated against the plugin's schema by the reload:
     *  a bad value raises and leaves the scene as it was). */
    void set_material(const std::string& name,
                      const std::vector<std::pair<std::string, ParamValue>>& params);

    /** Object names, or "[[object]] #N" for unnamed ones. */
    std::vector<std::string> objects() const;
    void set_transform(const std::string& name, const std::optional<Vec3>& translate,
                       const std::optional<Vec3>& rotate, const std::optional<Vec3>& scale,
                       const std::optional<Affine>& matrix);

    void set_camera(const std::optional<Vec3>& position, const std::optional<Vec3>& look_at,
                    const std::optional<Vec3>& up, const std::optional<double>& fov,
                    const std::optional<double>& aperture,
                    const std::optional<double>& focus_distance,
                    const std::optional<double>& ortho_height = std::nullopt,
                    const std::optional<std::string>& projection = std::nullopt);

    void set_light(std::size_t index, const std::optional<double>& intensity,
                   const std::optional<Vec3>& color, const std::optional<Vec3>& position,
                   const std::optional<double>& radius);

    /** Renders the live scene; stop() from another thread ends it after the waves in flight
     *  (a stop() while no render runs ends the next one after its first pass). The sample
     *  counts are the binding's, checked there (1 to 2^20). */
    RenderedImage render(std::optional<uint32_t> spp,
                         std::optional<std::pair<uint32_t, uint32_t>> size, bool layers,
                         const RenderCallbacks& callbacks, bool background_apart,
                         const AdaptiveArgs& adaptive = {}, const DenoiseArgs& denoise = {});
    void stop() { stop_.store(true); }

    /** The parameters of a plugin's model (the plugin's only model when `model` is empty), as
     *  its schema declares them. */
    std::vector<SpangleParamDesc_v3> parameters(const std::string& plugin,
                                                const std::string& model);

    const ColorConfig& color() const { return session_->color(); }
    const SceneInfo& info() const { return session_->info(); }

private:
    /** Reloads `edited` (the caller holds edit_lock() since it read the description); on
     *  success it becomes the description (else it throws, nothing changed). Refused while the
     *  session renders (from another thread or a callback: the render reads what a reload
     *  frees). */
    void apply_locked(SceneDescription edited);
    /** Locks rendering_ for an edit or a load, waiting for another thread's edit or load; throws
     *  when a render holds it. */
    std::unique_lock<std::mutex> edit_lock();
    /** Throws unless `size` is 1 to 16384 pixels a side. */
    static void check_size(const std::pair<uint32_t, uint32_t>& size);
    ObjectDesc& object_named(SceneDescription& d, const std::string& name) const;

    Logger log_;
    std::unique_ptr<Session> session_;
    SceneDescription desc_;
    mutable std::mutex desc_mutex_;  ///< held while desc_ is read for a copy or replaced
    bool loaded_ = false;
    /** The size load() gave the scene (its own, or load's size=): render(size=None) renders at
     *  it, whatever size an earlier render() asked for. */
    std::pair<uint32_t, uint32_t> base_size_{0, 0};
    double time_ = 0.0;
    std::atomic<bool> stop_{false};
    std::mutex rendering_;
    /** Set while render() holds rendering_: an edit from its own callbacks (the same thread,
     *  which must not try_lock a mutex it holds) is refused by this. */
    std::atomic<bool> busy_{false};
};

/** Where `spangle` was imported from: its plugins, OCIO config and OpenImageIO module are found
 *  there (an installed package), else in the build tree it was built in. */
void set_module_location(const std::string& package_dir);

}  // namespace spangle::python
