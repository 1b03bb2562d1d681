#pragma once
// Area lights: emissive mesh triangles and quads, in world space, chosen by power and sampled
// uniformly by area (solid-angle sampling of triangles is a later improvement).

#include <cstdint>
#include <vector>

#include "core/math.h"
#include "render/distribution.h"

namespace spangle {

/** One planar emitter: a triangle (p0, p0+e1, p0+e2) or a parallelogram (p0 + s e1 + t e2). */
struct AreaEmitter {
    Vec3 p0, e1, e2;    ///< world space
    Vec3 n;             ///< unit normal, emitting side (e1 x e2 direction)
    float area = 0.0f;  ///< m^2
    Vec3 radiance;      ///< working-space RGB, W/(m^2 sr)
    bool parallelogram = false;
    bool two_sided = false;
};

/** A light sample seen from a reference point. */
struct LightSample {
    Vec3 wi;            ///< unit direction from the reference point to the light
    float dist = 0.0f;  ///< distance to the sampled point
    Vec3 radiance;      ///< emitted radiance towards the reference point
    float pdf = 0.0f;   ///< solid-angle pdf, selection included; 0 = invalid
};

/** All area emitters and their selection distribution. */
class LightTable {
public:
    /** Adds an emitter; call finalize() once after the last one. */
    void add(const AreaEmitter& e) { emitters_.push_back(e); }
    /** Builds the power distribution. */
    void finalize();

    bool empty() const { return selection_.empty(); }
    std::size_t size() const { return emitters_.size(); }
    const AreaEmitter& emitter(uint32_t i) const { return emitters_[i]; }

    /** Samples a light point for reference point p with uniform numbers u0 (selection), u1, u2. */
    LightSample sample(Vec3 p, float u0, float u1, float u2) const;
    /** Solid-angle pdf that sample() picks point q on emitter i, seen from p. */
    float pdf(uint32_t i, Vec3 p, Vec3 q) const;
    /** Radiance leaving emitter i towards direction w (unit, pointing away from the light). */
    Vec3 emitted(uint32_t i, Vec3 w) const;

private:
    std::vector<AreaEmitter> emitters_;
    Distribution1D selection_;
};

}  // namespace spangle
