#include "render/lights.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace spangle {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/** 1 - cos of the half-angle of the cone a sphere of squared radius r2 subtends from squared
 *  distance dist2 (> r2), as sin^2 / (1 + cos): 1 - sqrt(1 - sin^2) in floats lost it (a bulb
 *  of 1e-3 of its distance came out 4-7% bright, one of 1e-4 black: its cone rounded to
 *  nothing). */
float sphere_one_minus_cos(float r2, float dist2) {
    const double s2 = static_cast<double>(r2) / static_cast<double>(dist2);
    return static_cast<float>(s2 / (1.0 + std::sqrt(std::max(0.0, 1.0 - s2))));
}

/** The direction at polar angle (cos_t, sin_t) from axis and azimuth 2 pi u1 about it. */
Vec3 cone_direction(Vec3 axis, float cos_t, float sin_t, float u1) {
    const float phi = 2.0f * kPi * u1;
    Vec3 s, t;
    make_basis(axis, s, t);
    return normalize(s * (sin_t * std::cos(phi)) + t * (sin_t * std::sin(phi)) + axis * cos_t);
}

/** Uniform direction in the cone about axis whose half-angle has 1 - cos = one_minus_cos. */
Vec3 sample_narrow_cone(Vec3 axis, float one_minus_cos, float u0, float u1) {
    const float x = u0 * one_minus_cos;  // 1 - cos(theta)
    return cone_direction(axis, 1.0f - x, std::sqrt(std::max(0.0f, x * (2.0f - x))), u1);
}

/** Uniform direction in the cone of half-angle acos(cos_max) about axis. */
Vec3 sample_cone(Vec3 axis, float cos_max, float u0, float u1) {
    const float cos_t = 1.0f - u0 * (1.0f - cos_max);
    return cone_direction(axis, cos_t, std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t)), u1);
}

Vec3 gram_schmidt(Vec3 v, Vec3 w) {
    return v - w * dot(v, w);
}

/** Arvo's uniform sampling of the spherical triangle (a, b, c) (unit vectors). */
bool sample_spherical_triangle(Vec3 a, Vec3 b, Vec3 c, float u0, float u1, Vec3& w) {
    const Vec3 n_ab = cross(a, b), n_bc = cross(b, c), n_ca = cross(c, a);
    if (!(length(n_ab) > 0.0f && length(n_bc) > 0.0f && length(n_ca) > 0.0f)) return false;
    const Vec3 nab = normalize(n_ab), nbc = normalize(n_bc), nca = normalize(n_ca);
    const auto angle = [](Vec3 x, Vec3 y) {
        return static_cast<double>(std::acos(std::clamp(dot(x, y), -1.0f, 1.0f)));
    };
    const double alpha = angle(nab, -nca), beta = angle(nbc, -nab), gamma = angle(nca, -nbc);
    // Sample a sub-triangle area uniformly, then the point along the arc.
    const double area_pi = alpha + beta + gamma;
    const double ap_pi = M_PI + static_cast<double>(u0) * (area_pi - M_PI);
    const double cos_a = std::cos(alpha), sin_a = std::sin(alpha);
    const double sin_phi = std::sin(ap_pi) * cos_a - std::cos(ap_pi) * sin_a;
    const double cos_phi = std::cos(ap_pi) * cos_a + std::sin(ap_pi) * sin_a;
    const double k1 = cos_phi + cos_a;
    const double k2 = sin_phi - sin_a * static_cast<double>(dot(a, b));
    const double denom = (k2 * sin_phi + k1 * cos_phi) * sin_a;
    if (!(std::fabs(denom) > 0.0)) return false;
    double cos_bp = (k2 + (k2 * cos_phi - k1 * sin_phi) * cos_a) / denom;
    cos_bp = std::clamp(cos_bp, -1.0, 1.0);
    const double sin_bp = std::sqrt(std::max(0.0, 1.0 - cos_bp * cos_bp));
    const Vec3 ca = gram_schmidt(c, a);
    if (!(length(ca) > 0.0f)) return false;
    const Vec3 cp = a * static_cast<float>(cos_bp) + normalize(ca) * static_cast<float>(sin_bp);
    const float cos_t = 1.0f - u1 * (1.0f - dot(cp, b));
    const float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
    const Vec3 cpb = gram_schmidt(cp, b);
    if (!(length(cpb) > 0.0f)) return false;
    w = normalize(b * cos_t + normalize(cpb) * sin_t);
    return is_finite(w);
}

}  // namespace

