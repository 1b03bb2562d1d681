#pragma once
// The systems that build a scene for rendering, each declared beside its code with what it
// needs, reads and writes (ecs/schedule.h), and the schedule that orders them. The session runs
// them on the first load and, on a reload, only those whose reads changed.
//
//   mesh_load        MeshFile, InlineMesh         -> TriangleMeshRef, LoadedMeshes
//   subdivide        SubdivSurface (+ the camera)  -> TriangleMeshRef, SubdividedMeshes
//   materials        Material, MaterialRef         -> MaterialSet
//   area_lights      QuadLight, SphereLight, Emission (+ meshes) -> EmitterRef, AreaLightSet
//   point_lights     PointLight, DistantLight      -> PointLightSet
//   environment      Environment, EnvironmentMapFile -> EnvironmentLight
//   accelerate       meshes, placements, lights' shapes -> SceneGeometry
//   cut_outs         AlphaCutOut (+ SceneGeometry, MaterialSet) -> CutOutSet
//   light_selection  the light sets, the scene's bounds -> SceneLights

#include "ecs/schedule.h"
#include "pipeline/world.h"

namespace spangle {

/** The systems above, in order. */
ecs::Schedule<World> build_schedule();

ecs::System<World> mesh_load_system();
ecs::System<World> subdivide_system();
ecs::System<World> materials_system();
ecs::System<World> area_lights_system();
ecs::System<World> point_lights_system();
ecs::System<World> environment_system();
ecs::System<World> accelerate_system();
ecs::System<World> cut_outs_system();
ecs::System<World> light_selection_system();

/** The mesh an object's TriangleMeshRef names (the system that made it must have run). */
const TriangleMesh& mesh_of(const World& w, const TriangleMeshRef& ref);

/** The light group of entity e (every light entity has one from the loader; 0 otherwise). */
uint32_t light_group(const ecs::Registry& r, ecs::Entity e);

}  // namespace spangle
