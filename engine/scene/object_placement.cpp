#include "scene/object_placement.h"

#include <algorithm>
#include <cmath>

namespace spangle {

namespace {

/** The most a placement's matrix, or its inverse, may scale: beyond, rays carried into the
 *  object's space leave the range Embree accepts. */
constexpr float kMaxPlacementScale = 1e12f;

}  // namespace

Affine compose_parts(const TransformParts& p) {
    Affine m = Affine::scale(p.scale);
    m = Affine::rotate(p.rotate.x, {1, 0, 0}).compose(m);
    m = Affine::rotate(p.rotate.y, {0, 1, 0}).compose(m);
    m = Affine::rotate(p.rotate.z, {0, 0, 1}).compose(m);
    return Affine::translate(p.translate).compose(m);
}

Affine matrix_of(const PlacementDesc& p) {
    return p.matrix ? *p.matrix : compose_parts(p.parts);
}

KeyedMotion<Affine> placement_motion(const ObjectDesc& d, int64_t frame_start, double fps,
                                     const Shutter& shutter) {
    if (!d.matrix_keys.keys.empty()) {
        if (!d.keys.keys.empty())
            throw_error(d.keys.loc, "{}: keys of its parts and keys of its matrix at once", d.what);
        return matrix_motion(d.matrix_keys, frame_start, fps, shutter);
    }
    if (d.keys.keys.empty()) return {matrix_of(d.placement), {}};
    if (d.placement.matrix)
        throw_error(d.keys.loc,
                    "{}: keys move scale, rotate and translate, but it is placed by "
                    "a matrix",
                    d.what);
    const TransformParts& base = d.placement.parts;
    const Track track = key_track(d.keys, frame_start, fps, [&](const ObjectKey& k) {
        const TransformParts p{k.scale.value_or(base.scale), k.rotate.value_or(base.rotate),
                               k.translate.value_or(base.translate)};
        return std::vector<double>{p.scale.x,     p.scale.y,     p.scale.z,
                                   p.rotate.x,    p.rotate.y,    p.rotate.z,
                                   p.translate.x, p.translate.y, p.translate.z};
    });
    const auto make = [&](const std::vector<double>& v, double t) {
        const auto f = [&](std::size_t j) { return static_cast<float>(v[j]); };
        const TransformParts now{{f(0), f(1), f(2)}, {f(3), f(4), f(5)}, {f(6), f(7), f(8)}};
        for (std::size_t a = 0; a < 3; ++a)
            if (!(std::fabs(f(a)) >= 1e-8f))
                throw_error(d.keys.loc,
                            "{}: the keyframed scale passes through 0 at {} s (the object would "
                            "vanish into a plane)",
                            d.what, t);
        return compose_parts(now);
    };
    return keyed_motion<Affine>(track, shutter, make);
}

void check_placement(const ObjectDesc& d, const Affine& m, bool moving) {
    // Rays are carried into object space through the inverse: a placement that squashes an
    // axis to almost nothing (1e-20 in a matrix, a Python scale) sent rays Embree refuses, and
    // the render aborted in its assertion.
    const Affine inv = m.inverse();
    float big = 0.0f, big_inv = 0.0f;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
            big = std::max(big, std::fabs(m.m[r][c]));
            big_inv = std::max(big_inv, std::fabs(inv.m[r][c]));
        }
    // Axes nearly parallel: the determinant, a difference of products of the entries, is
    // lost in their float rounding (rows [1,1,1], [1,1,1.0001], [1,1.0001,1]: 1e-8 against
    // products of 1), so the float inverse Embree makes is off or not finite whatever ours
    // is (the render aborted). A still object is traced through its mesh placed in world
    // space in double instead (EmbreeScene), whatever the share; a moving one's placements
    // are blended by Embree through the shutter, so they must keep 1e-5 of it (the float
    // determinant then within about 1%). A scale, a rotation or a shear, however strong,
    // keeps the two equal or close.
    const double share = m.determinant_share();
    if (moving && std::isfinite(share) && share < 1e-5)
        throw_error(d.loc,
                    "{}: its placement's axes are nearly parallel while it moves (its "
                    "matrix's determinant is {:.3g} of the size of the products it is the "
                    "difference of; at least 1e-5 is needed for rays to follow a moving "
                    "object): it flattens the object almost into a plane or a line",
                    d.what, share);
    if (!(big <= kMaxPlacementScale && big_inv <= kMaxPlacementScale) ||
        !std::isfinite(m.determinant()))
        throw_error(d.loc,
                    "{}: its placement squashes or stretches it beyond what rays can follow "
                    "(its matrix's largest entry {:.3g}, its inverse's {:.3g}; both must stay "
                    "within {:g}: keep every axis's scale between 1e-12 and 1e12)",
                    d.what, big, big_inv, kMaxPlacementScale);
}

}  // namespace spangle