float power_heuristic(float a, float b) {
    const float a2 = a * a, b2 = b * b;
    if (a2 + b2 <= std::numeric_limits<float>::max() &&
        a2 + b2 >= std::numeric_limits<float>::min())
        return a2 / (a2 + b2);
    // A density beyond 1.8e19 (an emitter seen exactly edge-on: cos 1e-17 from a 6e-17 rotation
    // term) squared to inf and the weight was inf / inf = NaN; densities below 1e-19 (a light
    // of 1e20 square metres) squared to 0 and the weight was 0 for both strategies: through the
    // ratio of the smaller density to the larger instead. (NaN densities give 0.)
    if (!(a > 0.0f) || !(b >= 0.0f)) return 0.0f;
    if (std::isinf(a) && std::isinf(b)) return 0.5f;
    if (a >= b) {
        const float r = b / a;
        return 1.0f / (1.0f + r * r);
    }
    const float r = a / b, r2 = r * r;
    return r2 / (1.0f + r2);
}

double triangle_solid_angle(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
    const Vec3 x = normalize(a - p), y = normalize(b - p), z = normalize(c - p);
    const double num = std::fabs(static_cast<double>(dot(x, cross(y, z))));
    const double den = 1.0 + static_cast<double>(dot(x, y)) + static_cast<double>(dot(y, z)) +
                       static_cast<double>(dot(z, x));
    return 2.0 * std::atan2(num, den);
}

bool use_solid_angle_sampling(double solid_angle) {
    // Arvo's formulas lose precision for tiny triangles, where area sampling is as good, and
    // for triangles that fill most of the view.
    return solid_angle > 1e-4 && solid_angle < 6.0;
}

// ------------------------------------------------------------------------------ environment map

EnvironmentMap::EnvironmentMap(std::vector<float> rgb, int width, int height, float rotation_deg,
                               MapProjection projection, const Affine& to_map)
    : width_(width),
      height_(height),
      rgb_(std::move(rgb)),
      projection_(projection),
      to_map_(to_map) {
    cos_rot_ = std::cos(rotation_deg * kPi / 180.0f);
    sin_rot_ = std::sin(rotation_deg * kPi / 180.0f);
    std::vector<double> row_weight(static_cast<std::size_t>(height));
    cols_.reserve(static_cast<std::size_t>(height));
    const bool equal_area = projection == MapProjection::EqualArea;
    // Every pixel of an equal-area map spans the same solid angle; a lat-long row, sin(theta).
    const double pixel_solid = equal_area ? 4.0 * M_PI / (static_cast<double>(width) * height)
                                          : (2.0 * M_PI / width) * (M_PI / height);
    for (int y = 0; y < height; ++y) {
        const double sin_t = equal_area ? 1.0 : std::sin(M_PI * (y + 0.5) / height);
        std::vector<double> w(static_cast<std::size_t>(width));
        double sum = 0.0;
        for (int x = 0; x < width; ++x) {
            const float* px = &rgb_[3 * (static_cast<std::size_t>(y) * width + x)];
            const double lum = luminance({px[0], px[1], px[2]});
            w[static_cast<std::size_t>(x)] = lum * sin_t;
            sum += lum * sin_t;
        }
        lum_integral_ += sum * pixel_solid;
        row_weight[static_cast<std::size_t>(y)] = sum;
        cols_.emplace_back(w);
    }
    rows_ = Distribution1D(row_weight);
}

