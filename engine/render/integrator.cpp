// The film and pass driver that any integrator's stages share: the job's set-up from the camera
// and film, tiles in parallel (oneTBB) wave by wave, a preview pass, passes of doubling sample
// counts with rollback on a stop request, the image as the mean of the film's exact sums, the
// render layers finished, and the statistics.

#include "render/integrator.h"

#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <numeric>

#include "core/cryptomatte.h"
#include "core/memory.h"
#include "core/pixel_filter.h"
#include "render/adaptive.h"
#include "render/wave.h"

namespace spangle {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/** The pixels of `to` (inside `from`) of a row-major image of `from`, `n` values per pixel. */
template <class T>
std::vector<T> cropped(const std::vector<T>& v, const CropWindow& from, const CropWindow& to,
                       std::size_t n) {
    const std::size_t fw = from.x1 - from.x0, tw = to.x1 - to.x0;
    std::vector<T> out(tw * (to.y1 - to.y0) * n);
    for (uint32_t y = to.y0; y < to.y1; ++y)
        std::copy_n(
            v.begin() + static_cast<std::ptrdiff_t>(((y - from.y0) * fw + (to.x0 - from.x0)) * n),
            tw * n, out.begin() + static_cast<std::ptrdiff_t>((y - to.y0) * tw * n));
    return out;
}

/** filter_samples = "shared": how the film's pixel means become the image. The render covers
 *  `win`, the window asked for grown by the filter's reach (clipped to the frame), so that every
 *  pixel of `asked` has all its neighbours in the frame. */
struct Spread {
    std::vector<double> weights;  ///< spread_weights(); empty: filter_samples = "own"
    CropWindow win, asked;
    bool on() const { return weights.size() > 1; }
    /** Spreads `values` (n channels per pixel of win; those of `spread` true) over `asked`. */
    void apply(std::vector<float>& values, std::size_t n, const std::vector<bool>& spread) const {
        if (!on() || values.empty()) return;
        spread_pixels(values.data(), n, spread, PixelRect{win.x0, win.y0, win.x1, win.y1},
                      PixelRect{asked.x0, asked.y0, asked.x1, asked.y1}, weights);
    }
};

/** Which of the layers are spread by a shared filter: the colours, not the data (depth,
 *  normals, positions, object numbers, Cryptomatte). */
std::vector<bool> spread_layers(const std::vector<std::string>& names) {
    std::vector<bool> out(names.size());
    for (std::size_t c = 0; c < names.size(); ++c) out[c] = !layer_channel_is_data(names[c]);
    return out;
}

/** One render's tiles and the threads that trace them. */
struct TileRun {
    RenderJob& job;
    const RenderOptions& options;
    CropWindow win;  ///< the pixels rendered
    uint32_t tile_x0 = 0, tile_y0 = 0, tiles_x = 0, tiles_y = 0;
    uint64_t total = 0;  ///< camera samples of the whole render, for progress
    tbb::enumerable_thread_specific<Workspace> workspaces;
    tbb::task_arena arena;
    std::atomic<bool> stopped{false};

    TileRun(RenderJob& j, const RenderOptions& o, CropWindow w, uint64_t samples)
        : job(j),
          options(o),
          win(w),
          total(samples),
          // At most the threads TBB runs at once: more were refused by TBB anyway, with its own
          // warning printed in the middle of the progress line (--threads 1000).
          arena(o.threads > 0 ? std::min(o.threads, tbb::this_task_arena::max_concurrency())
                              : tbb::this_task_arena::max_concurrency()) {
        // The full frame's tile grid: the tiles that meet the window, clipped to it.
        tile_x0 = win.x0 / kTileSize;
        tile_y0 = win.y0 / kTileSize;
        tiles_x = (win.x1 + kTileSize - 1) / kTileSize - tile_x0;
        tiles_y = (win.y1 + kTileSize - 1) / kTileSize - tile_y0;
    }

