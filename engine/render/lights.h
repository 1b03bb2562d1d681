#pragma once
// All lights of a frame and their sampling. One selection distribution over every light, by
// estimated power; each light type has its own sampling routine with an exact pdf so that
// next-event estimation and BSDF sampling combine by multiple importance sampling.
//
//   area     triangles of emissive meshes (solid-angle sampling, Arvo 1995, where stable; area
//            sampling otherwise) and quads (area sampling); emit from their front face
//   sphere   cone of directions subtended by the sphere; it emits outward (none inside it)
//   point    and spot: delta positions, intensity in W/sr
//   distant  a delta direction (irradiance), or a disk of angular radius r (uniform radiance
//            E / (pi sin^2 r), sampled uniformly in its cone): a sun
//   env      a lat-long environment map, importance-sampled by luminance x sin(theta)
// A constant-colour environment is not in the table: BSDF sampling alone reaches it, which is
// the better strategy for a uniform background.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/map_projection.h"
#include "core/math.h"
#include "render/distribution.h"

namespace spangle {

/** Which estimators the path tracer combines (NEE = next-event estimation). */
enum class Strategy {
    Mis,      ///< NEE and BSDF sampling, power heuristic (the default)
    NeeOnly,  ///< emitters count only through NEE (and through delta bounces)
    BsdfOnly  ///< emitters count only when BSDF-sampled rays hit them (delta lights still NEE)
};

/** The power heuristic (beta = 2) weight of a sample from the strategy with pdf a against b. */
float power_heuristic(float a, float b);

/** Weight of emission that a BSDF-sampled ray found, given the light-sampling pdf of the same
 *  point: the power heuristic, or the pure strategies' 0 / 1; always 1 after a delta bounce. */
float bsdf_hit_weight(Strategy strategy, bool after_delta, float bsdf_pdf, float light_pdf);

/** The images of textured area emitters (an emissive mesh whose emission is an image): image
 *  `index`'s colour at surface uv (u, v). Thread-safe; throws nothing. */
class EmissionImages {
public:
    virtual ~EmissionImages() = default;
    virtual Vec3 at(uint32_t index, float u, float v) const = 0;
};

/** One planar emitter: a triangle (p0, p0+e1, p0+e2) or a parallelogram (p0 + s e1 + t e2). */
struct AreaEmitter {
    Vec3 p0, e1, e2;    ///< world space
    Vec3 n;             ///< unit normal of the emitting side
    float area = 0.0f;  ///< m^2
    Vec3 radiance;      ///< working-space RGB, W/(m^2 sr) (times its image's colour, if any)
    /** A triangle's emission image (EmissionImages), -1 for none, with its corners' uvs (u0, v0,
     *  u1, v1, u2, v2), and the image's mean over the triangle (luminance), which weighs its
     *  power for light selection. */
    int32_t image = -1;
    float uv[6] = {0, 0, 0, 0, 0, 0};
    float image_mean = 1.0f;
    bool parallelogram = false;
    bool two_sided = false;
    bool transparent = false;  ///< a quad that lets every ray through (QuadLight::transparent)
    uint32_t group = 0;        ///< light group (render layers)
};

/** A spherical emitter. */
struct SphereEmitter {
    Vec3 center;
    float radius = 0.0f;
    Vec3 radiance;
    uint32_t group = 0;
};

/** A point or spot light. */
struct PointEmitter {
    Vec3 position;
    Vec3 intensity;           ///< W/sr, working-space RGB
    Vec3 axis{0, -1, 0};      ///< spot: unit direction of the cone
    float cos_outer = -1.0f;  ///< spot: no light beyond this angle (-1: a point light)
    float cos_inner = -1.0f;  ///< spot: full intensity within this angle
    uint32_t group = 0;
    bool quartic = false;  ///< spot: fades as t^4 (pbrt-v3), else smoothstep (pbrt-v4)
};

/** A light at infinity. */
struct DistantEmitter {
    Vec3 direction;            ///< unit, from the scene towards the light
    Vec3 radiance;             ///< disk: radiance; delta: irradiance (W/m^2)
    float cos_radius = 1.0f;   ///< cosine of the angular radius; 1 = delta
    float solid_angle = 0.0f;  ///< 2 pi (1 - cos r), computed stably; 0 = delta
    uint32_t group = 0;
};

/** A lat-long environment map in the working space. */
class EnvironmentMap {
public:
    /** rgb: width x height RGB, row 0 = up (+y). rotation_deg turns the map about +y (90 takes
     *  its centre from -z to +x). With another projection, `to_map` (a rotation) takes world
     * directions into the map's frame and rotation_deg is unused. */
    EnvironmentMap(std::vector<float> rgb, int width, int height, float rotation_deg,
                   MapProjection projection = MapProjection::LatLongYUp, const Affine& to_map = {});
    EnvironmentMap() = default;