namespace {

/** pbrt-v4's square of an equal-area octahedral map -> unit direction (Clarberg 2008): the
 *  square's diamond |u| + |v| <= 1 is the upper hemisphere, its corners the lower one. */
Vec3 equal_area_to_sphere(float su, float sv) {
    const float u = 2.0f * su - 1.0f, v = 2.0f * sv - 1.0f;
    const float au = std::fabs(u), av = std::fabs(v);
    const float signed_dist = 1.0f - (au + av);
    const float r = 1.0f - std::fabs(signed_dist);
    const float phi = (r == 0.0f ? 1.0f : (av - au) / r + 1.0f) * kPi / 4.0f;
    const float z = std::copysign(1.0f - r * r, signed_dist);
    const float s = r * std::sqrt(std::max(0.0f, 2.0f - r * r));
    return {std::copysign(std::cos(phi), u) * s, std::copysign(std::sin(phi), v) * s, z};
}

/** The inverse of equal_area_to_sphere: unit direction -> the square [0, 1]^2. */
void sphere_to_equal_area(Vec3 d, float& su, float& sv) {
    const float ax = std::fabs(d.x), ay = std::fabs(d.y), az = std::fabs(d.z);
    const float r = std::sqrt(std::max(0.0f, 1.0f - az));
    const float a = std::max(ax, ay), b = std::min(ax, ay);
    float phi = (a == 0.0f ? 0.0f : std::atan(b / a)) * 2.0f / kPi;
    if (ax < ay) phi = 1.0f - phi;
    float v = phi * r, u = r - v;
    if (d.z < 0.0f) {
        std::swap(u, v);
        u = 1.0f - u;
        v = 1.0f - v;
    }
    su = 0.5f * (std::copysign(u, d.x) + 1.0f);
    sv = 0.5f * (std::copysign(v, d.y) + 1.0f);
}

}  // namespace

float EnvironmentMap::uv_to_solid(Vec3 d) const {
    if (projection_ == MapProjection::EqualArea) return 4.0f * kPi;
    const Vec3 w = projection_ == MapProjection::LatLongZUp ? to_map_.apply_vector(d) : d;
    const float sin_t = projection_ == MapProjection::LatLongZUp ? std::sqrt(w.x * w.x + w.y * w.y)
                                                                 : std::sqrt(w.x * w.x + w.z * w.z);
    return 2.0f * kPi * kPi * sin_t;
}

void EnvironmentMap::to_uv(Vec3 d, float& u, float& v) const {
    if (projection_ != MapProjection::LatLongYUp) {
        const Vec3 w = to_map_.apply_vector(d);
        if (projection_ == MapProjection::EqualArea) return sphere_to_equal_area(w, u, v);
        // pbrt: phi = atan2(y, x) in [0, 2 pi), theta from +z.
        const float phi = std::atan2(w.y, w.x);
        u = (phi < 0.0f ? phi + 2.0f * kPi : phi) / (2.0f * kPi);
        v = std::atan2(std::sqrt(w.x * w.x + w.y * w.y), w.z) / kPi;
        return;
    }
    // Undo the map's turn about +y (rotation_deg 90 takes its centre from -z to +x), then
    // phi = atan2(x, -z): u = 0.5 looks down -z. theta comes
    // from atan2 of the horizontal length and y, which stays accurate at the poles (acos(y)
    // does not).
    const float x = cos_rot_ * d.x + sin_rot_ * d.z;
    const float z = -sin_rot_ * d.x + cos_rot_ * d.z;
    u = 0.5f + std::atan2(x, -z) / (2.0f * kPi);
    v = std::atan2(std::sqrt(x * x + z * z), d.y) / kPi;
}

