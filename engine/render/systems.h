#pragma once
// The frame's systems, in order, and the schedule that runs them. Each system reads components
// and writes into World; the schedule skips a system whose inputs are absent.

#include "ecs/schedule.h"
#include "render/world.h"

namespace spangle {

/** mesh_load, materials, area_lights, environment, accelerate, render. */
ecs::Schedule<World> make_frame_schedule();

void system_mesh_load(ecs::Registry& r, World& w);    ///< MeshFile -> TriangleMeshRef
void system_materials(ecs::Registry& r, World& w);    ///< MaterialRef -> plugin instances
void system_area_lights(ecs::Registry& r, World& w);  ///< QuadLight, Emission -> light table
void system_environment(ecs::Registry& r, World& w);  ///< Environment -> world.environment
void system_accelerate(ecs::Registry& r, World& w);   ///< meshes, quads -> Embree scene
void system_render(ecs::Registry& r, World& w);       ///< Camera, Film -> image

}  // namespace spangle
