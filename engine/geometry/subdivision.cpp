#include "geometry/subdivision.h"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <set>
#include <unordered_map>

#include "core/memory.h"

namespace spangle {

namespace {

namespace Far = OpenSubdiv::Far;
namespace Sdc = OpenSubdiv::Sdc;

/** A primvar OpenSubdiv can interpolate: N floats. */
template <int N>
struct Primvar {
    float v[N];
    void Clear() {
        for (float& x : v) x = 0.0f;
    }
    void AddWithWeight(const Primvar& s, float w) {
        for (int i = 0; i < N; ++i) v[i] += w * s.v[i];
    }
};
using P3 = Primvar<3>;
using P2 = Primvar<2>;

/** OpenSubdiv reports errors through a global callback; the messages are collected here while
 *  one refinement runs (the mutex serialises refinements, which only the subdivide system does). */
std::mutex g_osd_mutex;
std::string g_osd_error;
void on_osd_error(Far::ErrorType, const char* message) {
    if (g_osd_error.empty()) g_osd_error = message ? message : "unknown OpenSubdiv error";
}
void on_osd_warning(const char*) {}

}  // namespace

double subdivided_triangles(const Cage& cage, const SubdivOptions& o) {
    double triangles = 0.0;
    const double per_level = std::pow(4.0, std::max(0, o.level - 1));
    for (int n : cage.face_sizes) {
        if (o.level == 0)
            triangles += n - 2;  // fan-triangulated cage faces
        else if (o.scheme == SubdivOptions::Scheme::Loop)
            triangles += 4.0 * per_level;
        else
            triangles += 2.0 * n * per_level;  // n quads after the first level, 4x per level
    }
    return triangles;
}

void check_subdivision_memory(const Cage& cage, const SubdivOptions& o, bool from_camera,
                              const FileLoc& ref) {
    // Measured on the snowman body at levels 5 to 7: the peak grows by 265-271 bytes per
    // triangle (refiner, limit points, the mesh and Embree's BVH).
    constexpr double kBytesPerTriangle = 300.0;
    const double triangles = subdivided_triangles(cage, o);
    const double need = triangles * kBytesPerTriangle;
    const char* lower =
        from_camera ? "lower subdiv.max_level or raise subdiv.pixel_budget" : "lower subdiv.level";
    if (3.0 * triangles > 4294967295.0)
        throw_error(ref,
                    "subdividing '{}' ({} cage faces) at level {} would make {:.0f} triangles, "
                    "more than 32-bit indices can number: {}",
                    cage.source, cage.face_count(), o.level, triangles, lower);
    if (const uint64_t have = memory_short_for(need))
        throw_error(ref,
                    "subdividing '{}' ({} cage faces) at level {} would make {:.0f} triangles and "
                    "need about {}, but only {} of memory is available: {}",
                    cage.source, cage.face_count(), o.level, triangles, format_bytes(need),
                    format_bytes(static_cast<double>(have)), lower);
}

int level_for_camera(double longest, double distance, double pixel_angle, double budget,
                     int max_level) {
    const double pixels = longest / (std::max(distance, 1e-6) * pixel_angle);
    if (!(pixels > budget)) return 0;
    const double level = std::ceil(std::log2(pixels / budget));
    // Compared as a double: an infinite or huge ratio must not reach a cast to int.
    return level >= max_level ? max_level : std::max(0, static_cast<int>(level));
}

double longest_edge(const Cage& cage, const Affine& xf) {
    double longest = 0.0;
    std::size_t at = 0;
    const auto p = [&](int i) {
        const auto k = static_cast<std::size_t>(i) * 3;
        return xf.apply_point({cage.positions[k], cage.positions[k + 1], cage.positions[k + 2]});
    };
    for (int n : cage.face_sizes) {
        for (int k = 0; k < n; ++k) {
            const Vec3 a = p(cage.face_vertices[at + static_cast<std::size_t>(k)]);
            const Vec3 b = p(cage.face_vertices[at + static_cast<std::size_t>((k + 1) % n)]);
            longest = std::max(longest, static_cast<double>(length(b - a)));
        }
        at += static_cast<std::size_t>(n);
    }
    return longest;
}

/** Shares of subdivide()'s time, for its progress (measured on the beetle's body at level 7,
 *  2.6 M triangles: 3 s, 2 + 2 s, 6 s, then 2 s for the normals): the topology's refinement,
 *  the positions' and uvs' interpolation to the limit (half each), the triangles. */
constexpr double kTopologyShare = 0.2, kLimitShare = 0.3, kTriangleShare = 0.37;

TriangleMesh subdivide(const Cage& cage, const SubdivOptions& o, const FileLoc& ref,
                       const WorkProgress& progress, const std::string& what) {
    const auto report = [&](double fraction) {
        if (progress) progress(what, fraction);
    };
    report(0.0);
    const auto nv = static_cast<int>(cage.vertex_count());
    for (int v : o.crease_vertices)
        if (v < 0 || v >= nv)
            throw_error(ref, "crease names cage vertex {}, but '{}' has {} vertices", v,
                        cage.source, nv);
    for (int v : o.corner_vertices)
        if (v < 0 || v >= nv)
            throw_error(ref, "corner names cage vertex {}, but '{}' has {} vertices", v,
                        cage.source, nv);
    // A crease on two vertices that share no edge creases nothing (OpenSubdiv drops it): the
    // numbers were probably an OBJ's f-line ones, which count from 1.
    if (!o.crease_vertices.empty()) {
        std::set<std::pair<int, int>> edges;
        for_each_edge(cage, [&](std::size_t, int a, int b) {
            edges.emplace(std::min(a, b), std::max(a, b));
        });
        for (std::size_t i = 0; i + 1 < o.crease_vertices.size(); i += 2) {
            const int a = o.crease_vertices[i], b = o.crease_vertices[i + 1];
            if (!edges.count({std::min(a, b), std::max(a, b)}))
                throw_error(
                    ref,
                    "crease [{}, {}]: {} of '{}' (vertices count from 0, where an OBJ's "
                    "f lines count from 1)",
                    a, b,
                    a == b ? "names one vertex twice" : "those vertices share no edge of the cage",
                    cage.source);
        }
    }
    const bool loop = o.scheme == SubdivOptions::Scheme::Loop;
    if (loop)
        for (std::size_t f = 0; f < cage.face_count(); ++f)
            if (cage.face_sizes[f] != 3)
                throw_error(
                    ref,
                    "the Loop scheme needs a triangle cage, but face {} of '{}' has {} corners", f,
                    cage.source, cage.face_sizes[f]);

    Sdc::Options sdc;
    sdc.SetVtxBoundaryInterpolation(o.boundary == SubdivOptions::Boundary::None
                                        ? Sdc::Options::VTX_BOUNDARY_NONE
                                    : o.boundary == SubdivOptions::Boundary::EdgeOnly
                                        ? Sdc::Options::VTX_BOUNDARY_EDGE_ONLY
                                        : Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    switch (o.uv_interpolation) {
        case SubdivOptions::UvInterpolation::Smooth:
            sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_NONE);
            break;
        case SubdivOptions::UvInterpolation::CornersOnly:
            sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_CORNERS_ONLY);
            break;
        case SubdivOptions::UvInterpolation::Boundaries:
            sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_BOUNDARIES);
            break;
        case SubdivOptions::UvInterpolation::All:
            sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_ALL);
            break;
    }

    Far::TopologyDescriptor desc;
    desc.numVertices = nv;
    desc.numFaces = static_cast<int>(cage.face_count());
    desc.numVertsPerFace = cage.face_sizes.data();
    desc.vertIndicesPerFace = cage.face_vertices.data();
    desc.numCreases = static_cast<int>(o.crease_sharpness.size());
    desc.creaseVertexIndexPairs = o.crease_vertices.data();
    desc.creaseWeights = o.crease_sharpness.data();
    desc.numCorners = static_cast<int>(o.corner_sharpness.size());
    desc.cornerVertexIndices = o.corner_vertices.data();
    desc.cornerWeights = o.corner_sharpness.data();
    const bool has_uv = !cage.face_uvs.empty();
    Far::TopologyDescriptor::FVarChannel channel;
    if (has_uv) {
        channel.numValues = static_cast<int>(cage.uvs.size() / 2);
        channel.valueIndices = cage.face_uvs.data();
        desc.numFVarChannels = 1;
        desc.fvarChannels = &channel;
    }

    std::lock_guard<std::mutex> lock(g_osd_mutex);
    g_osd_error.clear();
    Far::SetErrorCallback(on_osd_error);
    Far::SetWarningCallback(on_osd_warning);
    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    std::unique_ptr<Far::TopologyRefiner> refiner(Factory::Create(
        desc, Factory::Options(loop ? Sdc::SCHEME_LOOP : Sdc::SCHEME_CATMARK, sdc)));
    if (!refiner || !g_osd_error.empty())
        throw_error(ref, "OpenSubdiv rejects the cage '{}': {}", cage.source,
                    g_osd_error.empty() ? "no reason given" : g_osd_error);
    Far::TopologyRefiner::UniformOptions uniform(o.level);
    uniform.fullTopologyInLastLevel = true;  // Limit() needs the last level's full topology
    refiner->RefineUniform(uniform);
    report(kTopologyShare);
    if (!g_osd_error.empty())
        throw_error(ref, "OpenSubdiv cannot refine '{}': {}", cage.source, g_osd_error);

    // OpenSubdiv sizes its per-vertex weight buffers by a level's largest valence (edges at a
    // vertex), with a fixed minimum, and writes one weight per incident face. Faces stacked on
    // the same edges (repeated faces, fans over one edge) give a vertex more faces than that:
    // refining from such a level overflows the buffers (found by the fuzzer), so it is refused;
    // at the last level it would only corrupt the limit masks, so those vertices are left at
    // their refined positions, with normals from the refined faces.
    bool stacked_last = false;
    for (int level = 0; level <= o.level; ++level) {
        const Far::TopologyLevel& t = refiner->GetLevel(level);
        int max_valence = 0;
        for (int v = 0; v < t.GetNumVertices(); ++v)
            max_valence = std::max(max_valence, t.GetVertexEdges(v).size());
        for (int v = 0; v < t.GetNumVertices(); ++v) {
            const int faces = t.GetVertexFaces(v).size(), edges = t.GetVertexEdges(v).size();
            if (level == o.level) {
                stacked_last = stacked_last || faces > max_valence;
            } else if (faces > std::max(16, max_valence) ||
                       faces + edges > std::max(32, 2 * max_valence)) {
                throw_error(ref,
                            "cage '{}' has too many faces stacked on the same edges (after {} "
                            "level{} of refinement a vertex lies on {} faces but has {} edges): "
                            "remove repeated or overlapping faces",
                            cage.source, level, level == 1 ? "" : "s", faces, edges);
            }
        }
    }

    // A vertex value (xyz per cage vertex) through every level: the values of all levels, and
    // where the last level's begin.
    Far::PrimvarRefiner primvar(*refiner);
    const auto refine_vertex_value = [&](const std::vector<float>& per_cage_vertex,
                                         std::vector<P3>& all) {
        all.assign(static_cast<std::size_t>(refiner->GetNumVerticesTotal()), P3{});
        for (int i = 0; i < nv; ++i)
            for (int c = 0; c < 3; ++c)
                all[static_cast<std::size_t>(i)].v[c] =
                    per_cage_vertex[static_cast<std::size_t>(3 * i + c)];
        P3* at = all.data();
        for (int level = 1; level <= o.level; ++level) {
            P3* next = at + refiner->GetLevel(level - 1).GetNumVertices();
            primvar.Interpolate(level, at, next);
            at = next;
        }
        return at;
    };
    // Positions, then to the limit with tangents.
    std::vector<P3> verts;
    P3* src = refine_vertex_value(cage.positions, verts);
    const Far::TopologyLevel& last = refiner->GetLevel(o.level);
    const auto n_last = static_cast<std::size_t>(last.GetNumVertices());
    std::vector<P3> limit(n_last), du(n_last), dv(n_last);
    if (stacked_last)
        std::copy(src, src + n_last, limit.begin());  // zero tangents: face normals below
    else
        primvar.Limit(src, limit, du, dv);

    // Vertex colours as positions are refined (a vertex primvar), to the limit.
    std::vector<P3> color_limit;
    if (!cage.colors.empty()) {
        std::vector<P3> colors;
        P3* cs = refine_vertex_value(cage.colors, colors);
        color_limit.resize(n_last);
        if (stacked_last)
            std::copy(cs, cs + n_last, color_limit.begin());
        else
            primvar.Limit(cs, color_limit);
    }

    report(kTopologyShare + kLimitShare * 0.5);
    std::vector<P2> uv_limit;
    if (has_uv) {
        std::vector<P2> uvs(static_cast<std::size_t>(refiner->GetNumFVarValuesTotal(0)));
        for (std::size_t i = 0; i < cage.uvs.size() / 2; ++i)
            uvs[i] = {{cage.uvs[2 * i], cage.uvs[2 * i + 1]}};
        P2* s = uvs.data();
        for (int level = 1; level <= o.level; ++level) {
            P2* d = s + refiner->GetLevel(level - 1).GetNumFVarValues(0);
            primvar.InterpolateFaceVarying(level, s, d, 0);
            s = d;
        }
        uv_limit.resize(static_cast<std::size_t>(last.GetNumFVarValues(0)));
        if (stacked_last)
            std::copy(s, s + uv_limit.size(), uv_limit.begin());
        else
            primvar.LimitFaceVarying(s, uv_limit, 0);
    }
    if (!g_osd_error.empty())
        throw_error(ref, "OpenSubdiv failed on '{}': {}", cage.source, g_osd_error);

    // Triangles over (vertex, uv value) pairs: a vertex on a uv seam is split, its position and
    // normal shared, so the surface stays closed and its shading continuous across the seam.
    TriangleMesh mesh;
    mesh.source = cage.source;
    std::unordered_map<uint64_t, uint32_t> index_of;
    std::vector<Vec3> face_normal_sum(n_last);
    const auto corner = [&](int v, int t) -> uint32_t {
        const uint64_t key =
            (static_cast<uint64_t>(static_cast<uint32_t>(v)) << 32) | static_cast<uint32_t>(t);
        auto [it, fresh] = index_of.emplace(key, static_cast<uint32_t>(mesh.vertex_count()));
        if (fresh) {
            const P3& p = limit[static_cast<std::size_t>(v)];
            mesh.positions.insert(mesh.positions.end(), {p.v[0], p.v[1], p.v[2]});
            const Vec3 n = cross(
                Vec3(du[static_cast<std::size_t>(v)].v[0], du[static_cast<std::size_t>(v)].v[1],
                     du[static_cast<std::size_t>(v)].v[2]),
                Vec3(dv[static_cast<std::size_t>(v)].v[0], dv[static_cast<std::size_t>(v)].v[1],
                     dv[static_cast<std::size_t>(v)].v[2]));
            mesh.normals.insert(mesh.normals.end(), {n.x, n.y, n.z});
            if (has_uv)
                mesh.uvs.insert(mesh.uvs.end(), {uv_limit[static_cast<std::size_t>(t)].v[0],
                                                 uv_limit[static_cast<std::size_t>(t)].v[1]});
            if (!color_limit.empty()) {
                // The limit of non-negative colours can undershoot 0 a little (the scheme's
                // weights are not all positive at creases): clamped.
                const P3& c = color_limit[static_cast<std::size_t>(v)];
                for (int k = 0; k < 3; ++k) mesh.colors.push_back(std::max(c.v[k], 0.0f));
            }
        }
        return it->second;
    };
    report(kTopologyShare + kLimitShare);
    const int last_faces = last.GetNumFaces();
    for (int f = 0; f < last_faces; ++f) {
        if ((f & 0x3fff) == 0x3fff)
            report(kTopologyShare + kLimitShare +
                   kTriangleShare * static_cast<double>(f) / static_cast<double>(last_faces));
        const Far::ConstIndexArray fv = last.GetFaceVertices(f);
        const Far::ConstIndexArray ft = has_uv ? last.GetFaceFVarValues(f, 0) : fv;
        const auto tri = [&](int a, int b, int c) {
            mesh.indices.insert(mesh.indices.end(), {corner(fv[a], has_uv ? ft[a] : 0),
                                                     corner(fv[b], has_uv ? ft[b] : 0),
                                                     corner(fv[c], has_uv ? ft[c] : 0)});
            const auto pos = [&](int k) {
                const P3& p = limit[static_cast<std::size_t>(fv[k])];
                return Vec3(p.v[0], p.v[1], p.v[2]);
            };
            const Vec3 n = cross(pos(b) - pos(a), pos(c) - pos(a));
            for (int k : {a, b, c}) face_normal_sum[static_cast<std::size_t>(fv[k])] += n;
        };
        for (int k = 1; k + 1 < fv.size(); ++k)
            tri(0, k, k + 1);  // quads, triangles, and n-gons at level 0
    }
    // Limit normals from the tangents; where the tangents are degenerate (zero-area faces), the
    // area-weighted normal of the refined faces, and the winding of the faces decides the side.
    for (const auto& [key, index] : index_of) {
        const auto v = static_cast<std::size_t>(key >> 32);
        float* n = &mesh.normals[3 * static_cast<std::size_t>(index)];
        Vec3 limit_n(n[0], n[1], n[2]);
        const Vec3 faces = face_normal_sum[v];
        if (!(length(limit_n) > 1e-20f) || !is_finite(limit_n)) limit_n = faces;
        if (dot(limit_n, faces) < 0.0f) limit_n = -limit_n;
        const float len = length(limit_n);
        limit_n = len > 0.0f && std::isfinite(len) ? limit_n / len : Vec3(0, 0, 1);
        n[0] = limit_n.x;
        n[1] = limit_n.y;
        n[2] = limit_n.z;
    }
    report(1.0);
    return mesh;
}

}  // namespace spangle