Vec3 EnvironmentMap::from_uv(float u, float v) const {
    if (projection_ != MapProjection::LatLongYUp) {
        Vec3 w;
        if (projection_ == MapProjection::EqualArea) {
            w = equal_area_to_sphere(u, v);
        } else {
            const float phi = u * 2.0f * kPi, theta = v * kPi;
            const float s = std::sin(theta);
            w = {s * std::cos(phi), s * std::sin(phi), std::cos(theta)};
        }
        // to_map_ is a rotation: its transpose takes the map's frame back to the world.
        const auto& m = to_map_.m;
        return {m[0][0] * w.x + m[1][0] * w.y + m[2][0] * w.z,
                m[0][1] * w.x + m[1][1] * w.y + m[2][1] * w.z,
                m[0][2] * w.x + m[1][2] * w.y + m[2][2] * w.z};
    }
    const float phi = (u - 0.5f) * 2.0f * kPi, theta = v * kPi;
    const float s = std::sin(theta);
    const float x = s * std::sin(phi), z = -s * std::cos(phi), y = std::cos(theta);
    return {cos_rot_ * x - sin_rot_ * z, y, sin_rot_ * x + cos_rot_ * z};
}

Vec3 EnvironmentMap::eval(Vec3 d) const {
    if (empty()) return Vec3(0.0f);
    // Bilinear between pixel centres (wrapping in u, clamped in v), so that a map seen directly
    // is not blocky. Sampling stays piecewise constant: where the pdf is 0 but the interpolated
    // radiance is not, BSDF sampling finds it with weight 1, so the estimate stays unbiased.
    float u, v;
    to_uv(d, u, v);
    const float x = u * static_cast<float>(width_) - 0.5f,
                y = v * static_cast<float>(height_) - 0.5f;
    const float fx = std::floor(x), fy = std::floor(y);
    const float tx = x - fx, ty = y - fy;
    const bool wrap_u = projection_ != MapProjection::EqualArea;
    const auto px = [&](int xi, int yi) {
        xi = wrap_u ? ((xi % width_) + width_) % width_ : std::clamp(xi, 0, width_ - 1);
        yi = std::clamp(yi, 0, height_ - 1);
        const float* p =
            &rgb_[3 * (static_cast<std::size_t>(yi) * width_ + static_cast<std::size_t>(xi))];
        return Vec3(p[0], p[1], p[2]);
    };
    const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
    return (px(x0, y0) * (1.0f - tx) + px(x0 + 1, y0) * tx) * (1.0f - ty) +
           (px(x0, y0 + 1) * (1.0f - tx) + px(x0 + 1, y0 + 1) * tx) * ty;
}

Vec3 EnvironmentMap::sample(float u0, float u1, float& pdf) const {
    pdf = 0.0f;
    if (empty() || rows_.empty()) return {0, 1, 0};
    float ry, rx;
    const uint32_t y = rows_.sample(u0, &ry);
    const uint32_t x = cols_[y].sample(u1, &rx);
    const float u = (static_cast<float>(x) + rx) / static_cast<float>(width_);
    const float v = (static_cast<float>(y) + ry) / static_cast<float>(height_);
    const float pdf_uv =
        rows_.pmf(y) * cols_[y].pmf(x) * static_cast<float>(width_) * static_cast<float>(height_);
    if (projection_ == MapProjection::EqualArea) {
        pdf = pdf_uv / (4.0f * kPi);
        return from_uv(u, v);
    }
    const float sin_t = std::sin(v * kPi);
    if (!(sin_t > 0.0f)) return {0, 1, 0};
    pdf = pdf_uv / (2.0f * kPi * kPi * sin_t);
    return from_uv(u, v);
}

float EnvironmentMap::pdf(Vec3 d) const {
    if (empty() || rows_.empty()) return 0.0f;
    float u, v;
    to_uv(d, u, v);
    const int x = std::clamp(static_cast<int>(u * static_cast<float>(width_)), 0, width_ - 1);
    const int y = std::clamp(static_cast<int>(v * static_cast<float>(height_)), 0, height_ - 1);
    const auto uy = static_cast<uint32_t>(y), ux = static_cast<uint32_t>(x);
    if (projection_ != MapProjection::LatLongYUp) {
        const float jacobian = uv_to_solid(d);
        if (!(jacobian > 0.0f)) return 0.0f;
        return rows_.pmf(uy) * cols_[uy].pmf(ux) * static_cast<float>(width_) *
               static_cast<float>(height_) / jacobian;
    }
    const float sin_t = std::sqrt(d.x * d.x + d.z * d.z);  // rotation about y keeps it
    if (!(sin_t > 0.0f)) return 0.0f;
    const float pdf_uv = rows_.pmf(uy) * cols_[uy].pmf(ux) * static_cast<float>(width_) *
                         static_cast<float>(height_);
    return pdf_uv / (2.0f * kPi * kPi * sin_t);
}

