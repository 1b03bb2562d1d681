// Skins and morph targets (glTF 2.0, 3.7.2.2 and 3.7.3): a primitive drawn by a skinned node, or
// one whose mesh has morph targets, is drawn in the shape they give it rather than its bind
// shape.
//
// - Morph targets: each target's POSITION and NORMAL displacements, times the node's weights
//   (else the mesh's; an animated `weights` channel gives them through time), are added to the
//   base shape; TANGENT displacements are not read (Spangle derives tangents from the uvs).
// - Skin: each vertex goes through the weighted sum of its joints' world matrix x inverse bind
//   matrix (JOINTS_0/WEIGHTS_0, and JOINTS_1/WEIGHTS_1 for eight influences), normals through
//   that sum's inverse transpose. The object stays placed by its first joint (skinned_motion in
//   gltf_nodes.cpp) and its vertices are expressed in that placement's space, so that a joint in
//   its bind pose leaves them exactly as written and a character moved by its root alone is the
//   rigid motion it was before.
//
// The base shape is each deformed mesh's rest pose (TriangleMesh::rest_positions): flakes and
// other object-space patterns stay on their spot of the surface while a character bends. A joint
// matrix at a time between keys is interpolated as the builder interpolates an object's matrix
// keys (by decomposition), so a joint and a rigid object moved by the same channel agree.

#include <algorithm>
#include <cmath>

#include "scene/gltf/gltf_accessors.h"
#include "scene/gltf/gltf_parts.h"
#include "scene/keyed_motion.h"

namespace spangle::gltf {
namespace {

/** Influences per vertex held (JOINTS_0 and JOINTS_1, four each). */
constexpr std::size_t kInfluences = 8;

/** A node's world matrix through time, interpolated between its keys as matrix_motion does. */
struct MatrixTrack {
    Affine rest;
    std::vector<double> times;
    std::vector<Affine> given;
    std::vector<DecomposedAffine> parts;

    explicit MatrixTrack(const NodeMotion& m) : rest(m.rest), times(m.times), given(m.matrices) {
        parts.reserve(given.size());
        for (const Affine& a : given) parts.push_back(decompose(a));
    }
    Affine at(double t) const {
        if (times.empty()) return rest;
        if (t <= times.front()) return given.front();
        if (t >= times.back()) return given.back();
        const auto i = static_cast<std::size_t>(std::upper_bound(times.begin(), times.end(), t) -
                                                times.begin()) -
                       1;
        if (t == times[i]) return given[i];
        return interpolate(parts[i], parts[i + 1], (t - times[i]) / (times[i + 1] - times[i]));
    }
};

/** a + w b, entry by entry (a weighted sum of placements). */
void add_scaled(Affine& a, const Affine& b, float w) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) a.m[r][c] += w * b.m[r][c];
    a.t = a.t + b.t * w;
}

/** Whether placement a is the identity within float rounding of a product of a matrix and its
 *  inverse (relative to its size and to `extent`, the mesh's size, for the translation). */
bool near_identity(const Affine& a, float extent) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            if (!(std::fabs(a.m[r][c] - (r == c ? 1.0f : 0.0f)) <= 1e-5f)) return false;
    const float tol = 1e-5f * extent;
    return std::fabs(a.t.x) <= tol && std::fabs(a.t.y) <= tol && std::fabs(a.t.z) <= tol;
}

class GltfDeformation final : public MeshDeformation {
public:
    std::shared_ptr<const TriangleMesh> base;
    FileLoc loc;          ///< the node, blamed for a shape that is not finite
    std::string what;     ///< "node N primitive P"
    float extent = 0.0f;  ///< the base shape's largest coordinate size

    // Morph targets: displacements per target (3 per vertex; normals may be empty).
    std::vector<std::vector<float>> dpos, dnrm;
    std::vector<float> weights;  ///< the weights without animation
    std::optional<WeightTrack> track;

    // Skin: kInfluences joints and weights per vertex (weights summing to 1, or all 0).
    bool skinned = false;
    std::vector<uint32_t> joint;
    std::vector<float> weight;
    std::vector<MatrixTrack> joints;  ///< each joint's world motion
    std::vector<Affine> ibm;          ///< inverse bind matrices
    std::optional<MatrixTrack> placement;

