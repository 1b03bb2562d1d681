#pragma once
// How an environment image wraps the sphere of directions.

#include <cstdint>

namespace spangle {

/** The layout of an environment map. */
enum class MapProjection : uint8_t {
    LatLongYUp,  ///< Spangle's: row 0 = +y, u = 0.5 looks down -z (then turned about +y)
    LatLongZUp,  ///< pbrt-v3's: row 0 = +z of the map's frame, u = atan2(y, x) / 2 pi
    EqualArea,   ///< pbrt-v4's square equal-area octahedral map (Clarberg 2008), map frame
};

}  // namespace spangle