    /** Tile `t` of the grid, clipped to the window. */
    Tile tile(uint32_t t) const {
        const uint32_t tx = (tile_x0 + t % tiles_x) * kTileSize,
                       ty = (tile_y0 + t / tiles_x) * kTileSize;
        return Tile{std::max(tx, win.x0), std::max(ty, win.y0), std::min(tx + kTileSize, win.x1),
                    std::min(ty + kTileSize, win.y1)};
    }

    /** The image index of full-frame pixel (x, y). */
    std::size_t image_index(uint32_t x, uint32_t y) const {
        return static_cast<std::size_t>(y - win.y0) * (win.x1 - win.x0) + (x - win.x0);
    }

    /** Pixels of tile `t` still taking samples (all of them without adaptive sampling). */
    uint64_t active_pixels(const Tile& t) const {
        if (!job.adaptive_film) return static_cast<uint64_t>(t.x1 - t.x0) * (t.y1 - t.y0);
        uint64_t n = 0;
        for (uint32_t y = t.y0; y < t.y1; ++y)
            for (uint32_t x = t.x0; x < t.x1; ++x)
                n += job.adaptive_film->active[image_index(x, y)];
        return n;
    }

    /** Adaptive sampling's checkpoint at `samples`: each active pixel of the tile measures its
     *  error; a pixel is within the threshold when every pixel of its 3 x 3 neighbourhood inside
     *  the tile is (a stopped one by the error it stopped at), and one within it at two
     *  checkpoints in a row stops (the samples it leaves untaken count as done for the
     *  progress). The tile is the full frame's, whole (the window is tile-aligned), so the
     *  decision is the same in every split of the work. Returns the samples skipped. */
    uint64_t check_tile(const Tile& t, uint32_t samples) {
        AdaptiveFilm& a = *job.adaptive_film;
        const uint32_t lc = job.layer_film.channels;
        for (uint32_t y = t.y0; y < t.y1; ++y)
            for (uint32_t x = t.x0; x < t.x1; ++x) {
                const std::size_t i = image_index(x, y);
                if (!a.active[i]) continue;
                const PixelSums sums{
                    &(*job.sums)[3 * i],
                    job.layers ? &(*job.layer_film.film)[i * lc + kAovCount] : nullptr,
                    &a.parts[AdaptiveFilm::kParts * i], a.count[i],
                    job.layers && job.background_apart
                        ? &(*job.layer_film.film)[i * lc + job.layer_film.layout.background]
                        : nullptr};
                a.ratio[i] = adaptive_error(*job.adaptive, sums);
            }
        uint64_t skipped = 0;
        for (uint32_t y = t.y0; y < t.y1; ++y)
            for (uint32_t x = t.x0; x < t.x1; ++x) {
                const std::size_t i = image_index(x, y);
                if (!a.active[i]) continue;
                float worst = 0.0f;
                for (uint32_t ny = std::max(y, t.y0 + 1) - 1; ny <= std::min(y + 1, t.y1 - 1); ++ny)
                    for (uint32_t nx = std::max(x, t.x0 + 1) - 1; nx <= std::min(x + 1, t.x1 - 1);
                         ++nx)
                        worst = std::max(worst, a.ratio[image_index(nx, ny)]);
                if (worst > 1.0f) {
                    a.strikes[i] = 0;
                } else if (++a.strikes[i] >= 2 && samples >= job.adaptive->min_spp) {
                    a.active[i] = 0;
                    skipped += job.spp - samples;
                }
            }
        return skipped;
    }