// ------------------------------------------------------------------------------ the table

uint32_t LightTable::add_area(const AreaEmitter& e) {
    area_.push_back(e);
    return static_cast<uint32_t>(area_.size() - 1);
}
uint32_t LightTable::add_sphere(const SphereEmitter& e) {
    spheres_.push_back(e);
    return static_cast<uint32_t>(spheres_.size() - 1);
}
void LightTable::add_point(const PointEmitter& e) {
    points_.push_back(e);
}
void LightTable::add_distant(const DistantEmitter& e) {
    distant_.push_back(e);
}
void LightTable::set_environment(std::shared_ptr<const EnvironmentMap> env, uint32_t group) {
    if (env && !env->empty()) env_ = std::move(env);
    env_group_ = group;
}

namespace {
/** The defensive share of light selection (see finalize) and the most lights it applies to:
 *  beyond, a uniform share would go to many small emitters (an emissive mesh's triangles). */
constexpr double kDefensiveShare = 0.5;
constexpr std::size_t kDefensiveMaxLights = 8;
}  // namespace

void LightTable::finalize(float scene_radius) {
    const double r2 = static_cast<double>(scene_radius) * static_cast<double>(scene_radius);
    std::vector<double> power;
    for (const AreaEmitter& e : area_)
        power.push_back(static_cast<double>(luminance(e.radiance)) * static_cast<double>(e.area) *
                        M_PI * (e.two_sided ? 2.0 : 1.0) *
                        (e.image >= 0 ? static_cast<double>(e.image_mean) : 1.0));
    for (const SphereEmitter& s : spheres_)
        power.push_back(static_cast<double>(luminance(s.radiance)) * 4.0 * M_PI *
                        static_cast<double>(s.radius * s.radius) * M_PI);
    for (const PointEmitter& p : points_) {
        const double lum = luminance(p.intensity);
        power.push_back(p.cos_outer <= -1.0f
                            ? 4.0 * M_PI * lum
                            : 2.0 * M_PI * lum *
                                  (1.0 - 0.5 * (static_cast<double>(p.cos_inner) +
                                                static_cast<double>(p.cos_outer))));
    }
    for (const DistantEmitter& d : distant_) {
        const double e = d.solid_angle > 0.0f
                             ? static_cast<double>(luminance(d.radiance)) *
                                   static_cast<double>(d.solid_angle)  // ~ L pi sin^2 r
                             : static_cast<double>(luminance(d.radiance));
        power.push_back(M_PI * r2 * e);
    }
    if (env_) power.push_back(M_PI * r2 * env_->luminance_integral());
    for (double& p : power)
        if (!std::isfinite(p) || p < 0.0) p = 0.0;
    // A defensive share: with a few lights, each that emits is picked at least half as often as
    // it would be uniformly. Power is a poor guess of what a point receives: lights at infinity
    // are weighed by the scene's radius, which a large ground plane sets (the beetle's 80 m
    // floor gave the studio map 98.3% of the picks and the small key light, which lights most of
    // the floor, 1.7%: a key-light contribution 57 times as often zero as not, the floor's grain).
    // Only the pmf changes, and every pdf reads it: unbiased either way.
    double total = 0.0;
    std::size_t emitting = 0;
    for (double p : power) {
        total += p;
        emitting += p > 0.0 ? 1 : 0;
    }
    if (total > 0.0 && emitting > 1 && emitting <= kDefensiveMaxLights)
        for (double& p : power)
            if (p > 0.0)
                p = (1.0 - kDefensiveShare) * p / total +
                    kDefensiveShare / static_cast<double>(emitting);
    selection_ = Distribution1D(power);
}

