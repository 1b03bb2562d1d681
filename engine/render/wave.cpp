// One wave through every stage (render/wave.h), and its paths' light into the film.

#include "render/wave.h"

#include <algorithm>

namespace spangle {
namespace {

/** The image index of full-frame pixel `pix` (the same index without a crop window). */
std::size_t film_index(const RenderJob& job, uint32_t pix) {
    const uint32_t x = pix % job.width, y = pix / job.width;
    return static_cast<std::size_t>(y - job.crop_y0) * job.crop_width + (x - job.crop_x0);
}

/** Adds the wave's n paths to the film in a fixed order (pixel-major, then sample). The
 *  film's sums are exact, so they are the same however the samples are split (threads,
 *  passes, --spp-range parts). A non-finite radiance is counted and replaced by black. */
template <class Sink>
void accumulate(RenderJob& job, const PathBatch& p, Sink& sink, std::size_t n) {
    for (std::size_t k = 0; k < n; ++k) {
        Vec3 l = p.radiance[k];
        const bool finite = is_finite(l);
        if (!finite) {
            ++job.nonfinite;
            const uint64_t key = (static_cast<uint64_t>(p.pixel[k]) << 24) | p.sample[k];
            uint64_t prev = job.first_bad.load();
            while (key < prev && !job.first_bad.compare_exchange_weak(prev, key)) {
            }
            l = Vec3(0.0f);
        }
        const std::size_t at = film_index(job, p.pixel[k]);
        if (job.sums) {
            SampleSum* px = &(*job.sums)[3 * at];
            px[0] += to_sample_sum(l.x);
            px[1] += to_sample_sum(l.y);
            px[2] += to_sample_sum(l.z);
        } else {
            float* px = &(*job.image)[3 * at];
            px[0] += l.x;
            px[1] += l.y;
            px[2] += l.z;
        }
        sink.accumulate(k, at, finite);
        if (job.adaptive_film && job.sums) {
            AdaptiveFilm& a = *job.adaptive_film;
            ++a.count[at];
            // The quarter-sums of sample numbers 1, 2, 3 modulo 4 (that of 0 is the rest).
            if (const uint32_t quarter = p.sample[k] & 3u) {
                const Vec3 g = finite ? sink.glint(k) : Vec3(0.0f);
                // The environment seen directly, when its layer keeps it out of the beauty, is
                // judged with it: the pixel the compositor rebuilds is beauty + background.
                const Vec3 bg = finite && job.background_apart ? sink.background_of(k) : Vec3(0.0f);
                float* o = &a.parts[AdaptiveFilm::kParts * at + 6 * (quarter - 1)];
                o[0] += l.x + bg.x;
                o[1] += l.y + bg.y;
                o[2] += l.z + bg.z;
                o[3] += g.x;
                o[4] += g.y;
                o[5] += g.z;
            }
        }
    }
}

}  // namespace

template <class Sink>
void trace_wave(RenderJob& job, Workspace& ws, Sink& sink, const Tile& tile, uint32_t first_sample,
                uint32_t count) {
    const std::size_t n = start_paths(job, ws, tile, first_sample, count);
    sink.begin_wave(job.layer_film, n);
    const auto& materials = *job.scene->materials;
    uint64_t rays = 0, shadow = 0;
    for (uint32_t bounce = 0; bounce <= job.max_depth; ++bounce) {
        intersect(job, ws, sink, n, bounce, rays);
        for (std::size_t m = 0; m < materials.size(); ++m) {
            const uint32_t first = ws.group_start[m], count_m = ws.group_start[m + 1] - first;
            for (uint32_t off = 0; off < count_m; off += kMaxBatch) {
                const uint32_t* paths = ws.order.data() + first + off;
                const uint32_t batch = std::min(kMaxBatch, count_m - off);
                shade(job, ws, sink, *materials[m], paths, batch, bounce, shadow);
                scatter(job, ws, sink, *materials[m], paths, batch, bounce);
            }
        }
    }
    job.camera_rays += n;
    job.bounce_rays += rays - n;
    job.shadow_rays += shadow;
    accumulate(job, ws.paths, sink, n);
}

template void trace_wave<NullSink>(RenderJob&, Workspace&, NullSink&, const Tile&, uint32_t,
                                   uint32_t);
template void trace_wave<LayerSink>(RenderJob&, Workspace&, LayerSink&, const Tile&, uint32_t,
                                    uint32_t);

}  // namespace spangle
