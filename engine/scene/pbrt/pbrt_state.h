#pragma once
// What the pbrt reader keeps while it reads: the graphics state and its stack, the current
// transforms, named coordinate systems, textures, materials and object definitions, the camera
// and film as written, and the description being filled. The directive handlers of
// pbrt_reader.cpp, pbrt_shapes.cpp, pbrt_materials.cpp, pbrt_lights.cpp and pbrt_camera.cpp
// share it.

#include <array>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "scene/pbrt/pbrt_params.h"
#include "scene/pbrt/pbrt_reader.h"
#include "scene/scene_description.h"

namespace spangle::pbrt {

/** A 4x4 transform, row-major, for column vectors (p' = M p), in double as pbrt keeps it. */
struct Mat4 {
    double m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    /** Scaling by x, y and z along the axes. */
    static Mat4 scale(double x, double y, double z);
    /** this * o: o applies first. */
    Mat4 operator*(const Mat4& o) const;
    bool operator==(const Mat4&) const = default;
    /** The inverse; none when singular. */
    std::optional<Mat4> inverse() const;
    /** Determinant of the upper-left 3x3 block. */
    double determinant3() const;
    /** A point through the transform (affine part). */
    Vec3 point(Vec3 p) const;
    /** A direction through the linear part. */
    Vec3 vector(Vec3 v) const;
    /** The affine part as Spangle's Affine (the last row is dropped). */
    Affine affine() const;
};

/** The area light that shapes take from AreaLightSource. */
struct AreaLight {
    ColorDesc L;                  ///< radiance as written (x scale), linear
    double scale = 1.0;           ///< "scale"
    bool two_sided = false;       ///< "twosided"
    std::optional<double> power;  ///< v4 "power" (W): radiance scaled so the shape emits it
    FileLoc loc;                  ///< the directive
    /** v4 "filename": an image of radiance read at the shape's uvs (L is then unused). */
    std::optional<TextureDesc> image;
};

/** A texture as Spangle can take it: a constant, or an image lookup with its scale. */
struct TextureValue {
    bool image = false;   ///< an image (`tex`), else the constant `value`
    Vec3 value{1, 1, 1};  ///< the constant (a float texture's value in every channel)
    TextureDesc tex;      ///< the image lookup
    FileLoc loc;          ///< where it is defined
};

/** pbrt's graphics state (what AttributeBegin saves and AttributeEnd restores). */
struct GraphicsState {
    Mat4 ctm[2];                       ///< the current transform at the start and end times
    bool active[2] = {true, true};     ///< which of the two transforms directives change
    std::string material;              ///< Spangle name of the current material; "" = default
    bool no_surface = false;           ///< "interface" / "none": shapes are boundaries only
    std::optional<AreaLight> area;     ///< the area light shapes take
    bool reverse = false;              ///< ReverseOrientation
    std::optional<std::string> space;  ///< v4 ColorSpace of colours; none = srgb
    /** v4 Attribute defaults, per category: shape, light, material, medium, texture. */
    std::map<std::string, ParamList> attributes;
};

/** A shape of an object definition: its object and its transform within the definition. */
struct InstancedShape {
    ObjectDesc object;  ///< shape, material, placement relative to the instance
    Mat4 placement[2];  ///< the definition's transforms at the two times
};

/** The camera as written (converted when the file ends: the fov needs the film). */
struct CameraState {
    std::string type = "perspective";  ///< pbrt's camera type
    Mat4 to_world[2];                  ///< camera to world at the two times
    ParamList params;                  ///< its parameters
    FileLoc loc;                       ///< the directive (none: no Camera)
    bool given = false;                ///< a Camera directive was read
};

/** Everything the reader holds while it reads. */
struct Reader {
    SceneDescription d;                 ///< being filled
    Notes notes;                        ///< the warnings
    PbrtReadInfo info;                  ///< version and counts, for tests
    std::filesystem::path dir;          ///< the main file's folder (pbrt's search path)
    std::filesystem::path current_dir;  ///< folder of the file being read
    GraphicsState gs;                   ///< the graphics state
    /** A block AttributeBegin, TransformBegin or ObjectBegin opened: the state it saved. */
    struct Block {
        char kind;         ///< 'a' attribute, 't' transform, 'o' object
        GraphicsState gs;  ///< the graphics state at its begin
        FileLoc loc;       ///< its begin
    };
    std::vector<Block> stack;  ///< the blocks open, innermost last
    /** Blocks below this depth are not the file's own to end (an Import's importer's). */
    std::size_t stack_floor = 0;
    std::map<std::string, std::array<Mat4, 2>> coord_systems;  ///< named coordinate systems
    std::map<std::string, TextureValue> float_textures;        ///< by name
    std::map<std::string, TextureValue> color_textures;        ///< by name
    std::map<std::string, std::string> materials;  ///< pbrt name -> Spangle material name
    std::map<std::string, std::vector<InstancedShape>> definitions;  ///< object definitions
    std::string defining;  ///< the object being defined; "" = none
    std::map<std::string, std::shared_ptr<const TriangleMesh>> shape_cache;  ///< equal shapes
    CameraState camera;                                                      ///< the camera
    ParamList film, sampler, integrator, filter;                             ///< as written
    FileLoc film_loc, sampler_loc, integrator_loc, filter_loc;               ///< their directives
    std::string film_type, sampler_type, integrator_type, filter_type;       ///< their types
    double time_start = 0.0, time_end = 1.0;                                 ///< TransformTimes
    bool world = false;                                                      ///< after WorldBegin
    int anonymous = 0;                     ///< anonymous materials so far
    std::string default_material;          ///< its name once added; "" = not yet
    std::set<std::string> material_names;  ///< every material's name (unique in Spangle)
    /** Named materials used before they are defined (pbrt-v4 looks them up once the whole
     *  scene is read), each at its first NamedMaterial; objects name them with
     *  kPendingMaterial before the name until the end. */
    std::map<std::string, FileLoc> pending_materials;
    /** Those of them first named by a Material "mix" (its heavier operand). */
    std::set<std::string> pending_from_mix;
    /** Shapes' `alpha` (a Number or an image Texture), each once; a shape's object names its
     *  material with kAlphaMark and the index after it until the end (alpha_materials). */
    std::vector<ParamDesc> alphas;
    /** An environment map whose layout depends on the version (known at the end). */
    bool env_map_pending = false;

