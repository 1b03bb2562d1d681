#pragma once
// What the path tracer reads of a built scene (RenderScene: everything borrowed from whoever
// built it) and what it writes (RenderResult: the image, its exact sums, the render layers and
// the counters). The path tracer knows nothing of the systems that built the scene.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "accel/embree_scene.h"
#include "core/sample_sum.h"
#include "geometry/triangle_mesh.h"
#include "render/lights.h"
#include "render/render_options.h"
#include "shading/material.h"

namespace spangle {

/** The built scene as the path tracer sees it. Every pointer is borrowed and outlives the
 *  render; none is null but accel's and cut_outs'. */
struct RenderScene {
    const GeometryStore* geometry = nullptr;  ///< meshes, indexed by Instance::mesh
    const std::vector<Instance>* instances = nullptr;
    /** Indexed by Instance::material; null entries are materials nothing uses. */
    const std::vector<std::shared_ptr<MaterialInstance>>* materials = nullptr;
    const LightTable* lights = nullptr;  ///< next-event estimation and emitters
    uint32_t quad_light_first = 0;       ///< light-table index of the first quad light
    Vec3 environment;                    ///< constant radiance of escaping rays
    uint32_t environment_group = 0;      ///< its light group
    const EmbreeScene* accel = nullptr;  ///< null: nothing to hit
    /** Per instance: where rays pass through it (its material's alpha); empty: nowhere. */
    const CutOuts* cut_outs = nullptr;
    /** By area light index: which cut-out instance triangle it is (empty: none). */
    const std::vector<EmitterCut>* emitter_cuts = nullptr;
    const HostServices* host = nullptr;                      ///< textures (for maps)
    const std::vector<std::string>* light_groups = nullptr;  ///< names, for the layers
    /** Cryptomatte names by [[object]] number and by material index (null: none). */
    const std::vector<std::string>* object_names = nullptr;
    const std::vector<std::string>* material_names = nullptr;
};

/** The render's output. */
struct RenderResult {
    uint32_t width = 0, height = 0;  ///< the image's size (the crop window's)
    ImageWindow window;              ///< where the image lies in the full frame
    std::vector<float> image;        ///< RGB, working space, row-major
    /** The film's exact sums behind `image` (RGB per pixel; core/sample_sum.h). */
    std::vector<SampleSum> sums;
    /** With RenderOptions::layers: layer_names.size() values per pixel, row-major. */
    std::vector<float> layers;
    std::vector<std::string> layer_names;
    RenderStats stats;
};

}  // namespace spangle
