#pragma once
// The context the schedule's systems share: borrowed services (colour, log, plugins) and what the
// systems produce (meshes, acceleration structure, materials, lights, the image).

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "accel/embree_scene.h"
#include "color/color_config.h"
#include "core/log.h"
#include "core/sample_sum.h"
#include "geometry/cage.h"
#include "geometry/triangle_mesh.h"
#include "render/lights.h"
#include "scene/scene_loader.h"
#include "shading/material.h"

namespace spangle {

/** A crop window in pixels of the full image: [x0, x1) x [y0, y1); x1 == 0: the whole image. */
struct CropWindow {
    uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    bool whole() const { return x1 == 0; }
};

/** The pixels `crop` renders of a width x height image (the whole image for whole()); throws
 *  SpangleError when the window is empty or not inside the image. */
CropWindow crop_within(const CropWindow& crop, uint32_t width, uint32_t height);

/** Where a (cropped) image lies in the full frame: its top-left pixel and the full size. */
struct ImageWindow {
    uint32_t x0 = 0, y0 = 0;
    uint32_t full_width = 0, full_height = 0;
};

/** The image after one pass of a progressive render. */
struct PassImage {
    const std::vector<float>& image;  ///< RGB, working space, divided by the samples reached
    uint32_t width, height;
    uint32_t spp;        ///< samples per pixel reached; 0 for a preview pass
    uint32_t target;     ///< samples per pixel the render is going to
    uint32_t block;      ///< 1, or the block side of a preview pass (each block one value)
    double seconds;      ///< render time so far
    ImageWindow window;  ///< where the image lies in the full frame (a crop)
};

/** How to render, from the command line; not part of the scene. */
struct RenderOptions {
    Strategy strategy = Strategy::Mis;  ///< for tests and debugging; MIS is always at least as good
    int threads = 0;                    ///< worker threads; 0 = all cores
    uint32_t spp_override = 0;          ///< replaces the scene's spp when non-zero
    uint32_t width_override = 0;        ///< replaces the scene's width when non-zero
    uint32_t height_override = 0;       ///< replaces the scene's height when non-zero
    /** Called with (samples done, samples total) from worker threads, serialised by the
     *  integrator; may be empty. */
    std::function<void(uint64_t, uint64_t)> progress;
    /** Called after each completed pass but the last with the image so far; may be empty. */
    std::function<void(const PassImage&)> on_pass;
    /** Polled between waves of tiles: when it returns true the render stops, keeping the
     *  passes completed so far. May be empty. */
    std::function<bool()> stop;
    /** Passes of 1, 1, 2, 4, ... samples (false: one pass of all samples; same image). */
    bool progressive = true;
    /** Before the first pass, a preview pass at reduced resolution (one path per block of
     *  preview_stride() pixels, shown through on_pass and then dropped): the first picture after
     *  an edit in a fraction of a full pass. The final image does not depend on it. */
    bool preview_pass = false;
    /** Render layers beside the beauty (world.layers): coverage, albedo, normal, depth,
     *  position, glints, one per light group. */
    bool layers = false;
    /** Renders only this window of the image (its pixels are those of the whole render, bit
     *  for bit: each pixel's samples depend on the pixel alone). */
    CropWindow crop;
    /** --spp-range: render samples [spp_first, spp_end) of the frame's (spp_end 0: all). The
     *  image is their mean; world.sums holds their exact sums, which add up across parts to
     *  the whole render's, bit for bit. */
    uint32_t spp_first = 0, spp_end = 0;
    /** Where converted textures are cached (empty: $SPANGLE_TEXTURE_CACHE or the user's cache
     *  directory) and how much memory the texture tile cache may hold. */
    std::string texture_cache;
    uint32_t texture_memory_mb = 1024;
};

/** The samples per pixel reached after each pass of a progressive render of `spp` samples:
 *  1, 2, 4, 8, ... doubling, the last pass ending exactly at spp. */
std::vector<uint32_t> pass_ends(uint32_t spp);

/** Side of the pixel blocks of a preview pass for a width x height film: a power of two up to
 *  16 that leaves at least 160 blocks along the longer side (1: no preview pass). */
uint32_t preview_stride(uint32_t width, uint32_t height);

/** Refuses (SpangleError naming the settings to lower) a film whose memory while rendering --
 *  the image and the copies passes need -- would not fit the memory available now. */
void check_film_memory(uint32_t width, uint32_t height, uint32_t spp, const RenderOptions& options,
                       uint32_t layer_channels = 0);

/** The render layers' channel names in film order (A, albedo.R/G/B, N.X/Y/Z, Z, P.X/Y/Z,
 *  glints.R/G/B, then lightgroup_<name>.R/G/B per light group). */
std::vector<std::string> layer_channel_names(const std::vector<std::string>& light_groups);

/** Counters of one render. */
struct RenderStats {
    uint64_t camera_rays = 0;  ///< primary rays
    uint64_t bounce_rays = 0;  ///< continuation rays after scattering
    uint64_t shadow_rays = 0;  ///< next-event visibility rays
    uint64_t samples = 0;      ///< camera samples (pixels x spp)
    uint64_t nonfinite = 0;    ///< contributions replaced by black
    uint32_t first_bad_pixel_x = 0, first_bad_pixel_y = 0, first_bad_sample = 0;
    double seconds = 0.0;      ///< wall time of the render system
    uint32_t spp_reached = 0;  ///< samples per pixel of the passes completed
    uint32_t spp_target = 0;   ///< samples per pixel asked for
    uint32_t spp_frame = 0;    ///< the frame's samples per pixel (spp_target unless --spp-range)
    uint32_t passes = 0;       ///< passes completed
};

#define SPANGLE_EMITTER_REF_FIELDS(X) X(int32_t, first, "first light-table entry of its triangles")
/** Written by the area_lights system on emissive objects. */
SPANGLE_COMPONENT(EmitterRef, SPANGLE_EMITTER_REF_FIELDS);

/** What the subdivide system did to one surface, for --stats. */
struct SubdivReport {
    std::string cage;          ///< cage file
    int level = 0;             ///< refinement level used
    bool from_camera = false;  ///< level chosen from the camera
    std::size_t cage_faces = 0, triangles = 0;
    double seconds = 0.0;  ///< load + refine + limit
};

/** What a watch session keeps between reloads, each entry keyed by everything that produced it
 *  (file identities, parameters). Systems look here before building and record what they built
 *  and reused; a one-shot render has no cache. Entries no load used are evicted after each
 *  successful load, so memory follows the scene, not the number of reloads. */
struct BuildCache {
    std::map<std::string, std::shared_ptr<const TriangleMesh>> meshes;
    std::map<std::string, std::shared_ptr<const Cage>> cages;
    std::map<std::string, std::shared_ptr<MaterialInstance>> materials;
    std::map<std::string, std::shared_ptr<const EnvironmentMap>> environments;
    std::set<std::string> used;         ///< keys the load in progress used
    std::set<std::string> last_used;    ///< keys the live scene uses (the last successful load)
    std::vector<std::string> built;     ///< what the load in progress built
    std::map<std::string, int> reused;  ///< kind -> count reused by the load in progress