    /** Samples [first, end) of one tile, wave by wave, until a stop request. With adaptive
     *  sampling a wave ends at each checkpoint, where the tile's pixels are judged. */
    void run_tile(Workspace& ws, const Tile& t, uint32_t first, uint32_t end, bool count_progress) {
        uint64_t active = active_pixels(t);
        for (uint32_t s = first; s < end && active > 0;) {
            if (stopped.load(std::memory_order_relaxed)) return;
            if (options.stop && options.stop()) {
                stopped = true;
                return;
            }
            uint32_t count = std::min(kSamplesPerWave, end - s);
            const uint32_t checkpoint = job.adaptive ? next_checkpoint(*job.adaptive, s) : 0;
            if (job.adaptive) count = std::min(count, checkpoint - s);
            if (job.layers)
                trace_wave(job, ws, ws.layers, t, s, count);
            else {
                NullSink none;
                trace_wave(job, ws, none, t, s, count);
            }
            s += count;
            uint64_t samples = active * count;
            if (count_progress && options.traced)
                options.traced->fetch_add(samples, std::memory_order_relaxed);
            if (job.adaptive && s == checkpoint) {
                samples += check_tile(t, s);
                active = active_pixels(t);
            }
            if (!count_progress) continue;
            job.samples_done += samples;
            if (options.progress) {
                // The count as it is under the lock, so that reports never go backwards (the
                // count taken before it let a thread report 256 after another's 512).
                std::lock_guard<std::mutex> lock(job.progress_mutex);
                options.progress(job.samples_done.load(), total);
            }
        }
    }

    /** Samples [first, end) of every tile, in parallel. */
    void run(uint32_t first, uint32_t end, bool count_progress) {
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<uint32_t>(0, tiles_x * tiles_y, 1),
                              [&](const tbb::blocked_range<uint32_t>& r) {
                                  Workspace& ws = workspaces.local();
                                  for (uint32_t t = r.begin(); t != r.end(); ++t)
                                      run_tile(ws, tile(t), first, end, count_progress);
                              });
        });
    }
};

/** Sets the job up from the camera, film and options; returns the first sample to render
 *  (--spp-range: samples [first, job.spp) of the frame's). */
uint32_t set_up_job(RenderJob& job, const RenderScene& scene, const RenderOptions& options,
                    const CameraModel& cam, const Film& film,
                    const std::vector<Camera>& camera_steps) {
    job.scene = &scene;
    job.strategy = options.strategy;
    job.clamp_indirect = film.clamp_indirect;
    job.filter_glossy = film.filter_glossy;
    job.camera = &cam;
    if (camera_steps.size() >= 2) job.camera_steps = &camera_steps;
    job.motion = job.camera_steps != nullptr ||
                 std::any_of(scene.instances->begin(), scene.instances->end(),
                             [](const Instance& i) { return !i.motion.empty(); });
    job.footprints = options.footprints_always || !scene.materials ||
                     std::any_of(scene.materials->begin(), scene.materials->end(),
                                 [](const std::shared_ptr<MaterialInstance>& m) {
                                     return m && m->reads_footprints();
                                 });
    job.width = film.width;
    job.height = film.height;
    job.spp = options.spp_override ? options.spp_override : film.spp;
    job.max_depth = film.max_depth;
    job.rr_depth = film.rr_depth;
    job.seed = film.seed;
    job.camera_sees_environment = film.transparent_background == 0;
    if (job.adaptive) job.spp = job.adaptive->max_spp;
    if (options.spp_end == 0) return 0;
    if (job.adaptive) throw_error("{}", spp_range_refusal("an adaptive render (noise_threshold)"));
    if (!(options.spp_first < options.spp_end && options.spp_end <= job.spp))
        throw_error(
            "sample range {}..{} is not inside the frame's {} samples per pixel (it needs A < B "
            "<= spp)",
            options.spp_first, options.spp_end, job.spp);
    job.spp = options.spp_end;
    return options.spp_first;
}

}  // namespace

