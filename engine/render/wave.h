#pragma once
// The path tracer in stages. A wave is every sample [first, first + count) of every pixel of a
// tile, traced together so that each material's plugin is called once per batch of shading
// points. trace_wave (render/wave.cpp) runs the stages bounce by bounce:
//
//   start_paths    camera rays                                    render/stage_camera.cpp
//   intersect      trace, light picked up by misses and emitters,
//                  surfaces reconstructed and sorted by material   render/stage_intersect.cpp
//   shade          plugin batches (textures, normal and bump maps,
//                  prepare) and next-event estimation              render/stage_shade.cpp
//   scatter        BSDF sampling, Russian roulette, differentials  render/stage_scatter.cpp
//   accumulate     the paths' radiance into the film               render/wave.cpp
//
// The film and pass driver (tiles, passes, rollback, the preview pass, statistics) is
// render/integrator.cpp. Every stage is a template over the render layers' sink
// (render/layers/layer_sink.h): NullSink without layers, LayerSink with them.

#include <atomic>
#include <cmath>
#include <cstring>
#include <mutex>
#include <vector>

#include "core/sample_sum.h"
#include "render/adaptive.h"
#include "render/arena.h"
#include "render/layers/layer_sink.h"
#include "render/path_state.h"
#include "render/render_scene.h"
#include "render/sampler.h"
#include "scene/components.h"
#include "shading/texture.h"

