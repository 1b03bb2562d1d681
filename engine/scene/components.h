#pragma once
// The scene's components. Each is declared once as a field list; SPANGLE_COMPONENT generates the
// element struct and its SoA columns. Colours are RGB in the working space (converted at load).

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/alpha_channel.h"
#include "core/error.h"
#include "core/map_projection.h"
#include "core/math.h"
#include "core/pixel_filter.h"
#include "ecs/pool.h"
#include "geometry/cage.h"
#include "geometry/subdivision.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

namespace ecs {
/** Where a value is written is not scene content. */
inline bool same_value(const FileLoc&, const FileLoc&) {
    return true;
}
}  // namespace ecs

/** An image bound to a material input, as written in the scene. */
struct TextureRef {
    std::string path;            ///< resolved file path
    std::string space;           ///< colour space as written (resolved); "raw" = data; "" = default
    float scale[3] = {1, 1, 1};  ///< multiplies the looked-up value (per channel)
    float uv[6] = {1, 0, 0, 0, 1, 0};  ///< (u, v) -> (uv0 u + uv1 v + uv2, uv3 u + uv4 v + uv5)
    int wrap = 0;                      ///< 0 periodic, 1 clamp, 2 black, 3 mirror
    int wrap_t = -1;                   ///< along t, where it differs (glTF's wrapT); -1: wrap
    /** Both axes' modes in one number: s + 4 t (what the texture lookups take). */
    int wraps() const { return (wrap & 3) + 4 * ((wrap_t < 0 ? wrap : wrap_t) & 3); }
    int filter = 0;    ///< 0 trilinear, 1 anisotropic
    float amount = 1;  ///< normal_map: strength; bump_map: height in metres
    float blend = 1;   ///< bump_map: how far the bumped normal replaces the surface's (0..1)
    /** alpha: the channel read, 0 to 3 (R, G, B, A); kAlphaAuto: A when the image has it, else
     *  its first; kAlphaOrOpaque: A when the image has it, else 1 (glTF's base colour). A number
     *  parameter: 0 to 2, or kLuminance; -1 its first channel. */
    int channel = -1;
    /** Times the mesh's vertex colours (TriangleMesh::colors; 1 where it has none). path is
     *  empty for the colours alone (times scale). */
    bool vertex_color = false;
    bool operator==(const TextureRef&) const = default;
};

/** One material parameter as written in the scene, before validation against a plugin schema. */
struct ParamEntry {
    enum class Kind { Number, Bool, String, Color, Texture };
    std::string name;              ///< key in the scene file
    Kind kind = Kind::Number;      ///< what the TOML value was
    double number[3] = {0, 0, 0};  ///< Number: [0]; Bool: [0] = 0 or 1; Color: working-space RGB
    bool is_integer = false;       ///< Number written as a TOML integer
    std::string text;              ///< String value
    TextureRef texture;            ///< Texture: the image and how to look it up
    FileLoc loc;                   ///< where the value is written
    FileLoc key_loc;               ///< where the key is written
    /** Same name, kind and value (not where it is written). */
    bool operator==(const ParamEntry& o) const {
        return name == o.name && kind == o.kind && number[0] == o.number[0] &&
               number[1] == o.number[1] && number[2] == o.number[2] && is_integer == o.is_integer &&
               text == o.text && texture == o.texture;
    }
};
using ParamList = std::vector<ParamEntry>;

#define SPANGLE_OBJECT_INFO_FIELDS(X)                               \
    X(std::string, name, "the object's name, empty if unnamed")     \
    X(FileLoc, loc, "the [[object]] table")                         \
    X(uint32_t, index, "its [[object]] number in the file, from 0") \
    X(uint8_t, shadow_catcher, "1: a shadow catcher (only the shadows and reflections of others)")
/** What messages about an object call it. */
SPANGLE_COMPONENT(ObjectInfo, SPANGLE_OBJECT_INFO_FIELDS);

#define SPANGLE_TRANSFORM_FIELDS(X) X(Affine, to_world, "object to world")
SPANGLE_COMPONENT(Transform, SPANGLE_TRANSFORM_FIELDS);

#define SPANGLE_MOTION_FIELDS(X)                                                               \
    X(std::vector<Affine>, steps,                                                              \
      "object to world at evenly spaced times from shutter open to close (2 or more); Embree " \
      "and shading interpolate linearly between them")
