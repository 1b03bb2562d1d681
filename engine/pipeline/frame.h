#pragma once
// One frame from a scene file through a Session (the one pipeline): load, build, render, and
// return the image with what happened. spangle bench, the accuracy report and the end-to-end
// tests go through here; the CLI's commands drive a Session themselves.

#include <functional>
#include <string>
#include <vector>

#include "color/color_config.h"
#include "ecs/schedule.h"
#include "pipeline/products.h"
#include "render/render_scene.h"
#include "scene/scene_loader.h"

namespace spangle {

class Session;

/** What to render and with what. */
struct FrameRequest {
    std::string scene;                     ///< scene file
    std::vector<std::string> plugin_dirs;  ///< --plugin-path entries, in order
    std::string ocio_config;               ///< explicit config; empty = $OCIO or the shipped one
    RenderOptions options;                 ///< threads, spp override, progress
    const Logger* log = nullptr;           ///< required
    /** Called once the scene is loaded and built, before it renders, with the colour config
     *  images are written in (for options.on_pass) and every file the scene read (scene files,
     *  meshes, textures, maps, the OCIO config: outputs must not overwrite them); may be empty. */
    std::function<void(const ColorConfig&, const SceneInfo&, const std::vector<std::string>&)>
        on_loaded;
    /** When set, the scene's triangles as traced (subdivided, in world space) are written here
     *  as an OBJ, for other tools (Embree's viewer) to measure the same geometry. */
    std::string export_obj;
    /** Time (seconds after the scene's frame_start) its keyframes are evaluated at. */
    double time = 0.0;
};

/** The rendered frame and its report. */
struct FrameResult {
    ColorConfig color;                        ///< config and working space used
    uint32_t width = 0, height = 0;           ///< image size (the crop window's)
    ImageWindow window;                       ///< where the image lies in the full frame
    std::vector<float> image;                 ///< RGB in the working space
    std::vector<float> layers;                ///< with options.layers: layer_names per pixel
    std::vector<std::string> layer_names;     ///< EXR channel names of the layers
    std::vector<SampleSum> sums;              ///< the film's exact sums (for --spp-range)
    std::vector<ecs::SystemReport> systems;   ///< which systems ran, which were skipped
    std::vector<std::string> plugins_opened;  ///< plugin names opened for this scene
    RenderStats stats;                        ///< counters of the render
    SceneInfo info;                           ///< facts about the scene
    std::vector<SubdivReport> subdiv;         ///< what the subdivide system did
    uint64_t triangles = 0;   ///< triangles of all instances (an instanced mesh counts each time)
    uint64_t mesh_bytes = 0;  ///< memory of the loaded and subdivided meshes
    uint64_t accel_peak_bytes = 0;  ///< most memory Embree held (BVHs and their build)
    uint64_t accel_bytes = 0;       ///< memory Embree held after the build
    /** Statistics each material's plugin reported: (material name, [(name, value)]). */
    std::vector<std::pair<std::string, std::vector<std::pair<std::string, double>>>> material_stats;
};

/** Writes every instance of the live scene's triangles in world space as one OBJ. */
void export_world_obj(const Session& session, const std::string& path);

/** Places where the shipped OCIO config is looked for when neither a path nor $OCIO is given. */
std::vector<std::string> default_ocio_locations();

/** Loads and renders req.scene through a Session. Throws SpangleError for any problem with
 *  the inputs. */
FrameResult render_frame(const FrameRequest& req);

/** Throws at the scene's key (file:line) when a --crop window or --spp-range part does not fit
 *  the image or the samples the loaded scene sets, or splits its adaptive render by samples (the
 *  command line gave no --size or --spp; against those it is a usage error, said with the
 *  options), before anything renders. */
void check_request_fits_scene(Session& session);

}  // namespace spangle
