#pragma once
// What a loaded scene is besides its components: paths, colour spaces, names in file order, the
// frame range and shutter, notes for the user. The builder fills it (scene/scene_builder.h).

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "core/math.h"
#include "scene/components.h"

namespace spangle {

/** Facts about the loaded scene that are not components. */
struct SceneInfo {
    std::string path;                ///< the scene file
    std::vector<std::string> files;  ///< scene files it includes or imports
    /** A hash of the bytes of the scene file, the files it includes or imports and, once a
     *  session has built it, every file its systems read (meshes, cages, textures, maps; a file
     *  over 64 MiB by its size alone), and of the camera looked through (what it is, not its
     *  name): written into the EXR header so that `spangle merge` can tell parts of different
     *  scenes or cameras, or of a scene or asset edited between its parts. */
    uint64_t content_hash = 0;
    /** The part of content_hash from the scene files alone (scene_content_hash): a save that
     *  leaves it the same changed nothing the scene says. */
    uint64_t scene_files_hash = 0;
    std::string output;  ///< the image it asks for; empty: none
    FileLoc output_loc;  ///< where the scene names it
    /** The part of the image it asks to render (pbrt's cropwindow): x0, x1, y0, y1 as fractions
     *  of the width and height, y down, 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1; none: all. The
     *  pixels are [ceil(x0 W), ceil(x1 W)) x [ceil(y0 H), ceil(y1 H)), as pbrt takes them. */
    std::optional<std::array<double, 4>> crop;
    FileLoc crop_loc;                         ///< where the scene writes it
    FileLoc size_loc;                         ///< where the scene writes its image size
    FileLoc spp_loc;                          ///< where it writes its samples per pixel
    FileLoc noise_threshold_loc;              ///< where it writes an adaptive threshold
    std::string working_space;                ///< canonical OCIO name
    std::string color_space;                  ///< space of bare colour arrays in the file
    std::vector<std::string> material_names;  ///< in [[material]] order
    Camera camera;                            ///< the [camera] table (also a component)
    /** Warnings for the caller to print: colour spaces that stood in for names the config lacks
     *  ("file:line: 'ACEScg' is not in the OCIO config; using its scene_linear role, ..."),
     *  motion that is not blurred. */
    std::vector<std::string> notes;
    /** Light groups, in order of first use: each light, emissive object and environment names
     *  one with `light_group` ("default" when it does not). The render layers have one per group.
     */
    std::vector<std::string> light_groups;
    /** Animation: the [render] frame range and rate, and whether anything has keys. Frame f is
     *  at time (f - frame_start) / fps seconds. */
    int64_t frame_start = 1, frame_end = 1;
    double fps = 24.0;
    bool animated = false;
    /** The earliest and the latest key of any keyed camera or object (seconds; +inf and -inf
     *  without keys; -inf and +inf with a mesh or cage sequence, whose every frame is a file of
     *  its own): frames past the frame range but within the keys still move. */
    double keys_from = std::numeric_limits<double>::infinity();
    double keys_to = -std::numeric_limits<double>::infinity();
    double time = 0.0;  ///< the time the scene was evaluated at
    /** [render] shutter = [open, close], in frames from the frame's time: the exposure. With
     *  open < close, moving things are blurred over [time + open / fps, time + close / fps]
     *  (components CameraMotion and Motion); everything else is placed at the shutter's middle.
     */
    double shutter_open = 0.0, shutter_close = 0.0;
    bool motion_blur = false;  ///< something moves while the shutter is open
    /** Each [[object]]'s placement (at the shutter's middle), in file order: the render layers'
     *  `object` channel numbers them from 1 and the EXR header carries these. */
    std::vector<Affine> object_to_world;
    /** Per [[object]], in file order: 1 when it is a deforming mesh with a rest pose (a sequence,
     *  or a `rest_mesh`), whose Pobj layer is then the position in its rest pose. Empty when no
     *  object has one. */
    std::vector<uint8_t> rest_pose;
    /** Per [[object]], in file order: its name for the Cryptomatte layers (object_name in
     *  scene_builder.h: `name`, else its mesh file's name). */
    std::vector<std::string> object_names;
    /** Per [[material]], in file order: 1 when its objects are shadow catchers. */
    std::vector<uint8_t> material_catchers;
    /** Per [[object]], in file order: 1 when it is a shadow catcher (its own flag or its
     *  material's). */
    std::vector<uint8_t> shadow_catchers;
};

/** The time of frame f of a scene (in seconds since its frame_start). */
inline double frame_time(const SceneInfo& info, int64_t frame) {
    return static_cast<double>(frame - info.frame_start) / info.fps;
}

}  // namespace spangle
