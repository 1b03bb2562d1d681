#pragma once
// The frame's systems, in order, and the schedule that runs them. Each system reads components
// and writes into World; the schedule skips a system whose inputs are absent.

#include "ecs/schedule.h"
#include "render/world.h"

namespace spangle {

/** mesh_load, materials, area_lights, point_lights, environment, accelerate, light_selection,
 *  render. */
ecs::Schedule<World> make_frame_schedule();

void system_subdivide(ecs::Registry& r, World& w);  ///< SubdivSurface -> TriangleMeshRef
void system_mesh_load(ecs::Registry& r, World& w);  ///< MeshFile -> TriangleMeshRef
void system_materials(ecs::Registry& r, World& w);  ///< MaterialRef -> plugin instances
/** Part of system_materials: warns about objects whose material needs uvs their mesh lacks. */
void warn_about_missing_uvs(ecs::Registry& r, World& w);
void system_area_lights(ecs::Registry& r, World& w);      ///< QuadLight, SphereLight, Emission
void system_point_lights(ecs::Registry& r, World& w);     ///< PointLight, DistantLight
void system_environment(ecs::Registry& r, World& w);      ///< Environment, EnvironmentMapFile
void system_light_selection(ecs::Registry& r, World& w);  ///< power distribution over lights
void system_accelerate(ecs::Registry& r, World& w);       ///< meshes, quads -> Embree scene
void system_render(ecs::Registry& r, World& w);           ///< Camera, Film -> image

}  // namespace spangle