namespace spangle {

constexpr uint32_t kTileSize = 16;
constexpr uint32_t kSamplesPerWave = 8;  ///< samples of each tile pixel traced together
constexpr uint32_t kMaxBatch = 256;  ///< shading points per plugin call: bounds per-batch scratch

/** Sobol dimension sets: two pairs for the camera, then kPairsPerBounce sets per bounce. A set is
 *  a pair (rnd2) or a triple (rnd3) of jointly stratified numbers. */
enum Pair : uint32_t {
    kPairFilter = 0,
    kPairLens = 1,
    kPairBounceBase = 2,
    kPairLight = 0,     ///< triple: light position (u1, u2), then the light's selection
    kPairBsdf = 1,      ///< triple: BSDF direction (u0, u1), then its lobe choice (u2)
    kPairSpare = 2,     ///< unused (it held the selections, drawn apart from what they select)
    kPairRoulette = 3,  ///< Russian roulette, spare
    kPairsPerBounce = 4,
    /** The path's time within the shutter (motion blur; first value). Far beyond the bounce
     *  pairs, so a scene without motion draws exactly the numbers it drew before. */
    kPairTime = 0x40000000u
};

/** State shared by all tiles of one render. */
struct RenderJob {
    const RenderScene* scene;
    Strategy strategy;
    float clamp_indirect;  ///< 0 = off
    /** Path regularisation ([render] filter_glossy; 0 = off): after a bounce of pdf p, later
     *  glossy lobes are kept at least as rough as alpha = 0.5 sqrt(1 - p / filter_glossy). */
    float filter_glossy = 0.0f;
    const CameraModel* camera;
    /** A camera moving while the shutter is open: its fields at evenly spaced times (empty:
     *  `camera` at every time). */
    const std::vector<Camera>* camera_steps = nullptr;
    /** Something moves while the shutter is open: every path draws a time. */
    bool motion = false;
    /** Some material reads footprints (MaterialInstance::reads_footprints): hits get them.
     *  Otherwise no footprint is computed and the shading points' footprint fields are 0. */
    bool footprints = true;
    const FilterSampler* filter;
    uint32_t width, height, spp, max_depth, rr_depth;
    /** The crop window: film pixel (x, y) of the full frame is image pixel
     *  (x - crop_x0, y - crop_y0) of a crop_width-wide image. */
    uint32_t crop_x0 = 0, crop_y0 = 0, crop_width = 0;
    uint64_t seed;
    /** Pixels traced per stride x stride block (1: every pixel; >1: a preview pass, one path per
     *  block with its footprint widened to the block). */
    uint32_t stride = 1;
    /** The film: exact fixed-point sums, RGB per pixel (core/sample_sum.h); a preview pass
     *  adds floats into `image` instead (sums null). */
    std::vector<SampleSum>* sums = nullptr;
    std::vector<float>* image = nullptr;
    bool layers = false;  ///< the render layers are on (and `layer_film` says where)
    LayerFilm layer_film;
    LayerPlan layer_plan;  ///< the layers written
    /** Camera rays see the environment (false: [render] transparent_background). */
    bool camera_sees_environment = true;
    /** The environment camera rays see goes to the `background` layer, not the beauty. */
    bool background_apart = false;
    /** Adaptive sampling (render/adaptive.h): the plan, and the pixels' counts, half-sums and
     *  activity; null when every pixel takes every sample. */
    const AdaptivePlan* adaptive = nullptr;
    AdaptiveFilm* adaptive_film = nullptr;
    std::atomic<uint64_t> camera_rays{0}, bounce_rays{0}, shadow_rays{0}, samples_done{0};
    std::atomic<uint64_t> nonfinite{0};
    std::atomic<uint64_t> first_bad{~0ull};  ///< (pixel << 24 | sample) of the first bad value
    std::mutex progress_mutex;
};

/** The pixels of a tile a wave traces: [x0, x1) x [y0, y1) of the full frame. */
struct Tile {
    uint32_t x0, y0, x1, y1;
};

/** Per-thread buffers for one wave of paths; reused across tiles and waves. */
struct Workspace {
    PathBatch paths;
    /** A path that hit a scattering surface, and the hit (in path order). */
    struct PathHit {
        uint32_t path;
        Hit hit;
    };
    std::vector<PathHit> hits;
    // Rays traced as one stream: the paths they belong to, origins, directions, times, and
    // what they found (closest hits, or occluded for shadow rays).
    std::vector<uint32_t> stream_path;
    std::vector<Vec3> stream_o, stream_d;
    std::vector<float> stream_time;
    std::vector<Hit> stream_hit;
    std::vector<uint8_t> stream_found;
    std::vector<Vec3> shadow_contrib;  ///< next-event contributions if unoccluded
    std::vector<float> shadow_tmax;
    std::vector<uint32_t> order;        ///< active hit paths sorted by material
    std::vector<uint32_t> group_start;  ///< where each material's paths start in `order`
    ShadingBatch batch;                 ///< one material batch's shading points
    std::vector<std::byte> closures;    ///< storage of the plugin's closures
    void* closure_data = nullptr;       ///< the batch's closures (aligned, in `closures`)
    ScratchArena arena;                 ///< the plugin's scratch memory
    // Textures of one material group: lookups, values per bound parameter, the map's values.
    TextureQuery tex_query;
    std::vector<std::vector<float>> tex_values;
    std::vector<const float*> param_values;  ///< one per schema entry (null: constant)
    std::vector<float> map_value, map_ds, map_dt;
    std::vector<float> gu, gv, gdudx, gdudy, gdvdx, gdvdy;  ///< the group's uvs, for the map
    LayerSink layers;                                       ///< used when the job has layers
};

/** Sobol pair `pair` of path `path` at `bounce`. */
inline void rnd2(const PathBatch& p, uint32_t path, uint32_t bounce, uint32_t pair, float& a,
                 float& b) {
    sobol_2d_keyed(p.key[path], p.sample[path], kPairBounceBase + bounce * kPairsPerBounce + pair,
                   a, b);
}

/** Sobol triple `set` of path `path` at `bounce`: a choice made with c leaves the samples that
 *  make the same choice stratified in (a, b). */
inline void rnd3(const PathBatch& p, uint32_t path, uint32_t bounce, uint32_t set, float& a,
                 float& b, float& c) {
    sobol_3d_keyed(p.key[path], p.sample[path], kPairBounceBase + bounce * kPairsPerBounce + set, a,
                   b, c);
}

/** The factor that caps the luminance of one indirect contribution c (a biased, optional
 *  firefly guard: light that reached the camera through `scatterings` >= 2 surface events);
 *  1 when it is under the cap. The render layers' parts of c are scaled by the same factor, so
 *  that they still add up to it. */
inline float clamp_factor(const RenderJob& job, Vec3 c, uint32_t scatterings) {
    if (job.clamp_indirect <= 0.0f || scatterings < 2) return 1.0f;
    const float lum = luminance(c);
    return lum > job.clamp_indirect ? job.clamp_indirect / lum : 1.0f;
}

/** The scene's scale for offset_origin (EmbreeScene::offset_scale; 1 without geometry). */
inline float offset_scale(const RenderJob& job) {
    return job.scene->accel ? job.scene->accel->offset_scale() : 1.0f;
}

/** Offsets a ray origin off a surface along the geometric normal by a few float ulps, scaled to
 *  the coordinates' magnitude (Waechter and Binder, "A Fast and Robust Method for Avoiding
 *  Self-Intersection", Ray Tracing Gems, 2019). n must face the side the ray leaves towards.
 *  Near the origin the offset is absolute, 1/65536 times `scale` (EmbreeScene::offset_scale():
 *  the scene's coordinate magnitude, at most 1), so that it stays small against small scenes. */
inline Vec3 offset_origin(Vec3 p, Vec3 n, float scale = 1.0f) {
    constexpr float kOrigin = 1.0f / 32.0f, kFloatScale = 1.0f / 65536.0f, kIntScale = 256.0f;
    float out[3];
    const float pc[3] = {p.x, p.y, p.z}, nc[3] = {n.x, n.y, n.z};
    for (int i = 0; i < 3; ++i) {
        const auto of = static_cast<int32_t>(kIntScale * nc[i]);
        int32_t bits;
        std::memcpy(&bits, &pc[i], sizeof(bits));
        bits += pc[i] < 0.0f ? -of : of;
        float moved;
        std::memcpy(&moved, &bits, sizeof(moved));
        out[i] = std::fabs(pc[i]) < kOrigin ? pc[i] + kFloatScale * scale * nc[i] : moved;
    }
    return {out[0], out[1], out[2]};
}

/** Camera rays: `count` samples from `first_sample` of every pixel of the tile (one path per
 *  block of job.stride pixels in a preview pass). Returns the number of paths. */
std::size_t start_paths(const RenderJob& job, Workspace& ws, const Tile& tile,
                        uint32_t first_sample, uint32_t count);

/** Traces every active path's ray; misses and emitters add their light; paths that hit a
 *  surface they go on from get it reconstructed, and are sorted by material into ws.order
 *  (ws.group_start). `rays` counts the rays traced. */
template <class Sink>
void intersect(RenderJob& job, Workspace& ws, Sink& sink, std::size_t n, uint32_t bounce,
               uint64_t& rays);

/** Shades one batch of one material: the plugin batch (with textures and the normal or bump
 *  map), prepare, then next-event estimation towards the lights. `shadow_rays` counts them. */
template <class Sink>
void shade(const RenderJob& job, Workspace& ws, Sink& sink, const MaterialInstance& mat,
           const uint32_t* paths, uint32_t n, uint32_t bounce, uint64_t& shadow_rays);

/** Continues the batch shade() prepared by sampling its BSDF: throughputs, Russian roulette,
 *  ray differentials through specular bounces, the next rays. */
template <class Sink>
void scatter(const RenderJob& job, Workspace& ws, Sink& sink, const MaterialInstance& mat,
             const uint32_t* paths, uint32_t n, uint32_t bounce);

/** Traces one wave: `count` samples from `first_sample` of every pixel of the tile, through
 *  every stage, into the job's film. */
template <class Sink>
void trace_wave(RenderJob& job, Workspace& ws, Sink& sink, const Tile& tile, uint32_t first_sample,
                uint32_t count);

}  // namespace spangle