    std::shared_ptr<const TriangleMesh> at(double seconds) const override {
        const TriangleMesh& b = *base;
        const std::size_t nv = b.vertex_count();
        auto m = std::make_shared<TriangleMesh>();
        m->source = b.source;
        m->positions = b.positions;
        m->normals = b.normals;
        m->uvs = b.uvs;
        m->colors = b.colors;
        m->indices = b.indices;
        m->notes = b.notes;
        // Morph targets.
        std::vector<float> w = weights;
        if (track) {
            std::vector<float> animated(track->count, 0.0f);
            evaluate_weights(*track, seconds, animated.data());
            for (std::size_t k = 0; k < w.size() && k < animated.size(); ++k) w[k] = animated[k];
        }
        for (std::size_t k = 0; k < dpos.size() && k < w.size(); ++k) {
            if (w[k] == 0.0f) continue;
            for (std::size_t i = 0; i < dpos[k].size(); ++i) m->positions[i] += w[k] * dpos[k][i];
            if (!m->normals.empty() && !dnrm[k].empty())
                for (std::size_t i = 0; i < dnrm[k].size(); ++i) m->normals[i] += w[k] * dnrm[k][i];
        }
        // Skin: each joint's matrix in the placement's space, the identity where it is one up to
        // rounding (a joint in its bind pose leaves its vertices exactly as they are).
        if (skinned) {
            const Affine to_object = placement->at(seconds).inverse();
            std::vector<Affine> s(joints.size());
            std::vector<char> identity(joints.size(), 0);
            bool all_identity = true;
            for (std::size_t j = 0; j < joints.size(); ++j) {
                s[j] = to_object.compose(joints[j].at(seconds).compose(ibm[j]));
                identity[j] = near_identity(s[j], extent) ? 1 : 0;
                all_identity = all_identity && identity[j];
            }
            if (!all_identity) {
                for (std::size_t v = 0; v < nv; ++v) {
                    Affine blend;
                    for (int r = 0; r < 3; ++r) blend.m[r][r] = 0.0f;
                    bool moved = false;
                    float total = 0.0f;
                    for (std::size_t k = 0; k < kInfluences; ++k) {
                        const float wk = weight[v * kInfluences + k];
                        if (wk == 0.0f) continue;
                        const uint32_t j = joint[v * kInfluences + k];
                        add_scaled(blend, s[j], wk);
                        moved = moved || !identity[j];
                        total += wk;
                    }
                    if (!moved || !(total > 0.0f)) continue;
                    const Vec3 p = blend.apply_point(m->position(static_cast<uint32_t>(v)));
                    m->positions[3 * v] = p.x;
                    m->positions[3 * v + 1] = p.y;
                    m->positions[3 * v + 2] = p.z;
                    if (!m->normals.empty()) {
                        const Vec3 n0{m->normals[3 * v], m->normals[3 * v + 1],
                                      m->normals[3 * v + 2]};
                        const Vec3 n = blend.normal_matrix().apply_vector(n0);
                        m->normals[3 * v] = n.x;
                        m->normals[3 * v + 1] = n.y;
                        m->normals[3 * v + 2] = n.z;
                    }
                }
            }
        }
        for (float x : m->positions)
            if (!std::isfinite(x))
                throw_error(loc,
                            "{}: its skin or morph targets make a vertex that is not a "
                            "finite number at {} s",
                            what, seconds);
        // Normals unit length; one that vanishes leaves the mesh its face normals.
        for (std::size_t i = 0; i + 2 < m->normals.size(); i += 3) {
            float* n = &m->normals[i];
            const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (!(len > 1e-20f) || !std::isfinite(len)) {
                m->normals.clear();
                break;
            }
            for (int c = 0; c < 3; ++c) n[c] /= len;
        }
        if (m->positions == b.positions && m->normals == b.normals) return base;
        m->rest_positions = b.rest_positions.empty() ? b.positions : b.rest_positions;
        return m;
    }
};

}  // namespace

