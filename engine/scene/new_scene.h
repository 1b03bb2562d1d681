#pragma once
// A scene to start from, around a model someone brings (`spangle new --mesh MODEL`): the model
// standing on a ground plane, lit by an environment map and a key light, the camera framed on
// its bounds, and a flake paint on it whose density is chosen for the framing.

#include <string>
#include <vector>

#include "core/math.h"

namespace spangle {

/** An axis-aligned box, world units. Empty while lo > hi. */
struct Box {
    Vec3 lo{1e30f, 1e30f, 1e30f};     ///< smallest corner
    Vec3 hi{-1e30f, -1e30f, -1e30f};  ///< largest corner
    bool empty() const { return lo.x > hi.x; }
    void add(Vec3 p);
    Vec3 centre() const { return (lo + hi) * 0.5f; }
};

/** What `write_new_scene` is asked for. */
struct NewSceneRequest {
    std::string model;    ///< OBJ, PLY (an object's mesh), glTF or GLB (an [[import]])
    std::string output;   ///< the TOML scene to write
    std::string env_map;  ///< the lat-long map to light it with (an existing file)
    /** The ground plane's PLY, written beside the scene; empty: OUTPUT's stem + "_ground.ply". */
    std::string ground;
    uint32_t width = 1280, height = 720;  ///< the scene's image size, pixels
    /** The model's up axis: "y" (glTF's and most tools'), "z" (CAD, 3ds Max, many scans and
     *  PLYs), "x", or one of them negated ("-z"). The scene turns the model so that it points
     *  up (+y), by `rotate` on its object or import. */
    std::string up = "y";
};

/** What was written, for the command's message and the tests. */
struct NewSceneReport {
    Box model_bounds;  ///< the model's bounds, its own units, turned by `up` (before its offset)
    Vec3 rotate;       ///< Euler degrees written as its `rotate` (0s for up = "y")
    Vec3 offset;       ///< translation that stands it on the ground, centred on y
    Vec3 camera, look_at;  ///< the camera written
    double fov_deg = 0.0;  ///< its vertical field of view
    double density = 0.0;  ///< flakes per square unit of the paint (of the meshes' own units)
    double flakes_per_pixel = 0.0;   ///< expected flakes a pixel sees at the look_at distance
    std::string ground;              ///< the ground plane's path
    std::string paint;               ///< the name of the flake material written
    std::vector<std::string> notes;  ///< what reading the model left out, to be said
};

/** The model's bounds in its own units: every vertex of an OBJ or PLY, or of every object of a
 *  glTF scene placed by its node transforms. Throws SpangleError naming the absolute path when
 *  the model is missing or unreadable. What the readers left out (faces skipped, a glTF's
 *  dropped extensions) is added to `notes`, ready to print. `area_ratio`, when given, is set
 *  to the model's surface area as placed over its area in its meshes' own coordinates (1 for
 *  an OBJ or PLY; 1e-4 for a glTF of centimetre meshes under a node scale of 0.01): an
 *  object-space flake density is per square unit of the latter. Every point is turned by
 *  `orient` (the rotation `up` asks for) before it enters the box. */
Box model_bounds(const std::string& model, std::vector<std::string>* notes = nullptr,
                 double* area_ratio = nullptr, const Affine& orient = Affine{});

/** The Euler angles (degrees, about X, then Y, then Z, as an object's `rotate`) that turn a
 *  model whose up axis is `up` ("x", "y", "z", "-x", "-y" or "-z") to stand along +y. Throws
 *  SpangleError for anything else. */
Vec3 up_rotation(const std::string& up);

/** Writes the scene (and its ground plane PLY) for `r`. Paths in the scene are relative to its
 *  folder where they can be, else absolute. Throws SpangleError when the model or the map is
 *  missing (naming the absolute path tried) or a file cannot be written. */
NewSceneReport write_new_scene(const NewSceneRequest& r);

/** `s` as one word of a POSIX shell command line: itself when it holds only characters no shell
 *  reads specially, else single-quoted (a quote in it as '\''), so that the command `new`
 *  suggests can be pasted whatever the file is called. */
std::string shell_word(const std::string& s);

}  // namespace spangle
