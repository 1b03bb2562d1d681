#pragma once
// Control cages for subdivision surfaces: polygons (triangles, quads, n-gons) with a separate
// face-varying uv index per face corner, so that uv seams stay seams and the cage stays one
// connected surface.

#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"

namespace spangle {

/** A polygonal cage in object space. */
struct Cage {
    std::vector<float> positions;    ///< xyz per vertex
    std::vector<int> face_sizes;     ///< corners of each face (>= 3)
    std::vector<int> face_vertices;  ///< vertex index per corner
    std::vector<float> uvs;          ///< uv per face-varying value (may be empty)
    std::vector<int> face_uvs;       ///< uv index per corner (empty when uvs is)
    std::string source;              ///< file, for messages

    std::size_t vertex_count() const { return positions.size() / 3; }
    std::size_t face_count() const { return face_sizes.size(); }
};

/** A hash of a cage's positions, faces and uvs (not its source name): equal for equal content. */
uint64_t cage_content_hash(const Cage& cage);

/** Same positions, faces and uvs. */
bool same_cage_content(const Cage& a, const Cage& b);

/** Loads an OBJ cage without triangulating it; validates it (see validate_cage). */
Cage load_cage(const std::string& path, const FileLoc& ref);

/** Checks a cage: finite positions, at least one face, faces of >= 3 corners, indices in range,
 *  no vertex twice in one face, uv indices given for every corner or none. Unreferenced
 *  vertices are allowed (they do not move the surface). Throws SpangleError naming the face or
 *  vertex and, through `ref`, the scene line. */
void validate_cage(const Cage& cage, const FileLoc& ref);

}  // namespace spangle
