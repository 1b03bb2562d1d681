#pragma once
// A scene as a reader hands it to the builder, in no file format's terms: what the file says,
// checked one value at a time (types, ranges, names of options), with the place each thing is
// written (file:line:col) so that the builder's checks across elements blame the place the user
// wrote. Nothing here is resolved yet: colours keep their numbers and the colour space as
// written, materials and light groups are names, keyframes are keys. The builder
// (scene/scene_builder.h) resolves, checks and fills the Registry.
//
// A reader fills in what its file says and leaves the rest at the defaults below (Spangle's
// defaults; a format with other defaults writes its own). Files a scene names are resolved by
// the reader against the scene's folder and checked to exist (scene/scene_paths.h).

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "core/alpha_channel.h"
#include "core/error.h"
#include "core/map_projection.h"
#include "core/math.h"
#include "core/pixel_filter.h"
#include "geometry/subdivision.h"
#include "geometry/triangle_mesh.h"

namespace spangle {

/** A colour as written: three numbers and the colour space they are in. */
struct ColorDesc {
    Vec3 rgb;                          ///< the numbers as written (finite)
    std::optional<std::string> space;  ///< the space as written; none = bare: render.color_space
    FileLoc loc;                       ///< where the colour is written
    FileLoc space_loc;                 ///< where its space is named (loc when bare)
};

/** An image bound to a material input, and how it is looked up. */
struct TextureDesc {
    std::string path;                  ///< resolved image path (the reader checked it exists)
    std::optional<std::string> space;  ///< colour space as written ("raw" or "data": values are
                                       ///< data); none = the default for the input
    FileLoc space_loc;                 ///< where the space is named
    float scale[3] = {1, 1, 1};        ///< multiplies the looked-up value (per channel)
    float uv[6] = {1, 0, 0, 0, 1, 0};  ///< (u, v) -> (uv0 u + uv1 v + uv2, uv3 u + uv4 v + uv5)
    int wrap = 0;                      ///< 0 periodic, 1 clamp, 2 black, 3 mirror
    int wrap_t = -1;                   ///< along t, where it differs (glTF's wrapT); -1: wrap
    int filter = 0;                    ///< 0 trilinear, 1 anisotropic, 2 closest
    float amount = 1;                  ///< normal map: strength; bump map: height in metres
    float blend = 1;  ///< bump map: how far the bumped normal replaces the surface's (0..1)
    /** alpha: the image channel read; a number parameter: the channel (0 to 2) or kLuminance,
     *  -1 its first (TextureRef::channel). */
    int channel = -1;
    /** A colour parameter: times the mesh's vertex colours (1 where a mesh has none); path may
     *  then be empty (the colours alone, times scale). */
    bool vertex_color = false;
};

/** One material parameter as written, before the plugin's schema checks it. */
struct ParamDesc {
    /** What the value was written as. */
    enum class Kind { Number, Bool, String, Color, Texture };
    std::string name;          ///< the parameter's name
    Kind kind = Kind::Number;  ///< which of the fields below holds the value
    double number = 0;         ///< Number: the value (finite); Bool: 0 or 1
    bool is_integer = false;   ///< Number written as an integer
    std::string text;          ///< String: the value
    ColorDesc color;           ///< Color: the colour
    TextureDesc texture;       ///< Texture: the image
    FileLoc loc;               ///< where the value is written
    FileLoc key_loc;           ///< where the name is written
};

/** A material: a model of a plugin and its parameters. */
struct MaterialDesc {
    std::string name;               ///< the name objects use (the builder checks it is unique)
    std::string plugin;             ///< plugin name, e.g. "smooth"
    std::string model;              ///< model within the plugin; empty = the plugin's only one
    std::vector<ParamDesc> params;  ///< in the order written
    /** normal_map or bump_map (at most one), as a Texture parameter of that name: the host
     *  applies it to the shading frame before the plugin sees the point. */
    std::vector<ParamDesc> maps;
    /** `alpha`: a Number in [0, 1] or a Texture: how much of its surfaces stops rays (a
     *  cut-out: 0 lets them through); none = opaque. */
    std::optional<ParamDesc> alpha;
    /** `alpha_cutoff`: a hit counts where alpha >= this; none = with probability alpha. */
    std::optional<double> alpha_cutoff;
    FileLoc alpha_cutoff_loc;     ///< where alpha_cutoff is written
    bool shadow_catcher = false;  ///< every object in it is a shadow catcher
    /** No warning when no object uses it: a pbrt scene's library of materials (pbrt says
     *  nothing of those either), or the operands of a mix that Spangle replaced by one. */
    bool quiet_unused = false;
    FileLoc loc;         ///< the material as a whole
    FileLoc name_loc;    ///< its name
    FileLoc plugin_loc;  ///< its plugin
    FileLoc model_loc;   ///< its model (loc when not written)
};

/** When a key is: seconds, or a frame of the render settings' range. */
struct KeyTime {
    double seconds = 0.0;          ///< the time, when frame is not set
    std::optional<int64_t> frame;  ///< a frame number: (frame - frame_start) / fps seconds
};

/** Keyframes of one thing, in the order written (the builder checks that time increases). */
template <class Key>
struct Keys {
    std::vector<Key> keys;  ///< empty: not animated
    bool smooth = true;     ///< a smooth spline through the keys, else straight segments
    FileLoc loc;            ///< where the keys are written (blamed for what they do between keys)
};

/** One key of the camera; what it does not give is the camera's own. */
struct CameraKey {
    KeyTime time;                   ///< when
    std::optional<Vec3> position;   ///< eye, world space
    std::optional<Vec3> look_at;    ///< point looked at
    std::optional<Vec3> up;         ///< up hint
    std::optional<double> fov_deg;  ///< vertical field of view, degrees, in (0, 180)
    FileLoc loc;                    ///< the key
    std::string what;               ///< what messages call the key, e.g. "[[camera.keys]] #2"
};

/** A perspective, orthographic or equirectangular camera, pinhole or thin lens. */
struct CameraDesc {
    Vec3 position;                         ///< eye, world space
    Vec3 look_at;                          ///< point looked at
    Vec3 up{0, 1, 0};                      ///< up hint
    double fov_deg = 40.0;                 ///< vertical field of view, degrees, in (0, 180)
    double aperture = 0.0;                 ///< lens radius, metres; 0 = pinhole
    std::optional<double> focus_distance;  ///< metres; none = the distance to look_at
    /** The image is the mirror image of a right-handed camera's: its x runs along up x forward
     *  (pbrt's left-handed camera space). */
    bool mirror = false;
    /** fov spans the image's shorter side (pbrt's convention) instead of its height: resolved
     *  against the size rendered, so that a --size of another aspect frames as pbrt would. */
    bool fov_shorter = false;
    /** pbrt's screen window: x0, x1, y0, y1 of the image in units of tan(fov / 2), y up (fov is
     *  then the window's unit, not the vertical field of view); none = centred, fov vertical. */
    std::optional<std::array<double, 4>> screen;
    FileLoc screen_loc;  ///< where the window is written
    /** An orthographic camera: parallel rays along the view over a view this many scene units
     *  tall (with fov_shorter, its shorter side; with a screen window, the window's unit is half
     *  of it), instead of fov_deg; 0 = perspective. */
    double ortho_height = 0.0;
    /** An equirectangular panorama (`projection = "equirectangular"`): every direction from the
     *  position, 360 degrees of azimuth across the image (the view at its centre, the right to
     *  its right) and 180 of elevation up it; no fov, lens or screen window. */
    bool equirect = false;
    Keys<CameraKey> keys;  ///< its motion
    FileLoc loc;           ///< the camera
    FileLoc look_at_loc;   ///< its look_at (blamed when it meets the position)
    FileLoc up_loc;        ///< its up (blamed when parallel to the view)
};

/** The light group a light, an emissive object or the environment belongs to (render layers). */
struct LightGroupDesc {
    std::string name = "default";  ///< 1 to 64 letters, digits or underscores (the builder checks)
    FileLoc loc;                   ///< where it is named (the owner's loc when not written)
};

/** The environment: a constant colour or a lat-long map. A reader gives at most one of them. */
struct EnvironmentDesc {
    /** A lat-long image. */
    struct Map {
        std::string path;                        ///< resolved image path
        FileLoc loc;                             ///< where it is named
        std::optional<std::string> color_space;  ///< as written; none = lin_rec709
        FileLoc color_space_loc;                 ///< where the space is named
        double rotation_deg = 0.0;               ///< turn about +y (Spangle's projection)
        /** How the image wraps the sphere: Spangle's lat-long, or pbrt's (then `to_world`). */
        MapProjection projection = MapProjection::LatLongYUp;
        Affine to_world;  ///< pbrt's projections: the map's frame to world (a rotation)
    };
    std::optional<ColorDesc> color;  ///< constant radiance; none (and no map) = black
    std::optional<Map> map;          ///< the map, when it is one
    double intensity = 1.0;          ///< scale (non-negative)
    LightGroupDesc group;            ///< its light group
    FileLoc loc;                     ///< the environment
};

/** An object's placement as parts: scale, Euler rotation (degrees), translation. */
struct TransformParts {
    Vec3 scale{1, 1, 1};      ///< per axis, each in [1e-8, 1e8] in size
    Vec3 rotate{0, 0, 0};     ///< degrees about X, then Y, then Z
    Vec3 translate{0, 0, 0};  ///< world-space offset
};

/** Where an object stands: parts (the TOML way, which keys animate), or a matrix. */
struct PlacementDesc {
    TransformParts parts;          ///< used when there is no matrix
    std::optional<Affine> matrix;  ///< object to world as a whole (pbrt, glTF); keys need parts
};

/** One key of an object's placement; the parts it does not give are the object's own. */
struct ObjectKey {
    KeyTime time;                   ///< when
    std::optional<Vec3> scale;      ///< per axis
    std::optional<Vec3> rotate;     ///< degrees
    std::optional<Vec3> translate;  ///< world space
    FileLoc loc;                    ///< the key
    std::string what;               ///< what messages call the key
};

/** One key of an object's placement as a whole matrix (pbrt's ActiveTransform, glTF's node
 *  animations). Between keys the placement is interpolated through its decomposition:
 *  translation and stretch along straight lines, rotation along the shorter arc. */
struct MatrixKey {
    KeyTime time;      ///< when
    Affine matrix;     ///< object to world (invertible)
    FileLoc loc;       ///< the key
    std::string what;  ///< what messages call the key
};

/** A triangle mesh in a file (OBJ, PLY), or a sequence of them, one per frame. */
struct MeshFileShape {
    /** Resolved path; a sequence's pattern (a run of '#' in its file name, scene/frame_sequence.h)
     *  when `sequence`: the builder picks the frame's file. */
    std::string path;
    FileLoc loc;            ///< where it is named
    bool sequence = false;  ///< `path` is a pattern: one file per frame
    /** The rest pose (`rest_mesh`): a mesh of the same topology whose positions object-space
     *  patterns are laid out on. Empty: a sequence rests in the file of frame_start; a single
     *  file is its own rest pose. */
    std::string rest_path;
    FileLoc rest_loc;  ///< where the rest pose is named
};

/** A subdivision surface: a cage in a file, or one the scene file holds itself, and how to
 *  refine it. */
struct SubdivShape {
    std::string path;       ///< resolved cage path (OBJ); empty with an inline cage
    bool sequence = false;  ///< `path` is a pattern: one cage per frame
    /** The rest cage (`rest_mesh`, same topology) whose refinement object-space patterns are
     *  laid out on; empty: a sequence rests in its cage of frame_start, a single cage in
     *  itself. */
    std::string rest_path;
    FileLoc rest_loc;                  ///< where the rest cage is named
    std::shared_ptr<const Cage> cage;  ///< the cage written in the scene (pbrt's loopsubdiv),
                                       ///< validated by the reader; null: read `path`
    FileLoc loc;                       ///< where the cage is named or written
    SubdivOptions options;             ///< scheme, boundaries, creases; level -1 = from the camera
    int max_level = 5;                 ///< upper bound of the camera-chosen level
    float pixel_budget = 2.0f;         ///< camera-chosen level: longest refined edge, in pixels
};

/** A mesh whose shape changes with time, computed rather than read from a file per frame (a
 *  glTF skin or morph-target animation): the builder asks it for the mesh at the time the scene
 *  is evaluated at. Its meshes carry their rest pose (TriangleMesh::rest_positions, the shape
 *  object-space patterns and flakes are laid out on) wherever they differ from it. */
class MeshDeformation {
public:
    virtual ~MeshDeformation() = default;
    /** The mesh at `seconds` (held before the first key and after the last). Throws
     *  SpangleError for a shape that is not finite. */
    virtual std::shared_ptr<const TriangleMesh> at(double seconds) const = 0;
    /** The first and last key times (seconds); first > last: it does not change with time. */
    double first = 0.0, last = -1.0;
    bool animated() const { return first <= last; }
};

/** A triangle mesh written in the scene file itself (pbrt's trianglemesh, glTF's buffers). */
struct InlineMeshShape {
    std::shared_ptr<const TriangleMesh> mesh;  ///< object space; `source` names the scene file
    FileLoc loc;                               ///< where it is written
    /** When its shape changes with time: what gives the mesh at the scene's time (`mesh` is then
     *  its shape at time 0, for whatever looks at the scene before it is built). */
    std::shared_ptr<const MeshDeformation> deformation = nullptr;
};

/** What an object is made of. */
using ShapeDesc = std::variant<MeshFileShape, SubdivShape, InlineMeshShape>;

/** Light an object's surface emits from its front faces (both, when two-sided). */
struct EmissionDesc {
    ColorDesc color;         ///< radiance (non-negative), W/(m^2 sr); 1 with a texture
    double intensity = 1.0;  ///< scale (non-negative)
    LightGroupDesc group;    ///< its light group
    bool two_sided = false;  ///< emits from its back faces too (pbrt's "twosided")
    /** The emission is its material's (a glTF material's emissiveFactor): an importing file
     *  that replaces the material by name replaces it too (scene_import.cpp). */
    bool of_material = false;
    /** An image whose colour (times its `scale`) multiplies the radiance, read at the mesh's
     *  uvs (a screen, a lamp's pattern, glTF's emissiveTexture). */
    std::optional<TextureDesc> texture;
    /** The texture's mean luminance where the reader knew it (glTF), else 1: how much of the
     *  colour's power it emits, for the glTF reader's "does the file light itself" test. */
    double mean = 1.0;
};

/** A placed shape with a material. */
struct ObjectDesc {
    std::string name;             ///< empty when unnamed
    ShapeDesc shape;              ///< its geometry
    std::string material;         ///< a material's name
    PlacementDesc placement;      ///< object to world
    Keys<ObjectKey> keys;         ///< its motion (of the placement's parts)
    Keys<MatrixKey> matrix_keys;  ///< or its motion as whole matrices
    /** The placement of the file it was imported from ([[import]]), applied after its own
     *  (and its motion's); none for an object of the scene itself. */
    std::optional<Affine> parent;
    std::optional<EmissionDesc> emission;  ///< when it is a light
    bool shadow_catcher = false;           ///< renders only the shadows and reflections of others
    FileLoc loc;                           ///< the object
    FileLoc material_loc;                  ///< its material's name
    std::string what;                      ///< what messages call it, e.g. "[[object]] #3"
};

/** A parallelogram area light. */
struct QuadLightDesc {
    Vec3 corner;             ///< one corner, world space
    Vec3 edge1;              ///< first edge from the corner
    Vec3 edge2;              ///< second edge; emits towards edge1 x edge2
    bool two_sided = false;  ///< emits from both faces
    /** Lets every ray through (Cycles' lights): the camera does not see it, it casts no
     *  shadow, and rays that meet it pick up its light and go on. */
    bool transparent = false;
    FileLoc edge2_loc;  ///< blamed when the edges span no area
};

/** A spherical area light. */
struct SphereLightDesc {
    Vec3 center;          ///< world space
    double radius = 1.0;  ///< metres, positive
};

/** A point light. */
struct PointLightDesc {
    Vec3 position;  ///< world space
};

/** A spot light: a point light whose cone falls off towards its edge. */
struct SpotLightDesc {
    Vec3 position;              ///< world space
    Vec3 look_at;               ///< the cone's axis points here
    double cone_angle = 30.0;   ///< the cone's half-angle, degrees, in (0, 90]
    double cone_falloff = 5.0;  ///< degrees inside the edge over which it fades, in [0, 90]
    /** How it fades over the falloff, in t from 0 at the edge to 1 inside: smoothstep
     *  3t^2 - 2t^3 (pbrt-v4's, the default), or t^4 (pbrt-v3's, `falloff = "quartic"`). */
    bool quartic = false;
    FileLoc look_at_loc;       ///< blamed when it meets the position
    FileLoc cone_falloff_loc;  ///< blamed when the falloff exceeds the angle
};

/** A light at infinity: a delta direction or a sun disk. */
struct DistantLightDesc {
    Vec3 direction;                   ///< from the scene towards the light (not normalised)
    double angular_radius_deg = 0.0;  ///< 0 = a delta direction
    FileLoc direction_loc;            ///< blamed when it is zero
};

/** What kind of light, with its own fields. */
using LightShapeDesc =
    std::variant<QuadLightDesc, SphereLightDesc, PointLightDesc, SpotLightDesc, DistantLightDesc>;

/** A light. Its emission is color x intensity: radiance, intensity (W/sr) or irradiance. */
struct LightDesc {
    LightShapeDesc shape;            ///< kind and placement
    std::optional<ColorDesc> color;  ///< non-negative; none = white in the working space
    double intensity = 1.0;          ///< scale (non-negative)
    LightGroupDesc group;            ///< its light group
    FileLoc loc;                     ///< the light
};

/** The smallest noise_threshold (a relative standard error) other than 0: below it no pixel
 *  stops before max_spp, and the value would underflow in float (adaptive sampling off). */
constexpr double kMinNoiseThreshold = 1e-6;

/** What is wrong with a noise threshold given in a scene, on the command line or from Python,
 *  after the name it was given under; empty when nothing is: a number in [0, 1] (not NaN), 0
 *  (off) or at least kMinNoiseThreshold (a tiny one became 0 in float, off, silently). */
inline std::string noise_threshold_problem(double t) {
    if (!(t >= 0.0 && t <= 1.0)) return fmt::format("must be a number in [0, 1], got {}", t);
    if (t > 0.0 && t < kMinNoiseThreshold)
        return fmt::format(
            "{:g} is below {:g}, which no pixel reaches before its max_spp: 0 turns adaptive "
            "sampling off",
            t, kMinNoiseThreshold);
    return {};
}

/** Image size, sampling, colour spaces, frame range and shutter. */
/** The note of a file whose camera is a default framing: dropped when a scene importing the
 *  file has a camera of its own. */
inline constexpr const char* kDefaultCameraNote =
    "the file has no camera: a default framing of its bounds stands in";

struct RenderDesc {
    uint32_t width = 640;                      ///< pixels
    uint32_t height = 360;                     ///< pixels
    uint32_t spp = 16;                         ///< samples per pixel
    uint32_t max_depth = 5;                    ///< maximum bounces
    uint32_t rr_depth = 3;                     ///< bounces before Russian roulette
    uint64_t seed = 0;                         ///< random seed
    FilterKind filter = FilterKind::Gaussian;  ///< pixel filter
    float filter_radius = 0.0f;    ///< its radius in pixels; 0 = the filter's own (0.5, 1.5, 2)
    bool filter_shared = false;    ///< filter_samples = "shared" (false: "own")
    float clamp_indirect = 0.0f;   ///< max luminance of one indirect contribution
    float filter_glossy = 0.0f;    ///< path regularisation; 0 = off (unbiased)
    float noise_threshold = 0.0f;  ///< adaptive sampling; 0 = off, else >= 1e-6
    uint32_t min_spp = 0;          ///< adaptive: samples before a stop; 0 = auto
    uint32_t max_spp = 0;          ///< adaptive: most samples of a pixel; 0 = spp
    bool transparent_background = false;       ///< camera rays do not see the environment
    std::optional<std::string> working_space;  ///< as written; none = the config's, else ACEScg
    std::optional<std::string> color_space;    ///< of bare colours; none = lin_rec709
    int64_t frame_start = 1;                   ///< first frame of the animation
    int64_t frame_end = 1;                     ///< last frame (not before frame_start)
    double fps = 24.0;                         ///< frames per second, positive
    double shutter_open = 0.0;                 ///< frames from the frame's time, in [-16, 16]
    double shutter_close = 0.0;                ///< not before shutter_open; equal = no blur
    /** The image the scene asks to be written (pbrt's Film "filename"); -o wins over it. */
    std::optional<std::string> output;
    FileLoc output_loc;  ///< where it is written
    /** The part of the image the scene asks to render (pbrt's Film "cropwindow"): x0, x1, y0, y1
     *  as fractions of the width and height, y down; --crop wins over it. */
    std::optional<std::array<double, 4>> crop;
    FileLoc crop_loc;             ///< where the crop window is written
    FileLoc size_loc;             ///< where the width (or the height) is written
    FileLoc spp_loc;              ///< where the samples per pixel are written
    FileLoc noise_threshold_loc;  ///< where adaptive sampling's threshold is written
    /** The keys the file wrote (TOML: of [render]); an import fills in the others. Empty for a
     *  reader whose format gives every setting. */
    std::vector<std::string> written;
    /** Whether the file wrote `key` (it is in `written`). */
    bool wrote(std::string_view key) const {
        return std::find(written.begin(), written.end(), key) != written.end();
    }
    FileLoc loc;                ///< the settings (blamed for defaults)
    FileLoc working_space_loc;  ///< where the working space is named
    FileLoc color_space_loc;    ///< where the bare colours' space is named
};

/** Another scene file brought into this one ([[import]]): its objects, materials and lights are
 *  added, the importing file's own materials replace imported ones of the same name, its
 *  camera, environment and render settings win (scene/scene_import.h). */
struct ImportDesc {
    std::string path;         ///< resolved scene file path (any format Spangle reads)
    PlacementDesc placement;  ///< where everything imported is placed
    bool camera = true;       ///< take its camera when the importing file has none
    bool lights = true;       ///< keep its lights
    bool environment = true;  ///< take its environment when the importing file has none
    FileLoc loc;              ///< the [[import]] table
};

/** What a reader may be asked besides the file. */
struct SceneReadOptions {
    std::string camera;  ///< the camera to look through in a file with several (by name)
    /** A lat-long image that replaces the scene's environment (`--env`); empty: the scene's.
     *  A reader that would put a stand-in light into a scene without lights does not when this
     *  is given. */
    std::string environment;
    /** Read as another file's [[import]]: a TOML file without a [camera] is fine (the importing
     *  file or another import gives it; a scene with none anywhere is still an error). */
    bool imported = false;
    /** The image's size is given (`--size`): a reader says nothing of a size its file would
     *  set (a glTF camera's aspect ratio, which --size overrides). */
    bool size_given = false;
    /** The folder of converted textures (--texture-cache; empty: the default folders): a glTF's
     *  embedded images are written under it. */
    std::string texture_cache = {};
};

/** The studio light a glTF file lit by its emission alone would have had without it. */
struct StudioLight {
    EnvironmentDesc environment;
    std::vector<LightDesc> lights;
};

/** Everything a scene file says, in the order written within each kind. */
struct SceneDescription {
    std::string path;  ///< the file it was read from
    /** Every file the reader read besides `path` (included and imported scene files): an edit
     *  of one reloads the scene. */
    std::vector<std::string> files;
    /** The reader's warnings ("file:line: what was dropped and what stands in"), printed by
     *  whoever loads the scene (SceneInfo::notes). */
    std::vector<std::string> notes;
    RenderDesc render;  ///< render settings
    CameraDesc camera;  ///< the camera (every scene has one)
    /** False when the file has no camera of its own (a TOML scene that imports one). */
    bool has_camera = true;
    /** The camera is the one SceneReadOptions::camera named (a glTF file's, by name). */
    bool camera_by_name = false;
    /** The camera is a default framing of the file's bounds (a glTF file without cameras); the
     *  note saying so is kDefaultCameraNote. */
    bool camera_is_default = false;
    std::vector<ImportDesc> imports;             ///< other scene files it brings in
    std::optional<EnvironmentDesc> environment;  ///< none = black, no environment light
    /** A glTF file lit by its emission alone: the studio light it would have had without it,
     *  which an importing file that replaces every emitting material takes instead. */
    std::optional<StudioLight> studio_light;
    std::vector<MaterialDesc> materials;  ///< in the order written
    std::vector<ObjectDesc> objects;      ///< in the order written (numbered from 0)
    std::vector<LightDesc> lights;        ///< in the order written
};

}  // namespace spangle