    /** Notes a sign that the file is pbrt-v3 (`v4` false) or pbrt-v4. */
    void sign(bool v4, const FileLoc& at, const char* what);
    /** Whether the file reads as pbrt-v4 so far. */
    bool v4() const { return info.version == PbrtVersion::V4; }
    /** A colour as written here: its numbers and the current colour space. */
    ColorDesc color(Vec3 rgb, const FileLoc& at) const;
    /** `given`, a file the scene names at `at`, found against the main file's folder (then the
     *  folder of the file being read). Throws SpangleError when it is not there. */
    std::string find_file(const std::string& given, const char* what, const FileLoc& at) const;
};

// Handlers, one per directive family (each in its own file).

/** Places `o` by the transforms at the two times (TransformTimes): a matrix, and matrix keys when
 *  they differ; into d.objects. A singular transform drops it with a warning. */
void place_object(Reader& r, ObjectDesc o, const Mat4 xf[2]);

/** Marks an object's material as a named material not yet defined (pending_materials). */
inline constexpr const char* kPendingMaterial = "\x1fpending ";

/** Marks an object's material as cut by a shape's alpha (Reader::alphas). */
inline constexpr const char* kAlphaMark =
    "\x1f"
    "alpha ";

/** Shape "type" params: into d.objects, or into the object being defined. */
void read_shape(Reader& r, const std::string& type, ParamList& params, const FileLoc& loc);
/** Texture "name" "float|spectrum" "class" params. */
void read_texture(Reader& r, const std::string& name, const std::string& kind,
                  const std::string& cls, ParamList& params, const FileLoc& loc);
/** Material "type" params, or MakeNamedMaterial "name" ("string type") params: its Spangle
 *  material's name. */
std::string read_material(Reader& r, const std::string& type, const std::string& name,
                          ParamList& params, const FileLoc& loc);
/** The material a shape gets when none was set (added on first use). */
std::string default_material(Reader& r, const FileLoc& loc);
/** LightSource "type" params. */
void read_light(Reader& r, const std::string& type, ParamList& params, const FileLoc& loc);
/** AreaLightSource "type" params: the area light of the shapes that follow. */
void read_area_light(Reader& r, const std::string& type, ParamList& params, const FileLoc& loc);
/** The camera, film, sampler, integrator and filter into d.camera and d.render, once the
 *  whole file is read. */
void finish_camera_and_render(Reader& r);
/** A colour-valued parameter (rgb, spectrum, blackbody) as linear Rec.709 in the current
 *  space; none when absent. `illuminant`: a light's (v4 normalises its luminance). */
std::optional<ColorDesc> color_param(Reader& r, const ParamList& params, const char* name,
                                     bool illuminant);

}  // namespace spangle::pbrt