    /** Looks `key` up in `map`; on a hit counts it as reused under `kind`. */
    template <class T>
    std::shared_ptr<T> find(std::map<std::string, std::shared_ptr<T>>& map, const std::string& key,
                            const char* kind) {
        used.insert(key);
        auto it = map.find(key);
        if (it == map.end()) return nullptr;
        ++reused[kind];
        return it->second;
    }
    void begin() {
        used.clear();
        built.clear();
        reused.clear();
    }
    /** A skipped system keeps what it built last time: its keys (by prefix) stay in use. */
    void keep(const std::string& prefix) {
        for (const auto& k : last_used)
            if (k.compare(0, prefix.size(), prefix) == 0) used.insert(k);
    }
    /** Drops every entry the load just committed does not use. */
    void evict() {
        last_used = used;
        auto prune = [&](auto& map) {
            for (auto it = map.begin(); it != map.end();)
                it = used.count(it->first) ? std::next(it) : map.erase(it);
        };
        prune(meshes);
        prune(cages);
        prune(materials);
        prune(environments);
    }
};

/** The entry of `map` for key(), or make()'s result, stored there and recorded as `what` built
 *  (when not empty). Without a cache it only calls make(), and key() is never computed. Reuses
 *  are counted under `kind`. */
template <class T, class Key, class Make>
std::shared_ptr<T> build_cached(BuildCache* cache,
                                std::map<std::string, std::shared_ptr<T>> BuildCache::*map,
                                const char* kind, Key&& key, Make&& make, const std::string& what) {
    if (!cache) return std::shared_ptr<T>(make());
    const std::string k = key();
    if (auto hit = cache->find(cache->*map, k, kind)) return hit;
    std::shared_ptr<T> built(make());
    (cache->*map)[k] = built;
    if (!what.empty()) cache->built.push_back(what);
    return built;
}

/** Shared state of one frame. */
struct World {
    ColorConfig* color = nullptr;        ///< borrowed
    const Logger* log = nullptr;         ///< borrowed
    PluginLoader* plugins = nullptr;     ///< borrowed
    const HostServices* host = nullptr;  ///< borrowed
    const SceneInfo* info = nullptr;     ///< borrowed
    RenderOptions options;
    BuildCache* cache = nullptr;  ///< borrowed from a watch session; null for one frame

    std::vector<SubdivReport> subdiv;  ///< subdivide
    GeometryStore geometry;            ///< mesh_load, subdivide
    uint32_t mesh_file_count = 0;      ///< meshes of mesh_load (subdivide's follow them)
    std::vector<std::shared_ptr<MaterialInstance>> materials;  ///< materials; null = unused
    LightTable lights;                                         ///< area_lights
    std::vector<Vec3> quad_vertices;                           ///< area_lights: 4 corners per quad
    std::vector<float> sphere_lights;    ///< area_lights: x, y, z, radius per sphere
    uint32_t quad_light_first = 0;       ///< light-table index of the first quad
    Vec3 environment;                    ///< environment
    uint32_t environment_group = 0;      ///< environment: its light group
    std::vector<Instance> instances;     ///< accelerate
    std::shared_ptr<EmbreeScene> accel;  ///< accelerate (kept across reloads: BLAS are reused)

    uint32_t width = 0, height = 0;  ///< render: the image's size (the crop window's)
    ImageWindow window;              ///< render: where the image lies in the full frame
    std::vector<float> image;        ///< render: RGB, working space, row-major
    /** render: the film's exact sums behind `image` (RGB per pixel; core/sample_sum.h). */
    std::vector<SampleSum> sums;
    /** render, with options.layers: layer_names.size() values per pixel, row-major. */
    std::vector<float> layers;
    std::vector<std::string> layer_names;
    RenderStats stats;  ///< render
};

}  // namespace spangle
