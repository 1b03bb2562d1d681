#pragma once
// `spangle bench`: renders fixed scenes, each in its own process, and prints what any change to
// the engine should be compared by: samples and rays per second, time per phase, peak memory.
// Among them the large procedural interior (interior_scene.h), written on first use.

#include <string>
#include <vector>

namespace spangle {

/** Options of `spangle bench`. */
struct BenchArgs {
    std::vector<std::string> scenes;  ///< scene files or shipped names; empty = the default set
    std::string size = "640x360";     ///< image size of every scene, as given ('' = the scene's)
    uint32_t width = 0, height = 0;   ///< size, parsed by the caller (0 = the scene's)
    uint32_t spp = 16;                ///< samples per pixel of every scene
    int threads = 0;                  ///< worker threads (0 = all cores)
    int repeat = 1;                   ///< renders per scene; the fastest is reported
    std::vector<std::string> plugin_dirs;
    std::string work_dir;      ///< where generated scenes go (default: a folder in the temp dir)
    std::string csv;           ///< also write the table as CSV here
    std::string export_obj;    ///< with one scene: also write its traced triangles as an OBJ
    bool measure_one = false;  ///< internal: measure scenes[0] in this process, print the result
};

/** Runs the benchmark; returns the process exit code. */
int run_bench(const BenchArgs& args);

}  // namespace spangle