/** An object that moves while the shutter is open (motion blur); its Transform is the placement
 *  at the shutter's middle. */
SPANGLE_COMPONENT(Motion, SPANGLE_MOTION_FIELDS);

#define SPANGLE_MESH_FILE_FIELDS(X)                                                     \
    X(std::string, path, "resolved mesh file path (a sequence's file of the frame)")    \
    X(FileLoc, loc, "where the scene names the file")                                   \
    X(std::string, rest, "the rest pose's file (same topology); empty: the mesh's own") \
    X(FileLoc, rest_loc, "where the scene names the rest pose (loc for a sequence's own)")
/** A mesh to load from an OBJ or PLY file (input of the mesh_load system), and the rest pose its
 *  object-space shading inputs are taken from when it deforms. */
SPANGLE_COMPONENT(MeshFile, SPANGLE_MESH_FILE_FIELDS);

namespace ecs {
/** An inline mesh is compared by its content hash (InlineMesh::content), not its address: a
 *  reload that reads the same triangles again makes a new mesh with the same content. */
inline bool same_value(const std::shared_ptr<const TriangleMesh>&,
                       const std::shared_ptr<const TriangleMesh>&) {
    return true;
}
}  // namespace ecs

#define SPANGLE_INLINE_MESH_FIELDS(X)                                                      \
    X(std::shared_ptr<const TriangleMesh>, mesh, "object space, made by the scene reader") \
    X(uint64_t, content, "hash of the mesh's content (mesh_content_hash)")                 \
    X(FileLoc, loc, "where the scene writes it")
/** Triangles a scene file holds itself (a pbrt trianglemesh, glTF primitives): input of the
 *  mesh_load system beside mesh files. Objects that share one mesh (instances) share one. */
SPANGLE_COMPONENT(InlineMesh, SPANGLE_INLINE_MESH_FIELDS);

namespace ecs {
/** An inline cage is compared by its content hash (SubdivSurface::cage_content). */
inline bool same_value(const std::shared_ptr<const Cage>&, const std::shared_ptr<const Cage>&) {
    return true;
}
}  // namespace ecs

#define SPANGLE_SUBDIV_FIELDS(X)                                                         \
    X(std::string, path, "resolved cage file path (OBJ); empty with an inline cage")     \
    X(FileLoc, loc, "where the scene names the cage")                                    \
    X(SubdivOptions, options, "scheme, boundaries, creases; level -1 = from the camera") \
    X(int, max_level, "upper bound of the camera-chosen level")                          \
    X(float, pixel_budget, "camera-chosen level: longest refined edge, in pixels")       \
    X(std::shared_ptr<const Cage>, cage, "a cage the scene file holds itself, or null")  \
    X(uint64_t, cage_content, "its content hash (cage_content_hash); 0 without one")     \
    X(std::string, rest, "the rest pose's cage file (same topology); empty: its own")    \
    X(FileLoc, rest_loc, "where the scene names the rest cage (loc for a sequence's own)")
/** A subdivision surface to refine (input of the subdivide system): a cage file or a cage the
 *  scene reader made, and the rest cage its object-space shading inputs are taken from when it
 *  deforms (refined alike). */
SPANGLE_COMPONENT(SubdivSurface, SPANGLE_SUBDIV_FIELDS);

#define SPANGLE_MATERIAL_FIELDS(X)                                                 \
    X(std::string, name, "scene-unique material name")                             \
    X(std::string, plugin, "plugin name, e.g. smooth")                             \
    X(std::string, model, "model name within the plugin, empty = the only one")    \
    X(ParamList, params, "parameters as written")                                  \
    X(ParamList, maps, "normal_map / bump_map, alpha / alpha_cutoff (the host's)") \
    X(FileLoc, loc, "the [[material]] table")                                      \
    X(FileLoc, plugin_loc, "the plugin key")                                       \
    X(FileLoc, model_loc, "the model key, or the table when absent")               \
    X(bool, quiet_unused, "defined by an imported file: no warning when nothing uses it")
/** A material definition (input of the materials system). */
SPANGLE_COMPONENT(Material, SPANGLE_MATERIAL_FIELDS);

