#pragma once
// Flake facets (flake_size): where a pixel's footprint is not much larger than a flake, each flake
// is a flat mirror with an outline (a regular hexagon, a square or a disc) rather than a point.
// A flake then counts towards a footprint by the share of its outline inside the footprint, so a
// footprint inside one facet sees that facet alone (a flat mirror with sharp edges), one across a
// facet's edge sees it partly, and a footprint much larger than the facets counts each flake by
// whether it is inside, as the point model does: the look passes continuously from facets to
// sparkle as the footprint grows. The share is monotone in the footprint (a footprint inside
// another sees at most its shares), and its mean over footprint positions is exactly the point
// model's count (a facet's area is counted once, wherever it falls).

#include <cstdint>

namespace spangle::flake {

struct Footprint;

/** The outline kinds of flake_shape. */
enum class FacetKind { Hexagon, Square, Round };

/** A facet's outline at unit width, centred on the flake's position: a convex polygon,
 *  counter-clockwise. Width is flat to flat for the hexagon, the side for the square and the
 *  diameter for the disc (a 32-gon, whose own area is the one used). */
struct FacetShape {
    static constexpr int kMaxVertices = 32;
    int n = 0;                    ///< vertices
    double x[kMaxVertices] = {};  ///< outline at unit width
    double y[kMaxVertices] = {};
    double radius = 0;  ///< circumradius at unit width (how far a facet reaches from its centre)
    double area = 0;    ///< area at unit width
    explicit FacetShape(FacetKind kind);
};

/** The share in [0, 1] of the facet of the flake at (u, v) (`size` wide in P's plane, turned
 *  by an angle drawn from the flake's hash `id`) that lies inside footprint P. 0 when P is
 *  singular. */
float facet_coverage(const Footprint& p, const FacetShape& shape, double size, double u, double v,
                     uint64_t id);

}  // namespace spangle::flake
