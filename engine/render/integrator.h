#pragma once
// The path tracer: tiles in parallel (oneTBB), each tile traced as a wavefront so that plugins
// are called once per material batch. Next-event estimation with multiple importance sampling
// (power heuristic) for area lights; the constant environment is reached by BSDF sampling.
// Randomness is counter-based, so the image is identical for any thread count.

#include <vector>

#include "render/layers/layer_sink.h"
#include "render/render_options.h"
#include "render/render_scene.h"
#include "scene/components.h"

namespace spangle {

/** Renders the camera's view of `scene` into `out` (width x height RGB, the sums, the layers,
 *  the counters). `camera_steps`: a camera that moves while the shutter is open (CameraMotion),
 *  empty for one that stands still. */
/** The layers a render with `options` writes: the light groups (or "default"), the
 *  environment apart with options.background_apart, a shadow catcher's matte when `catcher`,
 *  the Cryptomatte names. The MPI ranks agree on the channels through it. */
LayerPlan layer_plan(const RenderOptions& options, const std::vector<std::string>* light_groups,
                     const std::vector<std::string>* object_names,
                     const std::vector<std::string>* material_names, bool catcher);

void render_image(const RenderScene& scene, const RenderOptions& options, const Camera& camera,
                  const Film& film, const std::vector<Camera>& camera_steps, RenderResult& out);

}  // namespace spangle
