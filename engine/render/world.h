#pragma once
// The context the schedule's systems share: borrowed services (colour, log, plugins) and what the
// systems produce (meshes, acceleration structure, materials, lights, the image).

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "accel/embree_scene.h"
#include "color/color_config.h"
#include "core/log.h"
#include "geometry/triangle_mesh.h"
#include "render/lights.h"
#include "scene/scene_loader.h"
#include "shading/material.h"

namespace spangle {

/** How to render, from the command line; not part of the scene. */
struct RenderOptions {
    Strategy strategy = Strategy::Mis;  ///< for tests and debugging; MIS is always at least as good
    int threads = 0;                    ///< worker threads; 0 = all cores
    uint32_t spp_override = 0;          ///< replaces the scene's spp when non-zero
    uint32_t width_override = 0;        ///< replaces the scene's width when non-zero
    uint32_t height_override = 0;       ///< replaces the scene's height when non-zero
    /** Called with (samples done, samples total) from worker threads, serialised by the
     *  integrator; may be empty. */
    std::function<void(uint64_t, uint64_t)> progress;
};

/** Counters of one render. */
struct RenderStats {
    uint64_t camera_rays = 0;  ///< primary rays
    uint64_t bounce_rays = 0;  ///< continuation rays after scattering
    uint64_t shadow_rays = 0;  ///< next-event visibility rays
    uint64_t samples = 0;      ///< camera samples (pixels x spp)
    uint64_t nonfinite = 0;    ///< contributions replaced by black
    uint32_t first_bad_pixel_x = 0, first_bad_pixel_y = 0, first_bad_sample = 0;
    double seconds = 0.0;  ///< wall time of the render system
};

#define SPANGLE_EMITTER_REF_FIELDS(X) X(int32_t, first, "first light-table entry of its triangles")
/** Written by the area_lights system on emissive objects. */
SPANGLE_COMPONENT(EmitterRef, SPANGLE_EMITTER_REF_FIELDS);

/** What the subdivide system did to one surface, for --stats. */
struct SubdivReport {
    std::string cage;          ///< cage file
    int level = 0;             ///< refinement level used
    bool from_camera = false;  ///< level chosen from the camera
    std::size_t cage_faces = 0, triangles = 0;
    double seconds = 0.0;  ///< load + refine + limit
};

/** Shared state of one frame. */
struct World {
    ColorConfig* color = nullptr;        ///< borrowed
    const Logger* log = nullptr;         ///< borrowed
    PluginLoader* plugins = nullptr;     ///< borrowed
    const HostServices* host = nullptr;  ///< borrowed
    const SceneInfo* info = nullptr;     ///< borrowed
    RenderOptions options;

    std::vector<SubdivReport> subdiv;                          ///< subdivide
    GeometryStore geometry;                                    ///< mesh_load
    std::vector<std::unique_ptr<MaterialInstance>> materials;  ///< materials; null = unused
    LightTable lights;                                         ///< area_lights
    std::vector<Vec3> quad_vertices;                           ///< area_lights: 4 corners per quad
    std::vector<float> sphere_lights;    ///< area_lights: x, y, z, radius per sphere
    uint32_t quad_light_first = 0;       ///< light-table index of the first quad
    Vec3 environment;                    ///< environment
    std::vector<Instance> instances;     ///< accelerate
    std::unique_ptr<EmbreeScene> accel;  ///< accelerate

    uint32_t width = 0, height = 0;  ///< render
    std::vector<float> image;        ///< render: RGB, working space, row-major
    RenderStats stats;               ///< render
};

}  // namespace spangle