#define SPANGLE_MATERIAL_REF_FIELDS(X) X(uint32_t, material, "index of the [[material]] entry")
/** The material an object uses. */
SPANGLE_COMPONENT(MaterialRef, SPANGLE_MATERIAL_REF_FIELDS);

#define SPANGLE_ALPHA_CUT_OUT_FIELDS(X) \
    X(uint32_t, material, "index of the [[material]] entry whose alpha cuts its surfaces")
/** Beside a Material with `alpha`: rays pass through its surfaces where alpha says (input of
 *  the cut-outs system; a scene without one never runs it). */
SPANGLE_COMPONENT(AlphaCutOut, SPANGLE_ALPHA_CUT_OUT_FIELDS);

#define SPANGLE_EMISSION_FIELDS(X)                                       \
    X(Vec3, radiance, "emitted radiance, working-space RGB, W/(m^2 sr)") \
    X(bool, two_sided, "emits from its back faces too")
/** Makes an object's mesh an area light emitting from its front faces (both, when two_sided). */
SPANGLE_COMPONENT(Emission, SPANGLE_EMISSION_FIELDS);

#define SPANGLE_EMISSION_IMAGE_FIELDS(X)                                                     \
    X(TextureRef, texture, "colour image, read at the mesh's uvs, times Emission::radiance") \
    X(FileLoc, loc, "where the scene names it")
/** Beside an Emission: its radiance varies over the surface as an image (a screen, a lamp's
 *  pattern, glTF's emissiveTexture). */
SPANGLE_COMPONENT(EmissionImage, SPANGLE_EMISSION_IMAGE_FIELDS);

#define SPANGLE_QUAD_LIGHT_FIELDS(X)                           \
    X(Vec3, corner, "one corner, world space")                 \
    X(Vec3, edge1, "first edge from the corner")               \
    X(Vec3, edge2, "second edge; emits towards edge1 x edge2") \
    X(Vec3, radiance, "working-space RGB radiance")            \
    X(bool, two_sided, "emit from both faces")                 \
    X(bool, transparent, "lets every ray through: unseen, no shadow")
/** A parallelogram area light. */
SPANGLE_COMPONENT(QuadLight, SPANGLE_QUAD_LIGHT_FIELDS);

#define SPANGLE_SPHERE_LIGHT_FIELDS(X) \
    X(Vec3, center, "world space")     \
    X(float, radius, "metres")         \
    X(Vec3, radiance, "working-space RGB radiance")
/** A spherical area light. */
SPANGLE_COMPONENT(SphereLight, SPANGLE_SPHERE_LIGHT_FIELDS);

#define SPANGLE_POINT_LIGHT_FIELDS(X)                                              \
    X(Vec3, position, "world space")                                               \
    X(Vec3, intensity, "working-space RGB, W/sr")                                  \
    X(Vec3, axis, "spot: unit direction of the cone")                              \
    X(float, cos_outer, "spot: cosine of the cone's half-angle; -1 = point light") \
    X(float, cos_inner, "spot: cosine where the falloff ends")                     \
    X(bool, quartic, "spot: fades as t^4 (pbrt-v3), else smoothstep")
/** A point light, or a spot light when cos_outer > -1. */
SPANGLE_COMPONENT(PointLight, SPANGLE_POINT_LIGHT_FIELDS);

#define SPANGLE_DISTANT_LIGHT_FIELDS(X)                                 \
    X(Vec3, direction, "unit, from the scene towards the light")        \
    X(Vec3, irradiance, "working-space RGB, W/m^2 at normal incidence") \
    X(float, angular_radius_deg, "0 = a delta direction")
/** A light at infinity: a delta direction or a sun disk. */
SPANGLE_COMPONENT(DistantLight, SPANGLE_DISTANT_LIGHT_FIELDS);

#define SPANGLE_LIGHT_GROUP_FIELDS(X) X(uint32_t, group, "index into SceneInfo::light_groups")
/** The light group of a light, an emissive object or the environment (render layers). */
SPANGLE_COMPONENT(LightGroup, SPANGLE_LIGHT_GROUP_FIELDS);

#define SPANGLE_ENVIRONMENT_FIELDS(X) X(Vec3, radiance, "constant radiance seen by escaping rays")
/** A constant-colour environment. */
SPANGLE_COMPONENT(Environment, SPANGLE_ENVIRONMENT_FIELDS);