LayerPlan layer_plan(const RenderOptions& options, const std::vector<std::string>* light_groups,
                     const std::vector<std::string>* object_names,
                     const std::vector<std::string>* material_names, bool catcher) {
    LayerPlan plan;
    if (light_groups) plan.groups = *light_groups;
    if (plan.groups.empty()) plan.groups.push_back("default");
    plan.background = options.background_apart && options.layers;
    plan.catcher = catcher;
    if (object_names) plan.object_names = *object_names;
    if (material_names) plan.material_names = *material_names;
    return plan;
}

namespace {

/** Where the layers go (with options.layers): their names, and the job's layer film. */
void set_up_layers(RenderJob& job, const RenderScene& scene, const RenderOptions& options,
                   const Camera& camera, RenderResult& out) {
    const bool catcher = std::any_of(scene.instances->begin(), scene.instances->end(),
                                     [](const Instance& i) { return i.shadow_catcher != 0; });
    job.layer_plan =
        layer_plan(options, scene.light_groups, scene.object_names, scene.material_names, catcher);
    out.layer_names = layer_channel_names(job.layer_plan);
    job.layers = true;
    LayerFilm& f = job.layer_film;
    f.film = &out.layers;
    f.groups = static_cast<uint32_t>(job.layer_plan.groups.size());
    f.layout = layer_layout(f.groups);
    f.channels = f.layout.channels;
    f.camera_position = camera.position;
    f.camera_forward = normalize(camera.look_at - camera.position);
    // A panorama looks every way: its depth is the distance (along the view it ran from -d to d).
    f.radial_depth = camera.equirect;
    f.object_ids.clear();
    for (const std::string& n : job.layer_plan.object_names)
        f.object_ids.push_back(cryptomatte_id(n));
    f.material_ids.clear();
    for (const std::string& n : job.layer_plan.material_names)
        f.material_ids.push_back(cryptomatte_id(n));
    job.background_apart = options.background_apart && options.layers;
}

/** A preview pass: one path per block of pixels, shown before the first full pass. It is not
 *  part of the image: its values are thrown away once shown. */
void preview_pass(TileRun& run, const Film& film, uint32_t stride, uint32_t first_sample,
                  const RenderResult& out, std::chrono::steady_clock::time_point t0) {
    RenderJob& job = run.job;
    std::vector<float> preview(out.sums.size(), 0.0f);
    std::vector<SampleSum>* sums = job.sums;
    job.sums = nullptr;
    job.image = &preview;
    job.stride = stride;
    const bool layers = job.layers;
    job.layers = false;  // the preview pass shows the beauty only
    run.run(first_sample, first_sample + 1, false);
    job.layers = layers;
    job.sums = sums;
    job.image = nullptr;
    job.stride = 1;
    if (run.stopped) return;
    // Every pixel takes the value of its block's traced pixel.
    for (uint32_t y = 0; y < film.height; ++y) {
        const uint32_t sy = std::min((y / stride) * stride + stride / 2, film.height - 1);
        for (uint32_t x = 0; x < film.width; ++x) {
            const uint32_t sx = std::min((x / stride) * stride + stride / 2, film.width - 1);
            const std::size_t to = 3 * (static_cast<std::size_t>(y) * film.width + x);
            const std::size_t from = 3 * (static_cast<std::size_t>(sy) * film.width + sx);
            if (to != from)
                for (std::size_t c = 0; c < 3; ++c) preview[to + c] = preview[from + c];
        }
    }
    run.options.on_pass(PassImage{preview, film.width, film.height, 0, job.spp - first_sample,
                                  stride, seconds_since(t0), out.window});
}

/** Passes of doubling sample counts up to job.spp. Every pixel adds its samples in sample
 *  order whatever the passes, so the sums after the last pass are those of a one-pass render,
 *  bit for bit. A pass interrupted by a stop request is rolled back to the sums before it.
 *  Returns the samples reached; `passes` counts the passes completed. */
uint32_t full_passes(TileRun& run, uint32_t first_sample, const Spread& spread, RenderResult& out,
                     uint32_t& passes, std::chrono::steady_clock::time_point t0) {
    RenderJob& job = run.job;
    const RenderOptions& options = run.options;
    std::vector<uint32_t> ends = options.progressive
                                     ? pass_ends(job.spp - first_sample)
                                     : std::vector<uint32_t>{job.spp - first_sample};
    for (uint32_t& e : ends) e += first_sample;
    std::vector<SampleSum> before;
    std::vector<float> layers_before;
    AdaptiveFilm adaptive_before;
    uint32_t reached = first_sample;
    for (const uint32_t end : ends) {
        // The first pass starts from black: rolling it back needs no copy.
        if (options.stop && reached > first_sample) {
            before = out.sums;
            layers_before = out.layers;
            if (job.adaptive_film) adaptive_before = *job.adaptive_film;
        }
        if (!run.stopped) run.run(reached, end, true);
        if (run.stopped) {
            if (reached > first_sample) {
                out.sums.swap(before);
                out.layers.swap(layers_before);
                if (job.adaptive_film) std::swap(*job.adaptive_film, adaptive_before);
            } else {
                std::fill(out.sums.begin(), out.sums.end(), SampleSum(0));
                std::fill(out.layers.begin(), out.layers.end(), 0.0f);
                if (job.adaptive_film) job.adaptive_film->reset(out.sums.size() / 3);
            }
            break;
        }
        reached = end;
        ++passes;
        if (options.on_pass && end < job.spp) {
            std::vector<float> shown(out.sums.size());
            for (std::size_t i = 0; i < shown.size(); ++i)
                shown[i] =
                    sample_mean(out.sums[i], job.adaptive_film ? job.adaptive_film->count[i / 3]
                                                               : end - first_sample);
            // The layers so far, finished as at the end (a pass's EXR had the beauty alone:
            // with --layers premultiplied, its sky black and no alpha or background to restore).
            // (Only those asked for: adaptive sampling keeps a glints layer of its own.)
            const bool with_layers = job.layers && options.layers;
            std::vector<float> layers;
            if (with_layers) {
                layers = out.layers;
                finish_layers(layers, job.layer_film.layout, job.layer_plan, end - first_sample,
                              job.adaptive_film ? job.adaptive_film->count.data() : nullptr);
            }
            // Spread as the final image is; cut to the window asked for as it is (an adaptive
            // render's passes show its whole tiles).
            spread.apply(shown, 3, std::vector<bool>(3, true));
            if (with_layers)
                spread.apply(layers, out.layer_names.size(), spread_layers(out.layer_names));
            uint32_t w = out.width, h = out.height;
            ImageWindow window = out.window;
            if (spread.on() && !job.adaptive_film && spread.win != spread.asked) {
                shown = cropped(shown, spread.win, spread.asked, 3);
                if (with_layers)
                    layers = cropped(layers, spread.win, spread.asked, out.layer_names.size());
                w = spread.asked.x1 - spread.asked.x0;
                h = spread.asked.y1 - spread.asked.y0;
                window.x0 = spread.asked.x0;
                window.y0 = spread.asked.y0;
            }
            options.on_pass(PassImage{shown, w, h, end - first_sample, job.spp - first_sample, 1,
                                      seconds_since(t0), window, with_layers ? &layers : nullptr,
                                      with_layers ? &out.layer_names : nullptr});
        }
    }
    return reached;
}

/** `win` grown to the whole tiles of the full frame's grid that it meets (within the image). */
CropWindow whole_tiles(const CropWindow& win, uint32_t width, uint32_t height) {
    return CropWindow{win.x0 / kTileSize * kTileSize, win.y0 / kTileSize * kTileSize,
                      std::min(width, (win.x1 + kTileSize - 1) / kTileSize * kTileSize),
                      std::min(height, (win.y1 + kTileSize - 1) / kTileSize * kTileSize)};
}

/** Cuts a render of `from` down to the window asked for, `to` (the same when equal). */
void crop_result(const CropWindow& from, const CropWindow& to, std::vector<uint32_t>& counts,
                 RenderResult& out) {
    if (from == to) return;
    out.image = cropped(out.image, from, to, 3);
    out.sums = cropped(out.sums, from, to, 3);
    out.layers = cropped(out.layers, from, to, out.layer_names.size());
    if (!counts.empty()) counts = cropped(counts, from, to, 1);
    out.width = to.x1 - to.x0;
    out.height = to.y1 - to.y0;
    out.window.x0 = to.x0;
    out.window.y0 = to.y0;
}

/** Adaptive sampling's outputs: the samples each pixel took as the layer `spp` (after the
 *  other layers, or alone when they were not asked for: the glints layer was only the
 *  estimate's), and their range in the counters. */
void add_spp_layer(const std::vector<uint32_t>& counts, bool keep_layers, RenderResult& out) {
    const std::size_t pixels = counts.size();
    const std::size_t lc = keep_layers ? out.layer_names.size() : 0;
    std::vector<float> layers(pixels * (lc + 1));
    uint32_t lo = ~0u, hi = 0;
    double sum = 0.0;
    for (std::size_t p = 0; p < pixels; ++p) {
        std::copy_n(out.layers.begin() + static_cast<std::ptrdiff_t>(p * lc), lc,
                    layers.begin() + static_cast<std::ptrdiff_t>(p * (lc + 1)));
        layers[p * (lc + 1) + lc] = static_cast<float>(counts[p]);
        lo = std::min(lo, counts[p]);
        hi = std::max(hi, counts[p]);
        sum += counts[p];
    }
    out.stats.pixel_spp_mean = pixels ? sum / static_cast<double>(pixels) : 0.0;
    out.layers.swap(layers);
    if (!keep_layers) out.layer_names.clear();
    out.layer_names.emplace_back("spp");
    out.stats.pixel_spp_min = pixels ? lo : 0;
    out.stats.pixel_spp_max = hi;
}

/** The render's counters. */
void record_stats(const RenderJob& job, const RenderOptions& options, const Film& film,
                  uint32_t samples, uint32_t first_sample, uint32_t passes, RenderResult& out) {
    RenderStats& st = out.stats;
    st.camera_rays = job.camera_rays;
    st.bounce_rays = job.bounce_rays;
    st.shadow_rays = job.shadow_rays;
    st.samples = static_cast<uint64_t>(out.width) * out.height * samples;
    st.spp_reached = samples;
    st.spp_target = job.spp - first_sample;
    st.spp_frame = options.spp_override ? options.spp_override : film.spp;
    st.passes = passes;
    st.noise_threshold = job.adaptive ? job.adaptive->threshold : 0.0f;
    st.adaptive_min_spp = job.adaptive ? job.adaptive->min_spp : 0;
    st.nonfinite = job.nonfinite;
    if (st.nonfinite > 0) {
        const uint64_t key = job.first_bad;
        const auto pix = static_cast<uint32_t>(key >> 24);
        st.first_bad_pixel_x = pix % film.width;
        st.first_bad_pixel_y = pix / film.width;
        st.first_bad_sample = static_cast<uint32_t>(key & 0xffffff);
    }
}

}  // namespace

