#include "render/camera.h"

#include <algorithm>
#include <cmath>

#include "scene/components.h"

namespace spangle {

FilterSampler::FilterSampler(FilterKind kind, float radius)
    : radius_(radius > 0.0f ? radius : default_filter_radius(kind)) {
    // Piecewise-constant filter over kBins bins, then its inverse CDF tabulated finely enough that
    // linear interpolation in u reproduces it (sampling is the hot path; this runs once).
    std::array<double, kBins + 1> cdf{};
    const double r = static_cast<double>(radius_);
    for (int i = 0; i < kBins; ++i) {
        const double x = -r + (i + 0.5) * 2.0 * r / kBins;
        cdf[static_cast<std::size_t>(i + 1)] =
            cdf[static_cast<std::size_t>(i)] + filter_value(kind, x, r);
    }
    for (double& c : cdf) c /= cdf[kBins];
    std::size_t bin = 0;
    for (int j = 0; j <= kInverse; ++j) {
        const double u = static_cast<double>(j) / kInverse;
        while (bin + 1 < kBins && cdf[bin + 1] < u) ++bin;
        const double lo = cdf[bin], hi = cdf[bin + 1];
        const double t = hi > lo ? std::clamp((u - lo) / (hi - lo), 0.0, 1.0) : 0.5;
        inverse_[static_cast<std::size_t>(j)] =
            static_cast<float>(-r + (static_cast<double>(bin) + t) * 2.0 * r / kBins);
    }
}

float FilterSampler::sample(float u) const {
    const float x = std::clamp(u, 0.0f, 1.0f) * kInverse;
    const int i = std::min(static_cast<int>(x), kInverse - 1);
    const float t = x - static_cast<float>(i);
    return inverse_[static_cast<std::size_t>(i)] * (1.0f - t) +
           inverse_[static_cast<std::size_t>(i + 1)] * t;
}

CameraModel::CameraModel(Vec3 position, Vec3 look_at, Vec3 up, float fov_deg, float aperture,
                         float focus_distance, uint32_t width, uint32_t height,
                         const FilmLayout& layout)
    : origin_(position),
      forward_(normalize(look_at - position)),
      tan_half_(layout.ortho_height > 0.0f ? 0.5f * layout.ortho_height
                                           : std::tan(0.5f * fov_deg * kPi / 180.0f)),
      aspect_(static_cast<float>(width) / static_cast<float>(height)),
      aperture_(aperture),
      focus_(focus_distance),
      width_(static_cast<float>(width)),
      height_(static_cast<float>(height)) {
    screen_ = layout.screen;
    ortho_ = layout.ortho_height > 0.0f && !layout.equirect;
    equirect_ = layout.equirect;
    if (equirect_) {
        screen_ = {};
        aperture_ = 0.0f;
    }
    if (layout.fov_shorter && !has_screen() && aspect_ < 1.0f) tan_half_ /= aspect_;
    right_ = normalize(cross(forward_, up));
    up_ = cross(right_, forward_);
    if (layout.mirror) right_ = -right_;
    pixel_angle_ =
        has_screen() ? (screen_[3] - screen_[2]) * tan_half_ / height_ : 2.0f * tan_half_ / height_;
    if (equirect_) pixel_angle_ = kPi / height_;  // a pixel's height in elevation
}

CameraModel CameraModel::of(const Camera& c, uint32_t width, uint32_t height) {
    return CameraModel(c.position, c.look_at, c.up, c.fov_deg, c.aperture, c.focus_distance, width,
                       height,
                       FilmLayout{c.mirror, c.screen, c.fov_shorter, c.ortho_height, c.equirect});
}

bool CameraModel::has_screen() const {
    return screen_[0] != 0.0f || screen_[1] != 0.0f || screen_[2] != 0.0f || screen_[3] != 0.0f;
}

CameraMatrices CameraModel::matrices() const {
    const Vec3 axes[3] = {right_, up_, forward_};
    CameraMatrices m;
    auto& c = m.world_to_camera;
    for (int j = 0; j < 3; ++j) {
        const Vec3 a = axes[j];
        c[static_cast<std::size_t>(0 * 4 + j)] = a.x;
        c[static_cast<std::size_t>(1 * 4 + j)] = a.y;
        c[static_cast<std::size_t>(2 * 4 + j)] = a.z;
        c[static_cast<std::size_t>(3 * 4 + j)] = -dot(origin_, a);
    }
    c[15] = 1.0f;
    // Camera space to NDC: x = sx cx / W + ox, y = sy cy / W + oy, as (X, Y, Z, W) with W = cz
    // (perspective) or 1 (orthographic); the offsets sit in the row W comes from. Without a
    // screen window sx = 0.5 / (tan_half aspect), sy = -0.5 / tan_half and the offsets are 0.5;
    // with one x = (cx / W / t - x0) / (x1 - x0), y = (y1 - cy / W / t) / (y1 - y0).
    const float t = tan_half_, aspect = aspect_;
    float sx = 0.5f / (t * aspect), sy = -0.5f / t, ox = 0.5f, oy = 0.5f;
    if (has_screen()) {
        const float w = screen_[1] - screen_[0], h = screen_[3] - screen_[2];
        sx = 1.0f / (t * w);
        sy = -1.0f / (t * h);
        ox = -screen_[0] / w;
        oy = screen_[3] / h;
    }
    const std::size_t w_row = ortho_ ? 3 : 2;
    float p[16] = {};
    p[0 * 4 + 0] = sx;
    p[1 * 4 + 1] = sy;
    p[2 * 4 + 2] = 1.0f;
    p[w_row * 4 + 0] = ox;
    p[w_row * 4 + 1] = oy;
    p[w_row * 4 + 3] = 1.0f;
    for (std::size_t i = 0; i < 4; ++i)
        for (std::size_t j = 0; j < 4; ++j) {
            float sum = 0.0f;
            for (std::size_t k = 0; k < 4; ++k) sum += c[i * 4 + k] * p[k * 4 + j];
            m.world_to_ndc[i * 4 + j] = sum;
        }
    return m;
}

Vec3 CameraModel::point_on_film(float fx, float fy) const {
    if (equirect_) {
        const float phi = (fx / width_ - 0.5f) * (2.0f * kPi);
        const float theta = (0.5f - fy / height_) * kPi;
        const float c = std::cos(theta);
        return forward_ * (c * std::cos(phi)) + right_ * (c * std::sin(phi)) +
               up_ * std::sin(theta);
    }
    if (has_screen()) {
        const float sx = (screen_[0] + (screen_[1] - screen_[0]) * fx / width_) * tan_half_;
        const float sy = (screen_[3] - (screen_[3] - screen_[2]) * fy / height_) * tan_half_;
        return forward_ + right_ * sx + up_ * sy;
    }
    const float sx = (2.0f * fx / width_ - 1.0f) * tan_half_ * aspect_;
    const float sy = (1.0f - 2.0f * fy / height_) * tan_half_;
    return forward_ + right_ * sx + up_ * sy;
}

RayDifferential CameraModel::generate(float fx, float fy, float lu, float lv) const {
    // The lens point (concentric disk mapping), the same for the ray and its differentials.
    Vec3 lens(0.0f);
    if (aperture_ > 0.0f) {
        const float a = 2.0f * lu - 1.0f, b = 2.0f * lv - 1.0f;
        float rr = 0.0f, phi = 0.0f;
        if (a != 0.0f || b != 0.0f) {
            if (std::fabs(a) > std::fabs(b)) {
                rr = a;
                phi = (kPi / 4.0f) * (b / a);
            } else {
                rr = b;
                phi = kPi / 2.0f - (kPi / 4.0f) * (a / b);
            }
        }
        lens = (right_ * std::cos(phi) + up_ * std::sin(phi)) * (rr * aperture_);
    }
    const auto make = [&](float x, float y, Vec3& o, Vec3& d) {
        // The direction with a unit forward component (a unit direction for a panorama).
        const Vec3 dir = point_on_film(x, y);
        // Perspective: from the position towards the film point; orthographic: from the film
        // point on the plane through the position, along the view.
        const Vec3 from = ortho_ ? origin_ + (dir - forward_) : origin_;
        const Vec3 along = ortho_ ? forward_ : dir;
        if (aperture_ <= 0.0f) {
            o = from;
            d = normalize(along);
            return;
        }
        // Thin lens: every ray through the lens point reaches the same point on the focal plane.
        o = from + lens;
        d = normalize(from + along * focus_ - o);
    };
    RayDifferential r;
    make(fx, fy, r.o, r.d);
    make(fx + 1.0f, fy, r.dx_o, r.dx_d);
    make(fx, fy + 1.0f, r.dy_o, r.dy_d);
    return r;
}

}  // namespace spangle