#define SPANGLE_ENVIRONMENT_MAP_FIELDS(X)                             \
    X(std::string, path, "lat-long image (EXR, HDR, ...)")            \
    X(std::string, color_space, "canonical colour space of the file") \
    X(float, rotation_deg, "turn about +y")                           \
    X(float, intensity, "scale")                                      \
    X(FileLoc, loc, "where the scene names the map")                  \
    X(MapProjection, projection, "how the image wraps the sphere")    \
    X(Affine, to_map, "pbrt's projections: world to the map's frame (a rotation)")
/** An importance-sampled environment map (lat-long, or pbrt's layouts). */
SPANGLE_COMPONENT(EnvironmentMapFile, SPANGLE_ENVIRONMENT_MAP_FIELDS);

/** An image's window on the film plane: x0, x1, y0, y1 in units of tan(fov / 2). */
using ScreenWindow = std::array<float, 4>;

#define SPANGLE_CAMERA_FIELDS(X)                                                               \
    X(Vec3, position, "eye, world space")                                                      \
    X(Vec3, look_at, "point looked at")                                                        \
    X(Vec3, up, "up hint")                                                                     \
    X(float, fov_deg, "vertical field of view, degrees (with a screen window: its unit)")      \
    X(float, aperture, "lens radius, metres; 0 = pinhole")                                     \
    X(float, focus_distance, "distance of the plane in focus, metres")                         \
    X(bool, mirror, "image x along up x forward: pbrt's left-handed camera (mirrored image)")  \
    X(bool, fov_shorter, "fov spans the image's shorter side (pbrt), not its height")          \
    X(ScreenWindow, screen, "pbrt's screen window (y up), tan(fov / 2) units; all 0 = none")   \
    X(float, ortho_height,                                                                     \
      "an orthographic camera's view height in scene units (the screen window's unit is half " \
      "of it); 0 = perspective")                                                               \
    X(bool, equirect,                                                                          \
      "an equirectangular panorama: every direction, 360 degrees across the image and 180 "    \
      "up it, the view at its centre")
/** A perspective, orthographic or panoramic camera; the first two pinhole or thin lens. */
SPANGLE_COMPONENT(Camera, SPANGLE_CAMERA_FIELDS);

namespace ecs {
inline bool same_value(const std::vector<Camera>& a, const std::vector<Camera>& b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end(), Camera::same);
}
}  // namespace ecs

#define SPANGLE_CAMERA_MOTION_FIELDS(X)                                                     \
    X(std::vector<Camera>, steps,                                                           \
      "the camera at evenly spaced times from shutter open to close (2 or more); a sample " \
      "at time s between two steps sees through their fields interpolated linearly")
/** A camera that moves while the shutter is open (motion blur); the Camera component is the
 *  camera at the shutter's middle. */
SPANGLE_COMPONENT(CameraMotion, SPANGLE_CAMERA_MOTION_FIELDS);

#define SPANGLE_FILM_FIELDS(X)                                                            \
    X(uint32_t, width, "pixels")                                                          \
    X(uint32_t, height, "pixels")                                                         \
    X(uint32_t, spp, "samples per pixel")                                                 \
    X(uint32_t, max_depth, "maximum bounces")                                             \
    X(uint32_t, rr_depth, "bounces before Russian roulette")                              \
    X(uint64_t, seed, "random seed")                                                      \
    X(FilterKind, filter, "pixel filter")                                                 \
    X(float, filter_radius, "pixel filter radius, pixels; 0 = the filter's own")          \
    X(uint8_t, filter_shared, "1: samples stay in their pixel, the filter spreads means") \
    X(float, clamp_indirect, "max luminance of one indirect contribution; 0 = off")       \
    X(float, filter_glossy, "path regularisation after rough bounces; 0 = off")           \
    X(float, noise_threshold, "adaptive sampling's noise threshold; 0 = off")             \
    X(uint32_t, min_spp, "adaptive sampling: samples before a pixel may stop; 0 = auto")  \
    X(uint32_t, max_spp, "adaptive sampling: most samples of a pixel; 0 = spp")           \
    X(uint8_t, transparent_background, "1: camera rays do not see the environment")
/** Image size and render settings. */
SPANGLE_COMPONENT(Film, SPANGLE_FILM_FIELDS);

}  // namespace spangle