CropWindow crop_within(const CropWindow& crop, uint32_t width, uint32_t height) {
    if (crop.whole()) return CropWindow{0, 0, width, height};
    if (!(crop.x0 < crop.x1 && crop.x1 <= width && crop.y0 < crop.y1 && crop.y1 <= height))
        throw_error(
            "crop window {},{},{},{} is not inside the {}x{} image (it needs x0 < x1 <= width "
            "and y0 < y1 <= height)",
            crop.x0, crop.y0, crop.x1, crop.y1, width, height);
    return crop;
}

std::vector<uint32_t> pass_ends(uint32_t spp) {
    std::vector<uint32_t> out;
    for (uint64_t end = 1; end < spp; end *= 2) out.push_back(static_cast<uint32_t>(end));
    out.push_back(spp);
    return out;
}

uint32_t preview_stride(uint32_t width, uint32_t height) {
    uint32_t stride = 1;
    while (stride < kTileSize && std::max(width, height) / (2 * stride) >= 160) stride *= 2;
    return stride;
}

void check_film_memory(uint32_t width, uint32_t height, uint32_t spp, const RenderOptions& options,
                       uint32_t layer_channels) {
    // Per pixel: the film (RGB fixed-point sums, 48 bytes) and the image (RGB floats); a copy
    // of the sums to roll a stopped pass back to (from the second pass on); the copy each pass
    // shows; the preview pass's image. Writing adds only strips. The render layers have a film
    // and a roll-back copy of their own.
    const bool passes = options.progressive && spp > 1;
    const double layers = 4.0 * layer_channels * (passes && options.stop ? 2.0 : 1.0);
    const double per_pixel =
        60.0 + (passes && options.stop ? 48.0 : 0.0) + (passes && options.on_pass ? 12.0 : 0.0) +
        (options.preview_pass && options.on_pass && spp > 1 ? 12.0 : 0.0) + layers;
    const double need = per_pixel * width * height;
    if (const uint64_t have = memory_short_for(need))
        throw_error(
            "a {}x{} image needs about {} to render ({} bytes per pixel), but "
            "only {} of memory is available: lower the resolution ([render] "
            "width and height, or --size){}",
            width, height, format_bytes(need), per_pixel, format_bytes(static_cast<double>(have)),
            passes && options.on_pass ? ", or turn off --pass-output" : "");
}

