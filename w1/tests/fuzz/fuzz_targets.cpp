#include "fuzz_targets.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include "color/color_config.h"
#include "core/error.h"
#include "ecs/registry.h"
#include "geometry/cage.h"
#include "geometry/mesh_load.h"
#include "geometry/subdivision.h"
#include "scene/components.h"
#include "scene/scene_loader.h"

namespace spangle::fuzz {
namespace {

namespace fs = std::filesystem;

/** A private folder in /dev/shm (or $TMPDIR) for the input files, removed at exit. Inputs are
 *  written to ROOT/a/b/; links make the relative paths the seed scenes use resolve as they do
 *  beside the seeds (../../assets/, ../meshes/, meshes/, cages/, ...), so mutated seeds get past
 *  file lookup into the rest of the loader. */
class WorkDir {
public:
    WorkDir() {
        const fs::path base =
            fs::exists("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
        std::string pattern = (base / "spangle-fuzz-XXXXXX").string();
        if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
        root_ = pattern;
        const fs::path assets = SPANGLE_ASSET_DIR;
        const fs::path tests = SPANGLE_TEST_DIR;
        inputs_ = root_ / "a" / "b";
        fs::create_directories(inputs_);
        fs::create_directory_symlink(assets, root_ / "assets");
        fs::create_directory_symlink(assets / "meshes", root_ / "a" / "meshes");
        fs::create_directory_symlink(assets / "env", root_ / "a" / "env");
        for (const char* sub : {"meshes", "cages", "env"})
            fs::create_directory_symlink(tests / "scenes_bad" / sub, inputs_ / sub);
        fs::create_symlink(tests / "scenes" / "uvless_ball.obj", inputs_ / "uvless_ball.obj");
        // The pbrt seeds name their PLY beside them and images one folder up.
        fs::create_symlink(tests / "scenes" / "pbrt" / "twin_box.ply", inputs_ / "twin_box.ply");
        fs::create_directory_symlink(tests / "scenes" / "textures", root_ / "a" / "textures");
    }
    WorkDir(const WorkDir&) = delete;
    WorkDir& operator=(const WorkDir&) = delete;
    ~WorkDir() {
        std::error_code ec;
        fs::remove_all(root_, ec);
    }
    const fs::path& inputs() const { return inputs_; }

private:
    fs::path root_;
    fs::path inputs_;
};

const fs::path& work_dir() {
    static const WorkDir dir;
    return dir.inputs();
}

/** Writes the input to `name` in the work folder and returns its path. */
std::string write_input(const std::string& name, const std::uint8_t* data, std::size_t size) {
    const std::string path = (work_dir() / name).string();
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr) throw std::runtime_error("cannot write " + path);
    const bool ok = size == 0 || std::fwrite(data, 1, size, f) == size;
    if (std::fclose(f) != 0 || !ok) throw std::runtime_error("cannot write " + path);
    return path;
}

ColorConfig& shipped_config() {
    static ColorConfig config = ColorConfig::load(SPANGLE_ASSET_DIR "/ocio/config.ocio", {});
    return config;
}

void scene(const std::uint8_t* data, std::size_t size) {
    const std::string path = write_input("scene.toml", data, size);
    ColorConfig& color = shipped_config();
    ecs::Registry registry;
    load_scene(path, color, registry);
}

/** A pbrt scene (read and built); small inline cages are refined once, as the cage target does,
 *  so that OpenSubdiv's Loop scheme sees what the reader let through. */
void pbrt(const std::uint8_t* data, std::size_t size) {
    const std::string path = write_input("scene.pbrt", data, size);
    ColorConfig& color = shipped_config();
    ecs::Registry registry;
    load_scene(path, color, registry);
    if (auto* pool = registry.find_pool<SubdivSurface>())
        for (std::size_t i = 0; i < pool->size() && i < 4; ++i) {
            const SubdivSurface s = pool->columns().get(i);
            if (!s.cage || s.cage->face_count() > 64 || s.cage->vertex_count() > 256) continue;
            SubdivOptions options = s.options;
            options.level = 1;
            subdivide(*s.cage, options, s.loc);
        }
}

/** A glTF file (JSON or a .glb: the reader tells them by their first bytes), read and built.
 *  Embedded images go to the work folder, not the user's cache. */
void gltf(const std::uint8_t* data, std::size_t size) {
    static const bool cache_set =
        ::setenv("SPANGLE_TEXTURE_CACHE", (work_dir() / "cache").c_str(), 1) == 0;
    (void)cache_set;
    const std::string path = write_input("scene.gltf", data, size);
    ColorConfig& color = shipped_config();
    ecs::Registry registry;
    load_scene(path, color, registry);
}

void mesh(const char* name, const std::uint8_t* data, std::size_t size) {
    const std::string path = write_input(name, data, size);
    load_mesh(path, FileLoc{"fuzz.toml", 1, 1});  // reads and validates
}

void cage(const std::uint8_t* data, std::size_t size) {
    const std::string path = write_input("cage.obj", data, size);
    const FileLoc ref{"fuzz.toml", 1, 1};
    const Cage c = load_cage(path, ref);
    // Small cages are also refined once, so OpenSubdiv sees what the loader let through
    // (non-manifold edges, odd valences, faces sharing vertices in odd orders).
    if (c.face_count() > 64 || c.vertex_count() > 256) return;
    SubdivOptions options;
    options.level = 1;
    subdivide(c, options, ref);
    bool triangles = true;
    for (int n : c.face_sizes) triangles = triangles && n == 3;
    if (triangles) {
        options.scheme = SubdivOptions::Scheme::Loop;
        subdivide(c, options, ref);
    }
}

}  // namespace

bool run_one(const std::string& target, const std::uint8_t* data, std::size_t size) {
    try {
        if (target == "scene")
            scene(data, size);
        else if (target == "pbrt")
            pbrt(data, size);
        else if (target == "gltf")
            gltf(data, size);
        else if (target == "ply")
            mesh("mesh.ply", data, size);
        else if (target == "obj")
            mesh("mesh.obj", data, size);
        else if (target == "cage")
            cage(data, size);
        else
            throw std::invalid_argument("unknown fuzz target '" + target + "'");
        return true;
    } catch (const SpangleError&) {
        return false;
    }
}

}  // namespace spangle::fuzz