    bool empty() const { return width_ == 0; }
    /** Radiance arriving from direction d (unit, world space). */
    Vec3 eval(Vec3 d) const;
    /** Direction with solid-angle pdf; pdf 0 when the map is black. */
    Vec3 sample(float u0, float u1, float& pdf) const;
    /** Solid-angle pdf of sample() for direction d. */
    float pdf(Vec3 d) const;
    /** Integral of luminance over the sphere, for light selection by power. */
    double luminance_integral() const { return lum_integral_; }

private:
    void to_uv(Vec3 d, float& u, float& v) const;
    Vec3 from_uv(float u, float v) const;
    /** The solid angle of a unit of uv area at direction d over 4 pi^2 sin(theta) (lat-long) or
     *  4 pi (equal area): the Jacobian that turns a uv pdf into a solid-angle pdf. */
    float uv_to_solid(Vec3 d) const;

    int width_ = 0, height_ = 0;
    std::vector<float> rgb_;
    float cos_rot_ = 1.0f, sin_rot_ = 0.0f;
    MapProjection projection_ = MapProjection::LatLongYUp;
    Affine to_map_;                     ///< world to the map's frame (pbrt's projections)
    Distribution1D rows_;               ///< marginal over rows
    std::vector<Distribution1D> cols_;  ///< conditional over columns, per row
    double lum_integral_ = 0.0;
};

/** A light sample seen from a reference point. */
struct LightSample {
    Vec3 wi;            ///< unit direction from the reference point to the light
    float dist = 0.0f;  ///< distance to the sampled point; infinity for lights at infinity
    Vec3 radiance;      ///< radiance (or, for delta lights, irradiance-like value) arriving
    float pdf = 0.0f;  ///< solid-angle pdf with selection; delta lights: selection pmf; 0 = invalid
    bool delta = false;  ///< a delta light: no MIS with BSDF sampling
    uint32_t group = 0;  ///< the sampled light's light group
    /** An area emitter's triangle (not a parallelogram): its index and the point's
     *  barycentrics (p0 + b1 e1 + b2 e2); -1 for every other light. */
    int32_t area = -1;
    float b1 = 0.0f, b2 = 0.0f;
};

/** The frame's lights. Build with add_*, then finalize(). */
class LightTable {
public:
    uint32_t add_area(const AreaEmitter& e);
    uint32_t add_sphere(const SphereEmitter& e);
    void add_point(const PointEmitter& e);
    void add_distant(const DistantEmitter& e);
    /** The environment map (shared with whoever built it; null or empty: none). */
    void set_environment(std::shared_ptr<const EnvironmentMap> env, uint32_t group = 0);
    /** Builds the selection distribution; scene_radius sizes the power of lights at infinity. */
    void finalize(float scene_radius);

    /** True when next-event estimation has nothing to sample. */
    bool empty() const { return selection_.empty(); }
    std::size_t area_count() const { return area_.size(); }
    std::size_t sphere_count() const { return spheres_.size(); }
    const AreaEmitter& area(uint32_t i) const { return area_[i]; }
    const SphereEmitter& sphere(uint32_t i) const { return spheres_[i]; }

    /** Samples one light for reference point p with uniforms u0 (selection), u1, u2. */
    LightSample sample(Vec3 p, float u0, float u1, float u2) const;

    /** The images of textured area emitters (null: none). */
    void set_images(std::shared_ptr<const EmissionImages> images) { images_ = std::move(images); }
    /** Radiance of area emitter i towards w (unit, pointing away from the light), at
     *  barycentrics (b1, b2) of a triangle (where its image, if any, is read). */
    Vec3 area_emitted(uint32_t i, Vec3 w, float b1 = 0.0f, float b2 = 0.0f) const;
    /** Solid-angle pdf that sample() picks point q on area emitter i from p. */
    float area_pdf(uint32_t i, Vec3 p, Vec3 q) const;
    /** Solid-angle pdf that sample() picks sphere i from p. */
    float sphere_pdf(uint32_t i, Vec3 p) const;
    /** Radiance arriving along an escaped ray from env map and sun disks, each weighted by the
     *  power heuristic against light sampling (weight 1 after a delta bounce). by_group, when
     *  not null, receives each light's part added at its light group's index. */
    Vec3 escaped(Vec3 d, float bsdf_pdf, bool after_delta, Strategy strategy = Strategy::Mis,
                 Vec3* by_group = nullptr) const;

private:
    /** A point on area emitter id seen from p, with selection pmf sel. */
    LightSample sample_area(uint32_t id, Vec3 p, float sel, float u1, float u2) const;

    std::vector<AreaEmitter> area_;
    std::vector<SphereEmitter> spheres_;
    std::vector<PointEmitter> points_;
    std::vector<DistantEmitter> distant_;
    std::shared_ptr<const EnvironmentMap> env_;  ///< null: no map
    std::shared_ptr<const EmissionImages> images_;
    uint32_t env_group_ = 0;
    Distribution1D selection_;  ///< over [area..., spheres..., points..., distant..., env]
};

/** Solid angle of triangle (a, b, c) seen from p (Van Oosterom and Strackee 1983). */
double triangle_solid_angle(Vec3 p, Vec3 a, Vec3 b, Vec3 c);

/** Whether area emitters are sampled by solid angle from p (the same test in sample and pdf). */
bool use_solid_angle_sampling(double solid_angle);

}  // namespace spangle