Vec3 LightTable::area_emitted(uint32_t i, Vec3 w, float b1, float b2) const {
    const AreaEmitter& e = area_[i];
    const float c = dot(e.n, w);
    if (!(c > 0.0f || (e.two_sided && c < 0.0f))) return Vec3(0.0f);
    if (e.image < 0 || !images_) return e.radiance;
    const float b0 = 1.0f - b1 - b2;
    const float u = e.uv[0] * b0 + e.uv[2] * b1 + e.uv[4] * b2;
    const float v = e.uv[1] * b0 + e.uv[3] * b1 + e.uv[5] * b2;
    const Vec3 k = images_->at(static_cast<uint32_t>(e.image), u, v);
    return {e.radiance.x * k.x, e.radiance.y * k.y, e.radiance.z * k.z};
}

float LightTable::area_pdf(uint32_t i, Vec3 p, Vec3 q) const {
    const AreaEmitter& e = area_[i];
    const float sel = selection_.pmf(i);
    if (!e.parallelogram) {
        const double omega = triangle_solid_angle(p, e.p0, e.p0 + e.e1, e.p0 + e.e2);
        if (use_solid_angle_sampling(omega))
            return static_cast<float>(static_cast<double>(sel) / omega);
    }
    const Vec3 d = q - p;
    const float dist2 = dot(d, d);
    if (!(dist2 > 0.0f)) return 0.0f;
    const float cos_l = std::fabs(dot(e.n, d)) / std::sqrt(dist2);
    if (!(cos_l > 0.0f)) return 0.0f;
    return sel * dist2 / (cos_l * e.area);
}

float LightTable::sphere_pdf(uint32_t i, Vec3 p) const {
    const SphereEmitter& s = spheres_[i];
    const float sel = selection_.pmf(static_cast<uint32_t>(area_.size()) + i);
    const Vec3 d = s.center - p;
    const float dist2 = dot(d, d);
    const float r2 = s.radius * s.radius;
    if (dist2 <= r2) return 0.0f;  // inside: it emits outward, nothing reaches p
    return sel / (2.0f * kPi * sphere_one_minus_cos(r2, dist2));
}

float bsdf_hit_weight(Strategy strategy, bool after_delta, float bsdf_pdf, float light_pdf) {
    if (after_delta) return 1.0f;
    switch (strategy) {
        case Strategy::Mis:
            return power_heuristic(bsdf_pdf, light_pdf);
        case Strategy::NeeOnly:
            return light_pdf > 0.0f ? 0.0f : 1.0f;
        case Strategy::BsdfOnly:
            return 1.0f;
    }
    return 1.0f;
}

Vec3 LightTable::escaped(Vec3 d, float bsdf_pdf, bool after_delta, Strategy strategy,
                         Vec3* by_group) const {
    Vec3 l(0.0f);
    const auto first_distant =
        static_cast<uint32_t>(area_.size() + spheres_.size() + points_.size());
    for (std::size_t k = 0; k < distant_.size(); ++k) {
        const DistantEmitter& e = distant_[k];
        if (e.solid_angle <= 0.0f || dot(d, e.direction) < e.cos_radius) continue;
        const float light_pdf =
            selection_.pmf(first_distant + static_cast<uint32_t>(k)) / e.solid_angle;
        const Vec3 part = e.radiance * bsdf_hit_weight(strategy, after_delta, bsdf_pdf, light_pdf);
        l += part;
        if (by_group) by_group[e.group] += part;
    }
    if (env_) {
        const float light_pdf =
            selection_.pmf(first_distant + static_cast<uint32_t>(distant_.size())) * env_->pdf(d);
        const Vec3 part =
            env_->eval(d) * bsdf_hit_weight(strategy, after_delta, bsdf_pdf, light_pdf);
        l += part;
        if (by_group) by_group[env_group_] += part;
    }
    return l;
}

