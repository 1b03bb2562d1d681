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
    std::vector<float> colors;       ///< linear rgb per vertex, or empty
    std::string source;              ///< file, for messages
    /** Faces orient_cage() turned to agree with their neighbours (for the load's warning). */
    std::size_t turned_faces = 0;

    std::size_t vertex_count() const { return positions.size() / 3; }
    std::size_t face_count() const { return face_sizes.size(); }
};

/** Calls edge(face, a, b) for every edge of every face, a then b in the face's winding. */
template <class Edge>
void for_each_edge(const Cage& cage, Edge&& edge) {
    std::size_t at = 0;
    for (std::size_t f = 0; f < cage.face_count(); ++f) {
        const auto n = static_cast<std::size_t>(cage.face_sizes[f]);
        for (std::size_t k = 0; k < n; ++k)
            edge(f, cage.face_vertices[at + k], cage.face_vertices[at + (k + 1) % n]);
        at += n;
    }
}

/** A hash of a cage's positions, faces, uvs and colours (not its source name): equal for equal
 * content. */
uint64_t cage_content_hash(const Cage& cage);

/** Same positions, faces, uvs and colours. */
bool same_cage_content(const Cage& a, const Cage& b);

/** Winds every face as its neighbours are wound (OpenSubdiv takes an edge two faces cross the
 *  same way as a seam: a reversed face stayed a flat, sharp-edged panel on a rounded body).
 *  Per connected piece (faces joined by edges of exactly two faces), the winding most of its
 *  faces have is kept and the rest turned (corners reversed, uvs with them). Returns how many
 *  faces were turned; a piece that cannot be wound one way (a Moebius strip) keeps what it can. */
std::size_t orient_cage(Cage& cage);

/** Loads an OBJ cage without triangulating it; validates it (see validate_cage) and winds its
 *  faces one way (orient_cage, counted in turned_faces). */
Cage load_cage(const std::string& path, const FileLoc& ref);

/** Checks a cage: finite positions, at least one face, faces of >= 3 corners, indices in range,
 *  no vertex twice in one face, uv indices given for every corner or none. Unreferenced
 *  vertices are allowed (they do not move the surface). Throws SpangleError naming the face or
 *  vertex and, through `ref`, the scene line. */
void validate_cage(const Cage& cage, const FileLoc& ref);

}  // namespace spangle
