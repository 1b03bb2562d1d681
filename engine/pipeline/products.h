#pragma once
// What the systems make: the components they put on the scene's entities, and the products
// (ecs/products.h) they hand to one another and to the path tracer. Each system's declaration
// (pipeline/systems.h) names which of these it writes and reads.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "accel/embree_scene.h"
#include "ecs/pool.h"
#include "geometry/triangle_mesh.h"
#include "render/lights.h"
#include "shading/material.h"

namespace spangle {

/** Which system made a mesh. */
enum class MeshSource : uint32_t {
    File,         ///< mesh_load: a mesh file
    Subdivision,  ///< subdivide: a refined cage
};

#define SPANGLE_MESH_REF_FIELDS(X)                                      \
    X(MeshSource, source, "which system made it (whose list it is in)") \
    X(uint32_t, mesh, "index into that system's meshes")
/** An object's triangle mesh: written by mesh_load and subdivide, read by the lights, the
 *  materials' uv check and accelerate. */
SPANGLE_COMPONENT(TriangleMeshRef, SPANGLE_MESH_REF_FIELDS);

#define SPANGLE_EMITTER_REF_FIELDS(X) X(int32_t, first, "first light-table entry of its triangles")
/** Written by the area_lights system on emissive objects. */
SPANGLE_COMPONENT(EmitterRef, SPANGLE_EMITTER_REF_FIELDS);

/** mesh_load: one mesh per distinct file, in the order the scene first names them, then one
 *  per distinct inline mesh. */
struct LoadedMeshes {
    static constexpr const char* kName = "LoadedMeshes";
    static constexpr bool kProduct = true;
    std::vector<std::shared_ptr<const TriangleMesh>> meshes;  ///< shared with the build cache
};

/** What the subdivide system did to one surface, for --stats. */
struct SubdivReport {
    std::string cage;          ///< cage file
    int level = 0;             ///< refinement level used
    bool from_camera = false;  ///< level chosen from the camera
    std::size_t cage_faces = 0, triangles = 0;
    double seconds = 0.0;  ///< load + refine + limit
};

/** subdivide: one refined mesh per subdivision surface, in pool order. */
struct SubdividedMeshes {
    static constexpr const char* kName = "SubdividedMeshes";
    static constexpr bool kProduct = true;
    std::vector<std::shared_ptr<const TriangleMesh>> meshes;  ///< shared with the build cache
    std::vector<SubdivReport> reports;                        ///< one per mesh
};

/** materials: one instance per [[material]] entry, null for those no object uses. */
struct MaterialSet {
    static constexpr const char* kName = "MaterialSet";
    static constexpr bool kProduct = true;
    std::vector<std::shared_ptr<MaterialInstance>> instances;
};

/** area_lights: emissive triangles (world space) then quads, and spheres, in the order the
 *  light table takes them. */
struct AreaLightSet {
    static constexpr const char* kName = "AreaLightSet";
    static constexpr bool kProduct = true;
    std::vector<AreaEmitter> areas;      ///< triangles of emissive meshes, then quads
    uint32_t quad_first = 0;             ///< index of the first quad in `areas`
    std::vector<SphereEmitter> spheres;  ///< sphere lights
    /** The images of textured emitters (AreaEmitter::image), null without. */
    std::shared_ptr<const EmissionImages> images;
};

/** point_lights: point and spot lights, lights at infinity. */
struct PointLightSet {
    static constexpr const char* kName = "PointLightSet";
    static constexpr bool kProduct = true;
    std::vector<PointEmitter> points;
    std::vector<DistantEmitter> distant;
};

/** environment: the constant environment and the environment map. */
struct EnvironmentLight {
    static constexpr const char* kName = "EnvironmentLight";
    static constexpr bool kProduct = true;
    Vec3 constant;                              ///< radiance of escaping rays (sum of constants)
    uint32_t constant_group = 0;                ///< its light group
    std::shared_ptr<const EnvironmentMap> map;  ///< null: none (shared with the build cache)
    uint32_t map_group = 0;                     ///< its light group
};

/** accelerate: every placed mesh, and the Embree scene over them and the lights' shapes. */
struct SceneGeometry {
    static constexpr const char* kName = "SceneGeometry";
    static constexpr bool kProduct = true;
    GeometryStore geometry;           ///< loaded meshes, then subdivided ones
    std::vector<Instance> instances;  ///< one per object with a mesh
    /** Kept across reloads: the next build reuses its bottom-level BVHs in place. */
    std::shared_ptr<EmbreeScene> accel;
};

/** One instance's alpha: its material's AlphaMap over its mesh's uvs (CutOut::self). */
struct AlphaCoverage {
    std::shared_ptr<const MaterialInstance> material;  ///< holds the AlphaMap
    std::shared_ptr<const TriangleMesh> mesh;
};

/** cut_outs: the instances rays pass through where their material's alpha says. */
struct CutOutSet {
    static constexpr const char* kName = "CutOutSet";
    static constexpr bool kProduct = true;
    CutOuts per_instance;  ///< indexed as SceneGeometry::instances
    /** By area light index: the instance triangle of an emitting instance with a cut-out (empty
     *  when no such instance emits). */
    std::vector<EmitterCut> emitters;
    /** What per_instance's entries point at. */
    std::vector<std::unique_ptr<AlphaCoverage>> coverage;
};

/** light_selection: every light in one table with its selection distribution. */
struct SceneLights {
    static constexpr const char* kName = "SceneLights";
    static constexpr bool kProduct = true;
    LightTable table;
};

}  // namespace spangle