namespace {

/** Points s from p towards q (wi, dist); false when q is not a usable distance away. */
bool towards(Vec3 p, Vec3 q, LightSample& s) {
    const Vec3 d = q - p;
    s.dist = length(d);
    s.wi = d / s.dist;
    return s.dist > 0.0f && std::isfinite(s.dist);
}

/** A point q on area emitter e seen from p: by solid angle where that is stable (`solid`, and
 *  `pdf` is the solid-angle pdf with selection pmf sel), else by area; false when the sample
 *  fails. */
bool sample_area_point(const AreaEmitter& e, Vec3 p, float sel, float u1, float u2, Vec3& q,
                       bool& solid, float& pdf) {
    if (e.parallelogram) {
        q = e.p0 + e.e1 * u1 + e.e2 * u2;
        return true;
    }
    const Vec3 a = e.p0, b = e.p0 + e.e1, c = e.p0 + e.e2;
    const double omega = triangle_solid_angle(p, a, b, c);
    if (!use_solid_angle_sampling(omega)) {
        const float r = std::sqrt(u1);
        q = e.p0 + e.e1 * (r * (1.0f - u2)) + e.e2 * (r * u2);
        return true;
    }
    Vec3 w;
    if (!sample_spherical_triangle(normalize(a - p), normalize(b - p), normalize(c - p), u1, u2, w))
        return false;
    const float denom = dot(e.n, w);
    const float t = dot(e.n, a - p) / denom;
    if (!(t > 0.0f) || !std::isfinite(t)) return false;
    q = p + w * t;
    pdf = static_cast<float>(static_cast<double>(sel) / omega);
    solid = true;
    return true;
}

/** A direction towards sphere light e from p, with selection pmf sel. */
LightSample sample_sphere(const SphereEmitter& e, Vec3 p, float sel, float u1, float u2) {
    LightSample s;
    const Vec3 dc = e.center - p;
    const float dist2 = dot(dc, dc), r2 = e.radius * e.radius;
    // Inside the sphere: it emits outward, as the camera and BSDF rays see it (black from
    // within). It lit the inside through this sampling alone (a furnace in a sphere light: 0.5
    // by NEE, 0 by BSDF sampling, 0.09 combined).
    if (dist2 <= r2) return LightSample{};
    const float dist = std::sqrt(dist2);
    const Vec3 axis = dc / dist;
    const float one_minus_cos = sphere_one_minus_cos(r2, dist2);
    s.wi = sample_narrow_cone(axis, one_minus_cos, u1, u2);
    // Nearest intersection with the sphere along wi, in double, from the ray's distance to
    // the centre (b^2 - (|dc|^2 - r^2) cancels when the sphere is small and far).
    const double dx = dc.x, dy = dc.y, dz = dc.z;
    const double wx = s.wi.x, wy = s.wi.y, wz = s.wi.z;
    const double b = wx * dx + wy * dy + wz * dz;
    const double px = dx - wx * b, py = dy - wy * b, pz = dz - wz * b;
    const double rr = static_cast<double>(e.radius) * static_cast<double>(e.radius);
    const double disc = std::max(0.0, rr - (px * px + py * py + pz * pz));
    s.dist = static_cast<float>(b - std::sqrt(disc));
    s.pdf = sel / (2.0f * kPi * one_minus_cos);
    s.radiance = e.radiance;
    return s;
}

/** Point or spot light e seen from p, with selection pmf sel. */
LightSample sample_point(const PointEmitter& e, Vec3 p, float sel) {
    LightSample s;
    if (!towards(p, e.position, s)) return LightSample{};
    float falloff = 1.0f;
    if (e.cos_outer > -1.0f) {
        const float c = dot(-s.wi, e.axis);
        const float t =
            std::clamp((c - e.cos_outer) / std::max(1e-6f, e.cos_inner - e.cos_outer), 0.0f, 1.0f);
        // Smoothstep from the outer to the inner cone, or pbrt-v3's fourth power.
        falloff = e.quartic ? (t * t) * (t * t) : t * t * (3.0f - 2.0f * t);
    }
    s.radiance = e.intensity * (falloff / (s.dist * s.dist));
    s.pdf = sel;
    s.delta = true;
    return s;
}

/** A direction of light at infinity e, with selection pmf sel. */
LightSample sample_distant(const DistantEmitter& e, float sel, float u1, float u2) {
    LightSample s;
    s.dist = kInf;
    if (e.solid_angle <= 0.0f) {
        s.wi = e.direction;
        s.radiance = e.radiance;
        s.pdf = sel;
        s.delta = true;
    } else {
        s.wi = sample_cone(e.direction, e.cos_radius, u1, u2);
        s.radiance = e.radiance;
        s.pdf = sel / e.solid_angle;
    }
    return s;
}

}  // namespace