DrawnPrimitive drawn_primitive(Context& ctx, int n, int prim,
                               std::shared_ptr<const TriangleMesh> base,
                               const std::vector<NodeMotion>& motions, const NodeMotion& placement,
                               const std::map<int, WeightTrack>& weights) {
    const tinygltf::Node& node = ctx.model.nodes[static_cast<std::size_t>(n)];
    const tinygltf::Mesh& mesh = ctx.model.meshes[static_cast<std::size_t>(node.mesh)];
    const tinygltf::Primitive& p = mesh.primitives[static_cast<std::size_t>(prim)];
    const std::string np = fmt::format("nodes/{}", n);
    const std::string pp = fmt::format("meshes/{}/primitives/{}", node.mesh, prim);
    const bool has_joints = p.attributes.count("JOINTS_0") && p.attributes.count("WEIGHTS_0");
    if (node.skin < 0 && (p.attributes.count("JOINTS_0") || p.attributes.count("WEIGHTS_0")))
        ctx.note("joints without skin", ctx.at(pp + "/attributes"),
                 "a primitive with JOINTS_0/WEIGHTS_0 is drawn by a node without a skin: it is "
                 "not deformed");
    if (node.skin >= 0 && !has_joints)
        ctx.note("skin without joints", ctx.at(np + "/skin"),
                 "a skinned node's primitive has no JOINTS_0 and WEIGHTS_0: it is drawn "
                 "rigidly, placed by the skin's first joint");
    const bool skinned = node.skin >= 0 && has_joints;
    if (!skinned && p.targets.empty()) return {base, nullptr};

    // A still shape is the same for every node that draws this primitive with the same skin and
    // weights (linked duplicates, a crowd): made once.
    const std::vector<double>& given = !node.weights.empty() ? node.weights : mesh.weights;
    bool moves = !p.targets.empty() && weights.count(n);
    if (skinned)
        for (int j : ctx.model.skins[static_cast<std::size_t>(node.skin)].joints)
            moves = moves || (j >= 0 && static_cast<std::size_t>(j) < motions.size() &&
                              !motions[static_cast<std::size_t>(j)].times.empty());
    std::string still_key;
    if (!moves) {
        still_key = fmt::format("{}/{}/{}/{}", node.mesh, prim, skinned ? node.skin : -1,
                                fmt::join(given, ","));
        if (const auto it = ctx.posed.find(still_key); it != ctx.posed.end())
            return {it->second, nullptr};
    }

    auto d = std::make_shared<GltfDeformation>();
    d->base = base;
    d->loc = ctx.at(np);
    d->what = fmt::format("node {} primitive {}", n, prim);
    const std::size_t nv = base->vertex_count();
    for (float x : base->positions) d->extent = std::max(d->extent, std::fabs(x));

    // Morph targets and their weights: the node's, else the mesh's, else 0 (glTF 2.0, 3.7.2.2).
    if (!p.targets.empty()) {
        const std::size_t count = p.targets.size();
        for (std::size_t k = 0; k < count; ++k) {
            const std::string tp = fmt::format("{}/targets/{}", pp, k);
            std::vector<float> pos, nrm;
            if (const auto a = p.targets[k].find("POSITION"); a != p.targets[k].end())
                pos = read_per_vertex(ctx, a->second, 3, nv, "a morph target's POSITION",
                                      tp + "/POSITION");
            else
                pos.assign(3 * nv, 0.0f);
            if (const auto a = p.targets[k].find("NORMAL"); a != p.targets[k].end())
                nrm = read_per_vertex(ctx, a->second, 3, nv, "a morph target's NORMAL",
                                      tp + "/NORMAL");
            d->dpos.push_back(std::move(pos));
            d->dnrm.push_back(std::move(nrm));
        }
        const std::string wp =
            !node.weights.empty() ? np + "/weights" : fmt::format("meshes/{}/weights", node.mesh);
        d->weights.assign(count, 0.0f);
        if (!given.empty() && given.size() != count)
            ctx.note("weights count", ctx.at(wp),
                     fmt::format("{} morph weights for {} targets: the missing ones are 0, the "
                                 "extra ones dropped",
                                 given.size(), count));
        for (std::size_t k = 0; k < count && k < given.size(); ++k) {
            const float w = narrow(given[k]);
            if (!std::isfinite(w))
                throw_error(ctx.at(wp), "a morph weight is not a finite number ({})", given[k]);
            d->weights[k] = w;
        }
        if (const auto it = weights.find(n); it != weights.end()) {
            if (it->second.count != count)
                ctx.note("animated weights count", it->second.loc,
                         fmt::format("the animation gives {} weights per key for {} morph "
                                     "targets: the missing ones keep their weights, the extra "
                                     "ones are dropped",
                                     it->second.count, count));
            for (float x : it->second.values)
                if (!std::isfinite(x))
                    throw_error(it->second.loc, "a morph weight is not a finite number");
            d->track = it->second;
            d->first = it->second.times.front();
            d->last = it->second.times.back();
        }
    } else if (weights.count(n)) {
        ctx.note(
            "weights without targets", weights.at(n).loc,
            fmt::format("node {}'s weights are animated but its mesh has no morph targets", n));
    }

    // The skin: up to eight influences per vertex, weights made to sum to 1.
    if (skinned) {
        const tinygltf::Skin& skin = ctx.model.skins[static_cast<std::size_t>(node.skin)];
        const std::string sp = fmt::format("skins/{}", node.skin);
        const std::size_t nj = skin.joints.size();
        for (std::size_t j = 0; j < nj; ++j)
            check_index(ctx, sp + "/joints", skin.joints[j], ctx.model.nodes.size(), "node");
        d->ibm.assign(nj, Affine{});
        if (skin.inverseBindMatrices >= 0) {
            const std::vector<float> f =
                read_floats(ctx, skin.inverseBindMatrices, 16, "an inverse bind matrix",
                            sp + "/inverseBindMatrices");
            if (f.size() < 16 * nj)
                throw_error(ctx.at(sp + "/inverseBindMatrices"),
                            "the skin has {} joints and {} inverse bind matrices", nj,
                            f.size() / 16);
            for (std::size_t j = 0; j < nj; ++j) d->ibm[j] = column_major_affine(&f[16 * j]);
        }
        d->joint.assign(nv * kInfluences, 0);
        d->weight.assign(nv * kInfluences, 0.0f);
        bool bad_joint = false, negative = false;
        for (int set = 0; set < 2; ++set) {
            const std::string jn = fmt::format("JOINTS_{}", set),
                              wn = fmt::format("WEIGHTS_{}", set);
            const auto ja = p.attributes.find(jn), wa = p.attributes.find(wn);
            if (ja == p.attributes.end() || wa == p.attributes.end()) {
                if (ja != p.attributes.end() || wa != p.attributes.end())
                    ctx.note("joints unpaired",
                             ctx.at(pp + "/attributes/" + (ja != p.attributes.end() ? jn : wn)),
                             fmt::format("{} without its {} is dropped",
                                         ja != p.attributes.end() ? jn : wn,
                                         ja != p.attributes.end() ? wn : jn));
                break;
            }
            const std::vector<float> jv =
                read_per_vertex(ctx, ja->second, 4, nv, "JOINTS", pp + "/attributes/" + jn);
            const std::vector<float> wv =
                read_per_vertex(ctx, wa->second, 4, nv, "WEIGHTS", pp + "/attributes/" + wn);
            for (std::size_t v = 0; v < nv; ++v)
                for (std::size_t c = 0; c < 4; ++c) {
                    const float jf = jv[4 * v + c], wf = wv[4 * v + c];
                    negative = negative || wf < 0.0f;
                    if (!(wf > 0.0f)) continue;  // negative or zero: no influence
                    if (!(jf >= 0.0f && jf < static_cast<float>(nj))) {
                        bad_joint = true;
                        continue;
                    }
                    d->joint[v * kInfluences + 4 * static_cast<std::size_t>(set) + c] =
                        static_cast<uint32_t>(jf);
                    d->weight[v * kInfluences + 4 * static_cast<std::size_t>(set) + c] = wf;
                }
        }
        if (p.attributes.count("JOINTS_2"))
            ctx.note("JOINTS_2", ctx.at(pp + "/attributes/JOINTS_2"),
                     "influences past JOINTS_1/WEIGHTS_1 (more than eight per vertex) are dropped");
        if (bad_joint)
            ctx.note("bad joint", ctx.at(pp + "/attributes/JOINTS_0"),
                     fmt::format("a vertex names a joint the skin does not have (it has {}): "
                                 "that influence is dropped",
                                 nj));
        std::size_t unweighted = 0;
        for (std::size_t v = 0; v < nv; ++v) {
            float total = 0.0f;
            for (std::size_t k = 0; k < kInfluences; ++k) total += d->weight[v * kInfluences + k];
            if (total > 0.0f)
                for (std::size_t k = 0; k < kInfluences; ++k)
                    d->weight[v * kInfluences + k] /= total;
            else
                ++unweighted;
        }
        if (unweighted)
            ctx.note("unweighted vertices", ctx.at(pp + "/attributes/WEIGHTS_0"),
                     fmt::format("{} of the {} vertices have no positive skin weight: they stay "
                                 "where they are written (placed by the skin's first joint)",
                                 unweighted, nv));
        if (negative)
            ctx.note("negative weights", ctx.at(pp + "/attributes/WEIGHTS_0"),
                     "negative skin weights are dropped (glTF's weights are not negative)");
        for (std::size_t j = 0; j < nj; ++j) {
            const NodeMotion& jm = motions[static_cast<std::size_t>(skin.joints[j])];
            d->joints.emplace_back(jm);
            if (!jm.times.empty()) {
                d->first = std::min(d->animated() ? d->first : jm.times.front(), jm.times.front());
                d->last = std::max(d->last, jm.times.back());
            }
        }
        d->placement.emplace(placement);
        d->skinned = true;
    }
    if (!d->animated()) {
        // A still shape: computed once, no deformation left to evaluate.
        std::shared_ptr<const TriangleMesh> still = d->at(0.0);
        ctx.posed[still_key] = still;
        return {still, nullptr};
    }
    std::shared_ptr<const TriangleMesh> first = d->at(0.0);
    return {first, d};
}

}  // namespace spangle::gltf
