// The first stage: camera rays. Each path's pixel, sample and time; its ray through the pixel
// filter and the lens, with differentials towards the neighbouring pixels.

#include <algorithm>
#include <limits>

#include "render/wave.h"

namespace spangle {
namespace {

/** The camera at shutter time `time` (0..1) of a moving camera: the fields of the two steps
 *  around it blended linearly. */
CameraModel camera_at(const RenderJob& job, float time) {
    const std::vector<Camera>& steps = *job.camera_steps;
    std::size_t i = 0;
    float s = 0.0f;
    motion_step(steps.size(), time, i, s);
    const Camera& a = steps[i];
    const Camera& b = steps[i + 1];
    const auto mix = [s](auto x, auto y) { return x + (y - x) * s; };
    Camera c = a;  // the flags and the screen window are a's
    c.position = mix(a.position, b.position);
    c.look_at = mix(a.look_at, b.look_at);
    c.up = mix(a.up, b.up);
    c.fov_deg = mix(a.fov_deg, b.fov_deg);
    c.aperture = mix(a.aperture, b.aperture);
    c.focus_distance = mix(a.focus_distance, b.focus_distance);
    c.ortho_height = mix(a.ortho_height, b.ortho_height);
    return CameraModel::of(c, job.width, job.height);
}

/** Path i: sample `smp` of pixel (x, y), the top-left of a block of job.stride pixels whose
 *  value is traced at pixel `pix`. */
void start_path(const RenderJob& job, PathBatch& p, std::size_t i, uint32_t x, uint32_t y,
                uint32_t pix, uint32_t smp) {
    const float scale = static_cast<float>(job.stride);
    float fu, fv, lu, lv, tu = 0.0f, spare;
    const uint64_t key = sobol_pixel_key(job.seed, pix);
    sobol_2d_keyed(key, smp, kPairFilter, fu, fv);
    sobol_2d_keyed(key, smp, kPairLens, lu, lv);
    if (job.motion) sobol_2d_keyed(key, smp, kPairTime, tu, spare);
    // Filter importance sampling: the sample lands where the filter puts it.
    const float fx = static_cast<float>(x) + scale * (0.5f + job.filter->sample(fu));
    const float fy = static_cast<float>(y) + scale * (0.5f + job.filter->sample(fv));
    p.pixel[i] = pix;
    p.key[i] = key;
    p.sample[i] = smp;
    p.time[i] = tu;
    float pixel_angle = job.camera->pixel_angle(), pixel_width = job.camera->pixel_width();
    if (job.camera_steps) {  // a moving camera (2 or more steps)
        const CameraModel cam = camera_at(job, tu);
        p.ray[i] = cam.generate(fx, fy, lu, lv);
        pixel_angle = cam.pixel_angle();
        pixel_width = cam.pixel_width();
    } else {
        p.ray[i] = job.camera->generate(fx, fy, lu, lv);
    }
    if (job.stride > 1) {  // a preview path stands for the whole block: so does its footprint
        RayDifferential& r = p.ray[i];
        r.dx_o = r.o + (r.dx_o - r.o) * scale;
        r.dx_d = r.d + (r.dx_d - r.d) * scale;
        r.dy_o = r.o + (r.dy_o - r.o) * scale;
        r.dy_d = r.d + (r.dy_d - r.d) * scale;
    }
    p.has_diff[i] = 1;
    p.fp_width[i] = pixel_width * scale;
    p.fp_spread[i] = pixel_angle * scale;
    p.throughput[i] = Vec3(1.0f);
    p.radiance[i] = Vec3(0.0f);
    p.prev_pdf[i] = 0.0f;
    p.prev_delta[i] = 1;  // camera rays see emitters with full weight
    p.min_pdf[i] = std::numeric_limits<float>::infinity();
    p.active[i] = 1;
    p.catcher[i] = 0;
}

}  // namespace

std::size_t start_paths(const RenderJob& job, Workspace& ws, const Tile& tile,
                        uint32_t first_sample, uint32_t count) {
    const uint32_t st = job.stride;
    const uint32_t tw = (tile.x1 - tile.x0 + st - 1) / st, th = (tile.y1 - tile.y0 + st - 1) / st;
    const std::size_t n = static_cast<std::size_t>(tw) * th * count;
    ws.paths.resize(n);
    std::size_t i = 0;
    const std::vector<uint8_t>* active =
        job.adaptive_film && st == 1 ? &job.adaptive_film->active : nullptr;
    for (uint32_t y = tile.y0; y < tile.y1; y += st)
        for (uint32_t x = tile.x0; x < tile.x1; x += st) {
            // Adaptive sampling: a pixel that has stopped takes no more samples.
            if (active && !(*active)[static_cast<std::size_t>(y - job.crop_y0) * job.crop_width +
                                     (x - job.crop_x0)])
                continue;
            for (uint32_t s = 0; s < count; ++s, ++i) {
                // The pixel that holds the block's value (the pixel itself when st == 1).
                const uint32_t pix = std::min(y + st / 2, tile.y1 - 1) * job.width +
                                     std::min(x + st / 2, tile.x1 - 1);
                start_path(job, ws.paths, i, x, y, pix, first_sample + s);
            }
        }
    ws.paths.resize(i);
    return i;
}

}  // namespace spangle