LightSample LightTable::sample_area(uint32_t id, Vec3 p, float sel, float u1, float u2) const {
    const AreaEmitter& e = area_[id];
    LightSample s;
    Vec3 q;
    bool solid = false;
    if (!sample_area_point(e, p, sel, u1, u2, q, solid, s.pdf)) return LightSample{};
    if (!towards(p, q, s)) return LightSample{};
    // (A textured emitter's radiance is read below, where the point's barycentrics are known.)
    if (e.image < 0) s.radiance = area_emitted(id, -s.wi);
    if (!solid) {
        const float cos_l = std::fabs(dot(e.n, s.wi));
        s.pdf = cos_l > 0.0f ? sel * s.dist * s.dist / (cos_l * e.area) : 0.0f;
    }
    if (!e.parallelogram) {
        // Where q lies on the triangle (for its cut-out, if it has one).
        const Vec3 d = q - e.p0;
        const float d00 = dot(e.e1, e.e1), d01 = dot(e.e1, e.e2), d11 = dot(e.e2, e.e2);
        const float d20 = dot(d, e.e1), d21 = dot(d, e.e2);
        const float den = d00 * d11 - d01 * d01;
        if (den > 0.0f) {
            s.area = static_cast<int32_t>(id);
            s.b1 = std::clamp((d11 * d20 - d01 * d21) / den, 0.0f, 1.0f);
            s.b2 = std::clamp((d00 * d21 - d01 * d20) / den, 0.0f, 1.0f - s.b1);
        }
        // A textured emitter shines with its image's colour at that point.
        if (e.image >= 0) s.radiance = area_emitted(id, -s.wi, s.b1, s.b2);
    }
    return s;
}

LightSample LightTable::sample(Vec3 p, float u0, float u1, float u2) const {
    if (selection_.empty()) return LightSample{};
    const uint32_t id = selection_.sample(u0, nullptr);
    const float sel = selection_.pmf(id);
    const auto n_area = static_cast<uint32_t>(area_.size());
    const auto n_sphere = static_cast<uint32_t>(spheres_.size());
    const auto n_point = static_cast<uint32_t>(points_.size());
    const auto n_distant = static_cast<uint32_t>(distant_.size());
    LightSample s;
    if (id < n_area) {
        s = sample_area(id, p, sel, u1, u2);
        s.group = area_[id].group;
    } else if (id < n_area + n_sphere) {
        s = sample_sphere(spheres_[id - n_area], p, sel, u1, u2);
        s.group = spheres_[id - n_area].group;
    } else if (id < n_area + n_sphere + n_point) {
        s = sample_point(points_[id - n_area - n_sphere], p, sel);
        s.group = points_[id - n_area - n_sphere].group;
    } else if (id < n_area + n_sphere + n_point + n_distant) {
        s = sample_distant(distant_[id - n_area - n_sphere - n_point], sel, u1, u2);
        s.group = distant_[id - n_area - n_sphere - n_point].group;
    } else {
        float pdf;
        s.wi = env_->sample(u1, u2, pdf);
        s.dist = kInf;
        s.radiance = env_->eval(s.wi);
        s.pdf = sel * pdf;
        s.group = env_group_;
    }
    if (!(s.pdf > 0.0f) || !std::isfinite(s.pdf) || max_component(s.radiance) <= 0.0f ||
        !is_finite(s.wi))
        return LightSample{};
    return s;
}

}  // namespace spangle