void render_image(const RenderScene& scene, const RenderOptions& options, const Camera& camera,
                  const Film& film, const std::vector<Camera>& camera_steps, RenderResult& out) {
    const auto t0 = std::chrono::steady_clock::now();
    const CameraModel cam = CameraModel::of(camera, film.width, film.height);
    // filter_samples = "shared": every sample lands in its own pixel (a box), and the filter
    // spreads the pixels' means afterwards. (A filter no wider than a pixel spreads nothing: its
    // own samples, as asked.)
    Spread spread;
    if (film.filter_shared != 0) spread.weights = spread_weights(film.filter, film.filter_radius);
    const FilterSampler filter(spread.on() ? FilterKind::Box : film.filter,
                               spread.on() ? 0.5f : film.filter_radius);
    RenderJob job;
    job.filter = &filter;
    const AdaptivePlan plan = adaptive_plan(film, options);
    AdaptiveFilm adaptive;
    if (plan.on()) job.adaptive = &plan;
    const uint32_t first_sample = set_up_job(job, scene, options, cam, film, camera_steps);
    // Plugin outputs the host cannot use are counted over this render (an earlier one's go).
    if (scene.materials)
        for (const auto& mat : *scene.materials)
            if (mat) mat->bad_output().take_report();
    // The crop window (the whole image without one); adaptive sampling renders the whole tiles
    // it meets, since a pixel's decision reads its neighbours in its tile.
    const CropWindow asked = crop_within(options.crop, film.width, film.height);
    // A shared filter reads the pixels within its reach: they are rendered too.
    const auto reach = static_cast<uint32_t>(spread.weights.size() / 2);
    const CropWindow grown{
        asked.x0 - std::min(asked.x0, reach), asked.y0 - std::min(asked.y0, reach),
        std::min(film.width, asked.x1 + reach), std::min(film.height, asked.y1 + reach)};
    if (reach > 0 && options.spp_end > 0 && asked != CropWindow{0, 0, film.width, film.height})
        throw_error(
            "--spp-range parts of a crop window cannot be merged with filter_samples = "
            "\"shared\" (a pixel takes its neighbours' samples, from beyond the window): render "
            "parts of the whole frame, or filter_samples = \"own\"");
    const CropWindow win = plan.on() ? whole_tiles(grown, film.width, film.height) : grown;
    spread.win = win;
    spread.asked = asked;
    job.crop_x0 = win.x0;
    job.crop_y0 = win.y0;
    job.crop_width = win.x1 - win.x0;
    out.width = win.x1 - win.x0;
    out.height = win.y1 - win.y0;
    out.window = ImageWindow{win.x0, win.y0, film.width, film.height};
    out.layers.clear();
    out.layer_names.clear();
    // Adaptive sampling judges the glints apart: it needs their layer, shown or not.
    if (options.layers || plan.on()) set_up_layers(job, scene, options, camera, out);
    // Adaptive sampling's per-pixel state (80 bytes) counted as 20 layer channels.
    check_film_memory(out.width, out.height, job.spp - first_sample, options,
                      job.layer_film.channels + (plan.on() ? 20 : 0));
    out.sums.assign(static_cast<std::size_t>(out.width) * out.height * 3, SampleSum(0));
    job.sums = &out.sums;
    if (plan.on()) {
        adaptive.reset(static_cast<std::size_t>(out.width) * out.height);
        job.adaptive_film = &adaptive;
    }
    out.layers.assign(static_cast<std::size_t>(out.width) * out.height * job.layer_film.channels,
                      0.0f);

    TileRun run(job, options, win,
                static_cast<uint64_t>(out.width) * out.height * (job.spp - first_sample));
    const uint32_t stride = options.preview_pass && options.on_pass && job.spp - first_sample > 1 &&
                                    options.crop.whole()
                                ? preview_stride(film.width, film.height)
                                : 1;
    if (stride > 1) preview_pass(run, film, stride, first_sample, out, t0);
    uint32_t passes = 0;
    const uint32_t samples = full_passes(run, first_sample, spread, out, passes, t0) - first_sample;
    // The image: the mean of the samples summed.
    out.image.resize(out.sums.size());
    const uint32_t* counts = plan.on() ? adaptive.count.data() : nullptr;
    for (std::size_t i = 0; i < out.image.size(); ++i)
        out.image[i] = sample_mean(out.sums[i], counts ? counts[i / 3] : samples);
    if (job.layers)
        finish_layers(out.layers, job.layer_film.layout, job.layer_plan, samples, counts);
    spread.apply(out.image, 3, std::vector<bool>(3, true));
    // (Adaptive sampling's own glint layer, when not asked for, is dropped below: not spread.)
    if (job.layers && options.layers)
        spread.apply(out.layers, out.layer_names.size(), spread_layers(out.layer_names));
    // Cut to the window before the counters are taken: they count its own samples (MPI bands
    // that rendered the rows around them add up to the frame's, not those rows twice). Adaptive
    // sampling cuts below, once it has counted every sample taken.
    if (!plan.on()) {
        std::vector<uint32_t> none;
        crop_result(win, asked, none, out);
    }
    record_stats(job, options, film, samples, first_sample, passes, out);
    out.stats.footprints = job.footprints;
    if (spread.on()) out.stats.filter_spread = spread.weights;
    if (scene.materials)
        for (const auto& mat : *scene.materials) {
            if (!mat) continue;
            if (std::string report = mat->bad_output().take_report(); !report.empty())
                out.stats.plugin_problems.push_back(fmt::format(
                    "{}: outputs the renderer could not use: {}", mat->label(), report));
        }
    if (plan.on()) {
        // Every sample taken counts (those of the tiles' pixels outside the window too).
        out.stats.samples =
            std::accumulate(adaptive.count.begin(), adaptive.count.end(), uint64_t{0});
        crop_result(win, asked, adaptive.count, out);
        add_spp_layer(adaptive.count, options.layers, out);
    }
    out.stats.seconds = seconds_since(t0);
}

}  // namespace spangle
