#pragma once
// Variants of the shipped scenes for the accuracy report: edits of a scene's text, and a session
// that renders them with only the path tracing timed.

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/session.h"

namespace spangle::accuracy {

/** Samples of the untimed render before each timed one: enough for the flake material's
 *  lazily built tables to exist for every view angle the timed render meets. */
constexpr uint32_t kWarmUpSpp = 4;

/** An RGB image in the working space. */
struct Image {
    uint32_t width = 0, height = 0;
    std::vector<float> rgb;  ///< row-major, 3 floats per pixel
    std::size_t pixels() const { return static_cast<std::size_t>(width) * height; }
    /** Mean of the three channels of pixel i ("brightness"). */
    double brightness(std::size_t i) const {
        return (static_cast<double>(rgb[3 * i]) + static_cast<double>(rgb[3 * i + 1]) +
                static_cast<double>(rgb[3 * i + 2])) /
               3.0;
    }
};

/** Edits applied to a shipped scene's text; everything else stays as shipped. */
struct SceneEdit {
    uint32_t width = 0, height = 0;  ///< [render] width and height
    uint64_t seed = 0;               ///< [render] seed: which sample sequences
    std::optional<double> clamp;     ///< [render] clamp_indirect; unset = the scene's value
    std::vector<std::pair<std::string, std::string>> flake;  ///< set on every flake material
    double gamma_scale = 1.0;  ///< multiplies every flake material's gamma
};

/** The shipped scene text with the edit applied and its relative paths ("../") made absolute
 *  against scene_dir, so that the copy can live anywhere. Throws SpangleError when the scene
 *  has no flake material. */
std::string edit_scene(const std::string& shipped, const std::string& scene_dir,
                       const SceneEdit& e);

/** `s` without leading and trailing blanks. */
std::string trim(const std::string& s);

/** Wall seconds since t0. */
double seconds_since(std::chrono::steady_clock::time_point t0);

/** The image after one pass of a progressive render. */
struct Pass {
    uint32_t spp = 0;
    double seconds = 0;  ///< render wall time from the start to the end of this pass
    Image image;
};

/** Every plugin library on the default search path, a line each: its file name and
 *  file_content_hash() (every byte of a library up to 64 MB). What a cached reference is rendered
 *  with, beside its scene text. Taken once, before any session opens a plugin (a library rebuilt
 *  during a run must not key references the loaded one rendered). Throws SpangleError when a
 *  library cannot be read. */
std::string plugins_fingerprint();

/** Renders one scene's variants through a Session, so that meshes, the acceleration structure
 *  and the flake material's tables are built once and only the path tracing is timed. */
class Renderer {
public:
    /** `work_file`: where the scene text is written for the session to load. */
    Renderer(std::string work_file, int threads);

    /** Makes `text` the live scene unless it already is. Throws SpangleError. */
    void load(const std::string& text);

    /** One render of `spp` samples, untimed. */
    Image render(uint32_t spp, Strategy strategy);

    /** A progressive render of `spp` samples: the images after 1, 2, 4, ... samples and at
     *  `spp`, each identical to a render of that many samples (the engine adds every pixel's
     *  samples in the same order), with the time each pass ended. An untimed render of
     *  kWarmUpSpp samples first builds what the flake material builds lazily. */
    std::vector<Pass> render_passes(uint32_t spp, Strategy strategy);

    /** The statistics of the first material that reports any, accumulated since it was built. */
    std::map<std::string, double> material_stats();

private:
    std::string file_, text_;
    Session session_;
};

}  // namespace spangle::accuracy
