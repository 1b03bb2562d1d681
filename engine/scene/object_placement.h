#pragma once
// An object's placement: its parts (scale, rotation, offset) or its matrix as one transform, its
// motion through a frame's shutter from its keys, and the check that rays can follow it.

#include <cstdint>

#include "core/math.h"
#include "scene/keyed_motion.h"
#include "scene/scene_description.h"

namespace spangle {

/** Placement parts as one transform: scale, then Euler angles (degrees) about X, then Y, then
 *  Z, then translation. */
Affine compose_parts(const TransformParts& p);

/** A placement as one transform: its matrix, or its parts composed. */
Affine matrix_of(const PlacementDesc& p);

/** An object's placement through the shutter (its keys at `frame_start` and `fps`); each key's
 *  parts default to the object's own. Throws at the keys for parts and matrix keys at once, or
 *  keys of parts on an object placed by a matrix, or a keyed scale through 0. */
KeyedMotion<Affine> placement_motion(const ObjectDesc& d, int64_t frame_start, double fps,
                                     const Shutter& shutter);

/** Throws at the object when rays cannot follow placement `m` (one of its steps through the
 *  shutter when `moving`): a scale beyond 1e12 either way, or, while it moves, axes so nearly
 *  parallel that Embree's float inverse is lost. */
void check_placement(const ObjectDesc& d, const Affine& m, bool moving);

}  // namespace spangle
