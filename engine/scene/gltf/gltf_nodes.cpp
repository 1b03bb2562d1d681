// The node tree of a glTF scene as Spangle objects, a camera and lights (glTF 2.0, 3.5): each
// primitive of a node's mesh is an object placed by the node's world matrix (or its matrix
// keys when an animation moves it); the first perspective camera, or the one asked for by
// name, looks down its node's -Z with +Y up; KHR_lights_punctual lights sit at their nodes.
// A file without a camera gets a framing of its bounds, one without light (or whose emission
// is too faint to light it) a studio light
// (docs/gltf.md gives both).

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include "scene/gltf/gltf_accessors.h"
#include "scene/gltf/gltf_parts.h"

namespace spangle::gltf {
namespace {

constexpr double kPhotometric = 683.0;  ///< lm/W at 555 nm: glTF's candela and lux to W/sr, W/m^2

/** Parents of every node (-1 for roots), checking that the nodes form a forest. */
std::vector<int> node_parents(const Context& ctx) {
    const std::size_t count = ctx.model.nodes.size();
    std::vector<int> parent(count, -1);
    for (std::size_t n = 0; n < count; ++n) {
        const std::vector<int>& children = ctx.model.nodes[n].children;
        for (std::size_t i = 0; i < children.size(); ++i) {
            const std::string cp = fmt::format("nodes/{}/children", n);
            check_index(ctx, cp, children[i], count, "node");
            const auto c = static_cast<std::size_t>(children[i]);
            if (parent[c] >= 0 || c == n)
                throw_error(ctx.at(cp),
                            "node {} is a child of node {}{}: the nodes must form "
                            "trees",
                            c, n, parent[c] >= 0 ? fmt::format(" and of node {}", parent[c]) : "");
            parent[c] = static_cast<int>(n);
        }
    }
    // Each node has one parent; a cycle is a chain that never reaches a root.
    std::vector<char> state(count, 0);  // 0 unknown, 1 on the walk, 2 reaches a root
    for (std::size_t n = 0; n < count; ++n) {
        std::vector<std::size_t> walk;
        int a = static_cast<int>(n);
        while (a >= 0 && state[static_cast<std::size_t>(a)] == 0) {
            state[static_cast<std::size_t>(a)] = 1;
            walk.push_back(static_cast<std::size_t>(a));
            a = parent[static_cast<std::size_t>(a)];
        }
        if (a >= 0 && state[static_cast<std::size_t>(a)] == 1)
            throw_error(ctx.at(fmt::format("nodes/{}", a)), "node {} is its own ancestor", a);
        for (std::size_t w : walk) state[w] = 2;
    }
    return parent;
}

/** The scene's nodes, parents before children: the default scene's (or the first), else all
 *  roots. */
std::vector<int> scene_nodes(const Context& ctx, const std::vector<int>& parent) {
    std::vector<int> roots;
    const tinygltf::Model& m = ctx.model;
    if (!m.scenes.empty()) {
        const int s = m.defaultScene >= 0 ? m.defaultScene : 0;
        check_index(ctx, "scene", s, m.scenes.size(), "scene");
        for (int n : m.scenes[static_cast<std::size_t>(s)].nodes) {
            check_index(ctx, fmt::format("scenes/{}/nodes", s), n, m.nodes.size(), "node");
            if (parent[static_cast<std::size_t>(n)] >= 0)
                throw_error(ctx.at(fmt::format("scenes/{}/nodes", s)),
                            "node {} is a scene's root but has a parent", n);
            if (std::find(roots.begin(), roots.end(), n) == roots.end()) roots.push_back(n);
        }
    } else {
        for (std::size_t n = 0; n < m.nodes.size(); ++n)
            if (parent[n] < 0) roots.push_back(static_cast<int>(n));
    }
    std::vector<int> order, stack(roots.rbegin(), roots.rend());
    while (!stack.empty()) {
        const int n = stack.back();
        stack.pop_back();
        order.push_back(n);
        const std::vector<int>& c = m.nodes[static_cast<std::size_t>(n)].children;
        stack.insert(stack.end(), c.rbegin(), c.rend());
    }
    return order;
}

/** A node motion as an object's matrix keys (seconds), blamed on `at`. */
Keys<MatrixKey> matrix_keys(const NodeMotion& m, const FileLoc& at, const std::string& what) {
    Keys<MatrixKey> keys;
    keys.loc = at;
    keys.smooth = false;
    for (std::size_t i = 0; i < m.times.size(); ++i)
        keys.keys.push_back(MatrixKey{KeyTime{m.times[i], {}}, m.matrices[i], at,
                                      fmt::format("{}, key {}", what, i + 1)});
    return keys;
}

}  // namespace

/** Whether placement `a` squashes space onto a plane, a line or a point (or is not finite): its
 *  determinant a vanishing share of the product of its columns' lengths. Relative, so that a
 *  small model's scale is not taken for none (gltfpack puts a quantised 1 cm model's 6e-7 per
 *  axis into each instance's scale: the determinant, 2e-19, was under an absolute 1e-18, and
 *  every instance was hidden). */
bool flattens(const Affine& a) {
    const double det = a.determinant_in_double();
    double columns = 1.0;
    for (int j = 0; j < 3; ++j) {
        double sq = 0.0;
        for (int i = 0; i < 3; ++i) {
            const auto x = static_cast<double>(a.m[i][j]);
            sq += x * x;
        }
        columns *= std::sqrt(sq);
    }
    return !std::isfinite(det) || !std::isfinite(columns) || !(std::fabs(det) > 1e-9 * columns);
}

namespace {

/** A placement that flattens its mesh onto a plane (one scale 0: a decal, a squashed shape)
 *  made invertible by the least thickness along the flattened direction (1e-6 of its size), so
 *  that it is drawn flat as a viewer draws it. False where it flattens the mesh onto a line or a
 *  point (nothing keeps an area). */
bool thicken(Affine& a) {
    const auto longest = [](Vec3 x, Vec3 y, Vec3 z) {
        const Vec3 c[3] = {cross(x, y), cross(y, z), cross(z, x)};
        Vec3 best = c[0];
        for (const Vec3& v : c)
            if (length(v) > length(best)) best = v;
        return best;
    };
    const Vec3 r0{a.m[0][0], a.m[0][1], a.m[0][2]}, r1{a.m[1][0], a.m[1][1], a.m[1][2]},
        r2{a.m[2][0], a.m[2][1], a.m[2][2]};
    const Vec3 c0{a.m[0][0], a.m[1][0], a.m[2][0]}, c1{a.m[0][1], a.m[1][1], a.m[2][1]},
        c2{a.m[0][2], a.m[1][2], a.m[2][2]};
    const Vec3 flat = longest(r0, r1, r2), missing = longest(c0, c1, c2);
    const float size = std::max({length(c0), length(c1), length(c2)});
    if (!(length(flat) > 1e-12f * size * size && length(missing) > 1e-12f * size * size))
        return false;
    const Vec3 n = normalize(flat), u = normalize(missing);
    const float e = 1e-6f * size;
    const float un[3][3] = {{u.x * n.x, u.x * n.y, u.x * n.z},
                            {u.y * n.x, u.y * n.y, u.y * n.z},
                            {u.z * n.x, u.z * n.y, u.z * n.z}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a.m[i][j] += e * un[i][j];
    return !flattens(a);
}

/** The most objects EXT_mesh_gpu_instancing makes from one file (instances x primitives). */
constexpr std::size_t kMaxInstanceObjects = std::size_t{1} << 22;

/** EXT_mesh_gpu_instancing: the transforms of node n's instances (each T R S from its
 *  TRANSLATION, ROTATION and SCALE, in the node's space: the node's matrix applies after it);
 *  empty when the node has none. */
std::vector<Affine> instance_matrices(Context& ctx, int n) {
    const tinygltf::Node& node = ctx.model.nodes[static_cast<std::size_t>(n)];
    const auto it = node.extensions.find("EXT_mesh_gpu_instancing");
    if (it == node.extensions.end()) return {};
    const std::string xp = fmt::format("nodes/{}/extensions/EXT_mesh_gpu_instancing", n);
    const tinygltf::Value& x = it->second;
    if (!x.IsObject() || !x.Has("attributes"))
        throw_error(ctx.at(xp), "EXT_mesh_gpu_instancing needs its 'attributes' object");
    if (!x.Get("attributes").IsObject() || x.Get("attributes").Size() == 0) {
        ctx.note("no instances", ctx.at(xp),
                 "EXT_mesh_gpu_instancing gives no instance attribute: the mesh is drawn once");
        return {};
    }
    std::vector<float> t, r, s;
    std::size_t count = 0;
    std::string first;
    for (const auto& [name, value] : x.Get("attributes").Get<tinygltf::Value::Object>()) {
        const std::string ap = xp + "/attributes/" + name;
        std::vector<float>* into = name == "TRANSLATION" ? &t
                                   : name == "ROTATION"  ? &r
                                   : name == "SCALE"     ? &s
                                                         : nullptr;
        if (!into) {
            // Custom attributes (_ID, _COLOR, ...) say nothing Spangle draws.
            ctx.note("instance attribute " + name, ctx.at(ap),
                     fmt::format("instance attribute {} is dropped (only TRANSLATION, ROTATION "
                                 "and SCALE place instances)",
                                 name));
            continue;
        }
        const double index = value.IsNumber() ? value.GetNumberAsDouble() : -1.0;
        if (!(index >= 0 && index <= 1e9) || index != std::floor(index))
            throw_error(ctx.at(ap), "instance attribute {} must be an accessor index", name);
        const int comps = name == "ROTATION" ? 4 : 3;
        // Each instance is an object per primitive: bounded before anything is read (a 1 KB
        // file asked for 2^24 of them, about 38 GB).
        const auto k = static_cast<std::size_t>(index);
        if (k < ctx.model.accessors.size()) {
            const std::size_t prims =
                node.mesh >= 0 && static_cast<std::size_t>(node.mesh) < ctx.model.meshes.size()
                    ? std::max<std::size_t>(
                          1,
                          ctx.model.meshes[static_cast<std::size_t>(node.mesh)].primitives.size())
                    : 1;
            const std::size_t wanted = ctx.model.accessors[k].count;
            if (static_cast<double>(wanted) * static_cast<double>(prims) +
                    static_cast<double>(ctx.instance_objects) >
                static_cast<double>(kMaxInstanceObjects))
                throw_error(ctx.at(ap),
                            "node {} asks for {} instances of a mesh of {} primitives: more "
                            "than the {} instanced objects Spangle makes from one file (each "
                            "is an object of about 2 KB)",
                            n, wanted, prims, kMaxInstanceObjects);
        }
        *into = read_floats(ctx, static_cast<int>(index), comps, name.c_str(), ap);
        const std::size_t c = into->size() / static_cast<std::size_t>(comps);
        if (!first.empty() && c != count)
            throw_error(ctx.at(ap),
                        "instance attribute {} has {} elements, {} has {}: each gives one per "
                        "instance",
                        name, c, first, count);
        count = c;
        first = name;
    }
    if (node.mesh >= 0 && static_cast<std::size_t>(node.mesh) < ctx.model.meshes.size())
        ctx.instance_objects +=
            count * std::max<std::size_t>(
                        1, ctx.model.meshes[static_cast<std::size_t>(node.mesh)].primitives.size());
    std::vector<Affine> out(count);
    for (std::size_t i = 0; i < count; ++i) {
        const Vec3 ti = t.empty() ? Vec3(0.0f) : Vec3(t[3 * i], t[3 * i + 1], t[3 * i + 2]);
        const float identity[4] = {0, 0, 0, 1};
        const float* ri = r.empty() ? identity : &r[4 * i];
        const Vec3 si = s.empty() ? Vec3(1.0f) : Vec3(s[3 * i], s[3 * i + 1], s[3 * i + 2]);
        out[i] = trs_matrix(ti, ri, si);
    }
    if (count == 0)
        ctx.note("no instances", ctx.at(xp),
                 "EXT_mesh_gpu_instancing gives no instance attribute: the mesh is drawn once");
    return out;
}

/** The objects of node n's mesh, one per primitive (and per instance of EXT_mesh_gpu_instancing).
 */
void mesh_objects(Context& ctx, int n, const NodeMotion& motion,
                  const std::vector<NodeMotion>& motions,
                  const std::map<int, WeightTrack>& weights) {
    const tinygltf::Node& node = ctx.model.nodes[static_cast<std::size_t>(n)];
    const std::string np = fmt::format("nodes/{}", n);
    check_index(ctx, np + "/mesh", node.mesh, ctx.model.meshes.size(), "mesh");
    Affine rest = motion.rest;
    if (motion.times.empty() && flattens(rest) && !thicken(rest)) {
        ctx.note(fmt::format("hidden {}", n), ctx.at(np),
                 fmt::format("node {} is scaled to nothing (onto a line or a point): its mesh "
                             "is not drawn",
                             n));
        return;
    }
    const tinygltf::Mesh& mesh = ctx.model.meshes[static_cast<std::size_t>(node.mesh)];
    std::vector<Affine> instances = instance_matrices(ctx, n);
    if (!instances.empty() && node.skin >= 0) {
        ctx.note(fmt::format("instanced skin {}", n),
                 ctx.at(np + "/extensions/EXT_mesh_gpu_instancing"),
                 "a skinned mesh's instances are not drawn apart (its joints place it): drawn "
                 "once");
        instances.clear();
    }
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
        std::shared_ptr<const TriangleMesh> tri =
            read_primitive(ctx, node.mesh, static_cast<int>(p));
        if (!tri) continue;
        DrawnPrimitive drawn =
            drawn_primitive(ctx, n, static_cast<int>(p), tri, motions, motion, weights);
        const std::string pp = fmt::format("meshes/{}/primitives/{}", node.mesh, p);
        const int mat = mesh.primitives[p].material;
        if (mat >= 0)
            check_index(ctx, pp + "/material", mat, ctx.model.materials.size(), "material");
        ObjectDesc o;
        std::optional<InlineMeshShape> mirrored;
        // Named after the node, else its mesh, else the node's number ("node 3"): messages and
        // the cryptomatte layers name it.
        o.name = !node.name.empty()   ? node.name
                 : !mesh.name.empty() ? mesh.name
                                      : fmt::format("node {}", n);
        if (mesh.primitives.size() > 1) o.name += fmt::format("#{}", p);
        o.material = use_material(ctx, mat, o.emission);
        o.shape = InlineMeshShape{drawn.mesh, ctx.at(pp), std::move(drawn.deformation)};
        o.loc = ctx.at(np);
        o.material_loc = ctx.at(mat >= 0 ? pp + "/material" : pp);
        o.what =
            fmt::format("node {}{} primitive {}", n,
                        node.name.empty() ? std::string() : fmt::format(" '{}'", node.name), p);
        if (instances.empty()) {
            if (motion.times.empty())
                o.placement.matrix = rest;
            else
                o.matrix_keys = matrix_keys(motion, ctx.at(np), o.what);
            face_for(ctx, o, mirrors(ctx, motion.rest, motion.matrices, ctx.at(np), o.what),
                     mirrored);
            ctx.scene->objects.push_back(std::move(o));
            continue;
        }
        // One object per instance, sharing the mesh: the node's placement (and motion) after
        // the instance's own. An instance scaled to nothing is not drawn and one flattened onto
        // a plane is drawn flat, as a node is.
        const std::string name = o.name, what = o.what;
        const auto hidden = [&](std::size_t i) {
            ctx.note(fmt::format("hidden instances {}", n),
                     ctx.at(np + "/extensions/EXT_mesh_gpu_instancing"),
                     fmt::format("instance {} of node {} is scaled to nothing (onto a line or a "
                                 "point): it is not drawn",
                                 i, n));
        };
        for (std::size_t i = 0; i < instances.size(); ++i) {
            ObjectDesc inst = o;
            inst.name = fmt::format("{}@{}", name, i);
            inst.what = fmt::format("{} instance {}", what, i);
            // The instance's own transform first (an animated node keeps it in every key),
            // then, at rest, the placement as a whole.
            Affine own = instances[i];
            const Affine written = own;  // before a flattened one is made thin
            if (motion.times.empty()) {
                // The placement as a whole (a tiny instance in a large node is not tiny).
                Affine placed = rest.compose(own);
                if (flattens(placed) && !thicken(placed)) {
                    hidden(i);
                    continue;
                }
                inst.placement.matrix = placed;
                face_for(ctx, inst, mirrors(ctx, motion.rest.compose(written), {}, {}, inst.what),
                         mirrored);
            } else {
                if (flattens(own) && !thicken(own)) {
                    hidden(i);
                    continue;
                }
                NodeMotion m = motion;
                m.rest = m.rest.compose(own);
                for (Affine& k : m.matrices) k = k.compose(own);
                inst.matrix_keys = matrix_keys(m, ctx.at(np), inst.what);
                std::vector<Affine> keys = motion.matrices;
                for (Affine& k : keys) k = k.compose(written);
                face_for(ctx, inst, mirrors(ctx, m.rest, keys, ctx.at(np), inst.what), mirrored);
            }
            ctx.scene->objects.push_back(std::move(inst));
        }
    }
}

/** Where a skinned mesh is placed: the glTF spec ignores a skinned mesh node's own transform;
 *  its vertices go through joint world matrix x inverse bind matrix. The object follows its
 *  first joint (its world matrix times its inverse bind matrix) and its vertices are deformed
 *  in that placement's space (gltf_deform.cpp): at the bind pose every joint puts them where
 *  they are written (an exporter's armature with a scale of 0.01 and the mesh node at the root,
 *  as Blender and Mixamo write them, was drawn 100 times too big before skins were read). */
NodeMotion skinned_motion(Context& ctx, int n, const std::vector<NodeMotion>& motions) {
    const tinygltf::Node& node = ctx.model.nodes[static_cast<std::size_t>(n)];
    const std::string sp = fmt::format("skins/{}", node.skin);
    check_index(ctx, fmt::format("nodes/{}/skin", n), node.skin, ctx.model.skins.size(), "skin");
    const tinygltf::Skin& skin = ctx.model.skins[static_cast<std::size_t>(node.skin)];
    if (skin.joints.empty()) return motions[static_cast<std::size_t>(n)];
    const int j0 = skin.joints[0];
    check_index(ctx, sp + "/joints", j0, ctx.model.nodes.size(), "node");
    Affine ibm;
    if (skin.inverseBindMatrices >= 0) {
        const std::vector<float> f =
            read_floats(ctx, skin.inverseBindMatrices, 16, "an inverse bind matrix",
                        sp + "/inverseBindMatrices");
        if (f.size() >= 16) ibm = column_major_affine(f.data());
    }
    NodeMotion out = motions[static_cast<std::size_t>(j0)];
    out.rest = out.rest.compose(ibm);
    for (Affine& a : out.matrices) a = a.compose(ibm);
    // A placement the vertices cannot be expressed in (the first joint's inverse bind matrix
    // flattens them): the mesh is placed by none and deformed in world space.
    const auto invertible = [](const Affine& a) {
        const double det = a.determinant_in_double();
        return std::isfinite(det) && std::fabs(det) > 1e-18;
    };
    bool ok = invertible(out.rest);
    for (const Affine& a : out.matrices) ok = ok && invertible(a);
    if (!ok) {
        ctx.note("skin placement", ctx.at(sp + "/inverseBindMatrices"),
                 fmt::format("skin {}'s first joint times its inverse bind matrix is not "
                             "invertible: its mesh is deformed in world space",
                             node.skin));
        return NodeMotion{};
    }
    return out;
}

/** v made unit length; -z for a zero vector (a node scaled to nothing). */
Vec3 unit(Vec3 v) {
    const float l = length(v);
    return l > 0.0f ? v * (1.0f / l) : Vec3{0, 0, -1};
}

/** A light of KHR_lights_punctual at node n. */
void punctual_light(Context& ctx, int n, int index, const NodeMotion& motion) {
    const std::string lp = fmt::format("extensions/KHR_lights_punctual/lights/{}", index);
    check_index(ctx, fmt::format("nodes/{}/extensions/KHR_lights_punctual/light", n), index,
                ctx.model.lights.size(), "light");
    const tinygltf::Light& g = ctx.model.lights[static_cast<std::size_t>(index)];
    if (!motion.times.empty())
        ctx.note("animated light", ctx.at(fmt::format("nodes/{}", n)),
                 "lights do not follow animations: they stay where their node is at time 0");
    if (g.range > 0.0)
        ctx.note("light range", ctx.at(lp + "/range"),
                 "a light's range is dropped: Spangle's lights fall off with distance squared "
                 "without a cut-off");
    LightDesc d;
    d.loc = ctx.at(lp);
    d.group.loc = d.loc;
    Vec3 rgb{1, 1, 1};
    if (g.color.size() == 3) rgb = {narrow(g.color[0]), narrow(g.color[1]), narrow(g.color[2])};
    if (!std::isfinite(rgb.x + rgb.y + rgb.z) || rgb.x < 0 || rgb.y < 0 || rgb.z < 0)
        throw_error(ctx.at(lp + "/color"), "a light's colour must be three non-negative numbers");
    d.color =
        ColorDesc{rgb, std::string("lin_rec709"), ctx.at(lp + "/color"), ctx.at(lp + "/color")};
    if (!std::isfinite(g.intensity) || g.intensity < 0)
        throw_error(ctx.at(lp + "/intensity"), "a light's intensity must be non-negative, got {}",
                    g.intensity);
    d.intensity = g.intensity / kPhotometric;
    const Vec3 at = motion.rest.apply_point({0, 0, 0});
    const Vec3 forward = unit(motion.rest.apply_vector({0, 0, -1}));
    if (g.type == "point") {
        d.shape = PointLightDesc{at};
    } else if (g.type == "spot") {
        const double outer = std::clamp(g.spot.outerConeAngle, 1e-4, M_PI / 2) * 180.0 / M_PI;
        const double inner = std::clamp(g.spot.innerConeAngle * 180.0 / M_PI, 0.0, outer);
        SpotLightDesc s;
        s.position = at;
        s.look_at = at + forward;
        s.cone_angle = outer;
        s.cone_falloff = outer - inner;
        s.look_at_loc = s.cone_falloff_loc = d.loc;
        d.shape = s;
    } else if (g.type == "directional") {
        d.shape = DistantLightDesc{forward * -1.0f, 0.0, d.loc};
    } else {
        throw_error(ctx.at(lp + "/type"), "light type '{}' must be point, spot or directional",
                    g.type);
    }
    ctx.scene->lights.push_back(std::move(d));
}

/** The world-space bounds of every object at its rest placement. */
bool scene_bounds(const Context& ctx, Vec3& lo, Vec3& hi) {
    bool any = false;
    for (const ObjectDesc& o : ctx.scene->objects) {
        const auto& shape = std::get<InlineMeshShape>(o.shape);
        const Affine m =
            o.placement.matrix ? *o.placement.matrix : o.matrix_keys.keys.front().matrix;
        for (std::size_t v = 0; v < shape.mesh->vertex_count(); ++v) {
            const Vec3 p = m.apply_point(shape.mesh->position(static_cast<uint32_t>(v)));
            lo = any ? Vec3{std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)} : p;
            hi = any ? Vec3{std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)} : p;
            any = true;
        }
    }
    return any;
}

/** The default framing: from the front (+Z) and 15 degrees above, the bounding sphere filling
 *  the 40-degree vertical view. */
void default_camera(Context& ctx) {
    CameraDesc& c = ctx.scene->camera;
    c.loc = c.look_at_loc = c.up_loc = FileLoc{ctx.path, 1, 1};
    c.fov_deg = 40.0;
    Vec3 lo{-1, -1, -1}, hi{1, 1, 1};
    scene_bounds(ctx, lo, hi);
    const Vec3 centre = (lo + hi) * 0.5f;
    // In double (the squares of a 1e20 extent overflow a float); a floor relative to where the
    // model lies, not 1 mm: a 10 micrometre model filled a millionth of the frame.
    const Vec3 e = hi - lo;
    const double extent = std::hypot(double(e.x), double(e.y), double(e.z));
    const float radius = std::max(
        static_cast<float>(0.5 * extent),
        1e-6f * std::max({1.0f, std::fabs(centre.x), std::fabs(centre.y), std::fabs(centre.z)}));
    const float distance = radius / std::sin(20.0f * kPi / 180.0f);
    const float up = std::sin(15.0f * kPi / 180.0f), front = std::cos(15.0f * kPi / 180.0f);
    c.position = centre + Vec3{0, up, front} * distance;
    c.look_at = centre;
    c.up = {0, 1, 0};
}

/** Camera `index` at node n: glTF's camera looks down -Z with +Y up (glTF 2.0, 3.10.1). */
void use_camera(Context& ctx, int n, int index, const NodeMotion& motion, bool size_given) {
    const tinygltf::Camera& g = ctx.model.cameras[static_cast<std::size_t>(index)];
    const std::string cp = fmt::format("cameras/{}", index);
    CameraDesc& c = ctx.scene->camera;
    c.loc = c.look_at_loc = c.up_loc = ctx.at(fmt::format("nodes/{}", n));
    double aspect = 0.0;
    if (g.type == "orthographic") {
        // xmag and ymag are half the view's width and height (glTF 2.0, 3.10.3); the image's
        // aspect is the viewport's, as for a perspective camera: ymag is kept and xmag only
        // sets the aspect, as aspectRatio does. Neither may be 0; a negative one (the
        // specification says it should not be) is taken by its size, with a note.
        for (const auto& [key, v] :
             {std::pair{"xmag", g.orthographic.xmag}, std::pair{"ymag", g.orthographic.ymag}}) {
            if (!(std::fabs(v) > 0.0) || !std::isfinite(v))
                throw_error(ctx.at(cp + "/orthographic/" + key),
                            "an orthographic camera's {} must be a finite number other than 0, "
                            "got {}",
                            key, v);
            if (v < 0.0)
                ctx.note("negative magnification", ctx.at(cp + "/orthographic/" + key),
                         fmt::format("{} {} is negative: its size is taken", key, v));
        }
        const double ymag = std::fabs(g.orthographic.ymag), xmag = std::fabs(g.orthographic.xmag);
        c.ortho_height = 2.0 * ymag;
        aspect = xmag / ymag;
    } else {
        const double yfov = g.perspective.yfov * 180.0 / M_PI;
        if (!(yfov > 0.0 && yfov < 180.0))
            throw_error(ctx.at(cp + "/perspective/yfov"), "yfov must be in (0, pi) radians, got {}",
                        g.perspective.yfov);
        c.fov_deg = yfov;
        aspect = g.perspective.aspectRatio;
    }
    const std::string aspect_at =
        cp + (g.type == "orthographic" ? "/orthographic/xmag" : "/perspective/aspectRatio");
    if (aspect > 0.0 && std::isfinite(aspect)) {
        const double h = std::round(ctx.scene->render.width / aspect);
        ctx.scene->render.height = static_cast<uint32_t>(std::clamp(h, 1.0, 16384.0));
        // An image of one row, or of 16384 (a width of 640 at an aspect of 1/1000: the clamp was
        // taken without a word).
        if (!(h >= 4.0 && h <= 16384.0) && !size_given)
            ctx.note("extreme aspect", ctx.at(aspect_at),
                     fmt::format("the camera's aspect ratio {:g} makes the image {} x {} pixels: "
                                 "give the size you want with --size (or [render] width and "
                                 "height in a TOML scene that imports this file)",
                                 aspect, ctx.scene->render.width, ctx.scene->render.height));
    } else if (g.type != "orthographic" && ctx.json.has(aspect_at) && !size_given) {
        // Written, but 0, negative or not a number: the size stays the default (silently before).
        ctx.note("bad aspect", ctx.at(aspect_at),
                 fmt::format("aspectRatio {:g} is not a positive number: ignored, the image is "
                             "{} x {}",
                             aspect, ctx.scene->render.width, ctx.scene->render.height));
    }
    const auto pose = [](const Affine& m, Vec3& eye, Vec3& look, Vec3& up) {
        eye = m.apply_point({0, 0, 0});
        look = eye + unit(m.apply_vector({0, 0, -1}));
        up = unit(m.apply_vector({0, 1, 0}));
    };
    pose(motion.rest, c.position, c.look_at, c.up);
    c.keys.loc = c.loc;
    c.keys.smooth = false;
    for (std::size_t i = 0; i < motion.times.size(); ++i) {
        CameraKey k;
        k.time.seconds = motion.times[i];
        Vec3 eye, look, up;
        pose(motion.matrices[i], eye, look, up);
        k.position = eye;
        k.look_at = look;
        k.up = up;
        k.loc = c.loc;
        k.what = fmt::format("camera node {}, key {}", n, i + 1);
        c.keys.keys.push_back(std::move(k));
    }
}

/** Picks the camera: the one `name` names (a camera's or its node's name, or "#N" for the
 *  file's camera N, which unnamed cameras have only), else the first. */
void choose_camera(Context& ctx, const std::vector<std::pair<int, int>>& cameras,
                   const SceneReadOptions& options, const std::vector<NodeMotion>& motions) {
    const std::string& name = options.camera;
    int index = -1;
    if (name.size() > 1 && name.size() < 10 && name[0] == '#' &&
        std::all_of(name.begin() + 1, name.end(), [](char ch) { return ch >= '0' && ch <= '9'; }))
        index = std::stoi(name.substr(1));
    // Each camera by a name --camera takes: its own, its node's, or "#N".
    std::vector<std::string> names;
    for (const auto& [node, cam] : cameras) {
        const std::string& cn = ctx.model.cameras[static_cast<std::size_t>(cam)].name;
        const std::string& nn = ctx.model.nodes[static_cast<std::size_t>(node)].name;
        names.push_back(!cn.empty() ? cn : !nn.empty() ? nn : fmt::format("#{}", cam));
    }
    // The first of several, not silently: the others are there to be chosen.
    if (name.empty() && cameras.size() > 1)
        ctx.note("first camera", ctx.at(fmt::format("nodes/{}", cameras.front().first)),
                 fmt::format("the file has {} cameras: the first, '{}', is used (--camera picks "
                             "another: {})",
                             cameras.size(), names.front(), fmt::join(names, ", ")));
    for (const auto& [node, cam] : cameras) {
        const bool named = ctx.model.cameras[static_cast<std::size_t>(cam)].name == name ||
                           ctx.model.nodes[static_cast<std::size_t>(node)].name == name ||
                           cam == index;
        if (name.empty() || named) {
            ctx.scene->camera_by_name = !name.empty();
            return use_camera(ctx, node, cam, motions[static_cast<std::size_t>(node)],
                              options.size_given);
        }
    }
    if (!name.empty()) {
        throw_error(
            ctx.at("cameras"), "no camera named '{}' (cameras: {})", name,
            names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", ")));
    }
    ctx.note("default camera", FileLoc{ctx.path, 1, 1}, kDefaultCameraNote);
    default_camera(ctx);
    ctx.scene->camera_is_default = true;
}

/** The world-space area of an object the reader placed (an inline mesh under a matrix); 0 for
 *  any other shape. */
double object_area(const ObjectDesc& o) {
    const auto* in = std::get_if<InlineMeshShape>(&o.shape);
    if (!in || !in->mesh) return 0.0;
    const Affine xf = o.placement.matrix.value_or(Affine{});
    return placed_area(*in->mesh, [&](Vec3 p) { return xf.apply_point(p); });
}

/** The largest channel of an emission's colour times its image's factor (with an image, the
 *  factor is the texture's scale and the colour white): its peak radiance per unit intensity. */
double emission_peak(const EmissionDesc& e) {
    const Vec3 c = e.color.rgb;
    const TextureDesc* t = e.texture ? &*e.texture : nullptr;
    return static_cast<double>(
        t ? std::max({t->scale[0] * c.x, t->scale[1] * c.y, t->scale[2] * c.z})
          : std::max({c.x, c.y, c.z}));
}

/** How brightly the file's own emission lights it: its emitted power (radiance x area x pi)
 *  spread over every surface of the file, an irradiance to set against the studio light's
 *  (about 2.5). */
double emission_irradiance(const SceneDescription& s) {
    double power = 0.0, area = 0.0;
    for (const ObjectDesc& o : s.objects) {
        const double a = object_area(o);
        area += a;
        if (o.emission) {
            power += std::numbers::pi * a * o.emission->intensity * o.emission->mean *
                     emission_peak(*o.emission);
        }
    }
    return area > 0.0 ? power / area : 0.0;
}

/** Emission spread this thin leaves the file black or nearly (surfaces of albedo 0.6 at
 *  about 0.02): an emissive atlas that is black but for one LED under emissiveFactor 1, as
 *  exporters write it, or a small LED on a device. 4% of the studio light's irradiance. */
constexpr double kFaintEmission = 0.1;

/** The studio light: a grey sky and a key light (docs/gltf.md). */
StudioLight studio_light(const Context& ctx) {
    const FileLoc file{ctx.path, 1, 1};
    StudioLight studio;
    studio.environment.loc = studio.environment.group.loc = file;
    studio.environment.color =
        ColorDesc{{0.25f, 0.25f, 0.25f}, std::string("lin_rec709"), file, file};
    LightDesc key;
    key.loc = key.group.loc = file;
    key.color = ColorDesc{{1, 1, 1}, std::string("lin_rec709"), file, file};
    key.intensity = 2.5;
    key.shape = DistantLightDesc{{-1.0f, 2.0f, 1.5f}, 2.0, file};
    studio.lights.push_back(std::move(key));
    return studio;
}

/** Says when the file's punctual lights leave it nearly black: their irradiance at the middle
 *  of its bounds (each light as if it faced it) below 1% of the studio key light's. glTF gives
 *  candela and lux, read at 683 lm/W as Blender's importer reads them; files made for viewers
 *  that take them without units (a sofa lit by a 3 lux sun) rendered black without a word. */
void dim_lights_note(Context& ctx) {
    if (ctx.scene->lights.empty() || ctx.scene->objects.empty()) return;
    Vec3 lo, hi;
    if (!scene_bounds(ctx, lo, hi)) return;
    const Vec3 middle = (lo + hi) * 0.5f;
    double irradiance = 0.0;
    for (const LightDesc& l : ctx.scene->lights) {
        const double peak =
            l.color
                ? static_cast<double>(std::max({l.color->rgb.x, l.color->rgb.y, l.color->rgb.z}))
                : 1.0;
        const auto at = [&](Vec3 p) {
            const Vec3 d = middle - p;
            return l.intensity * peak / std::max(1e-12, static_cast<double>(dot(d, d)));
        };
        if (std::holds_alternative<DistantLightDesc>(l.shape))
            irradiance += l.intensity * peak;
        else if (const auto* pt = std::get_if<PointLightDesc>(&l.shape))
            irradiance += at(pt->position);
        else if (const auto* sp = std::get_if<SpotLightDesc>(&l.shape))
            irradiance += at(sp->position);
        else
            return;  // a light of another kind: not judged here
    }
    constexpr double kKey = 2.5;  // the studio key light's irradiance
    if (!(irradiance < 0.01 * kKey)) return;
    ctx.note("dim lights", FileLoc{ctx.path, 1, 1},
             fmt::format("the file's lights give about {:.2g} W/m^2 at the middle of its bounds, "
                         "{:.0f} times less than the studio key light's {}: the image will be "
                         "nearly black (glTF's candela and lux are read at 683 lm/W, as "
                         "Blender's importer reads them; viewers that take them without units "
                         "show the file brighter)",
                         irradiance, kKey / std::max(irradiance, 1e-30), kKey));
}

/** What the file's emission is, when it has no light of its own. */
enum class Emission { None, Faint, Glow };

/** With no light in the file: the studio light stands in. */
void default_light(Context& ctx, Emission emission) {
    ctx.note("default light", FileLoc{ctx.path, 1, 1},
             emission == Emission::Faint
                 ? "the file's only light is emission too faint to light it (its power spread "
                   "over its surfaces is below 4% of the studio light's): the default studio "
                   "light is added (a grey sky and a key light)"
             : emission == Emission::Glow
                 ? "the file's only light is emission of radiance at most 1 (labels, screens, "
                   "LEDs, unlit surfaces: glow, as a viewer shows it): the default studio light "
                   "is added beside it (a grey sky and a key light; emission brighter than 1, "
                   "by KHR_materials_emissive_strength, lights the file alone)"
                 : "the file has no light: the default studio light stands in (a grey sky and a "
                   "key light)");
    StudioLight studio = studio_light(ctx);
    ctx.scene->environment = std::move(studio.environment);
    for (LightDesc& l : studio.lights) ctx.scene->lights.push_back(std::move(l));
}

}  // namespace

void read_nodes(Context& ctx, const SceneReadOptions& options) {
    const std::vector<int> parent = node_parents(ctx);
    const std::vector<int> order = scene_nodes(ctx, parent);
    const std::vector<NodeMotion> motions = node_motions(ctx, parent);
    const std::map<int, WeightTrack> weights = weight_tracks(ctx);
    std::vector<std::pair<int, int>> cameras;
    double end = 0.0;
    for (int n : order) {
        const tinygltf::Node& node = ctx.model.nodes[static_cast<std::size_t>(n)];
        const NodeMotion& motion = motions[static_cast<std::size_t>(n)];
        if (!motion.times.empty()) end = std::max(end, motion.times.back());
        if (const auto w = weights.find(n); w != weights.end())
            end = std::max(end, static_cast<double>(w->second.times.back()));
        if (node.mesh >= 0) {
            if (node.skin >= 0) {
                mesh_objects(ctx, n, skinned_motion(ctx, n, motions), motions, weights);
            } else {
                mesh_objects(ctx, n, motion, motions, weights);
            }
        }
        if (node.camera >= 0) {
            check_index(ctx, fmt::format("nodes/{}/camera", n), node.camera,
                        ctx.model.cameras.size(), "camera");
            cameras.emplace_back(n, node.camera);
        }
        if (auto x = node.extensions.find("KHR_lights_punctual"); x != node.extensions.end()) {
            const tinygltf::Value& v = x->second;
            if (!v.IsObject() || !v.Has("light") || !v.Get("light").IsInt())
                throw_error(ctx.at(fmt::format("nodes/{}/extensions/KHR_lights_punctual", n)),
                            "KHR_lights_punctual on a node needs a light index");
            punctual_light(ctx, n, v.Get("light").GetNumberAsInt(), motion);
        }
    }
    // An export of nothing (no meshes, or none the scene's nodes draw) rendered the studio's
    // background with notes about the camera and the lights only.
    if (ctx.scene->objects.empty())
        ctx.note("no meshes", FileLoc{ctx.path, 1, 1},
                 ctx.model.meshes.empty()
                     ? std::string("the file has no meshes: the image shows only the background")
                     : std::string("no node of the scene draws a mesh: the image shows only the "
                                   "background"));
    choose_camera(ctx, cameras, options, motions);
    bool emits = false;
    double brightest = 0.0;  // the largest emitted radiance (factor x strength)
    for (const ObjectDesc& o : ctx.scene->objects)
        if (o.emission) {
            emits = true;
            brightest = std::max(brightest, o.emission->intensity * emission_peak(*o.emission));
        }
    if (options.environment.empty()) dim_lights_note(ctx);  // --env lights it otherwise
    // --env lights the scene itself: no stand-in then. Nor where its emission lights it; faint
    // emission alone (which rendered black) gets the studio light beside it, and so does glow
    // of radiance at most 1 (emissive labels and screens of factor 1: test models whose labels
    // were taken for their light rendered nearly black).
    const Emission kind = !emits                                             ? Emission::None
                          : emission_irradiance(*ctx.scene) < kFaintEmission ? Emission::Faint
                          : brightest <= 1.0                                 ? Emission::Glow
                                                                             : Emission::None;
    const bool lit_by_emission = emits && kind == Emission::None;
    if (ctx.scene->lights.empty() && !lit_by_emission && options.environment.empty()) {
        default_light(ctx, kind);
    } else if (ctx.scene->lights.empty() && lit_by_emission && !ctx.scene->environment &&
               options.environment.empty()) {
        ctx.scene->studio_light = studio_light(ctx);  // for an import that drops the emission
        ctx.note("emission lights", FileLoc{ctx.path, 1, 1},
                 fmt::format("the file's only light is its emission (radiance up to {:.3g}): no "
                             "studio light is added; what it does not reach stays dark (--env "
                             "MAP lights the scene otherwise)",
                             brightest));
    }
    RenderDesc& r = ctx.scene->render;
    r.loc = r.working_space_loc = r.color_space_loc = FileLoc{ctx.path, 1, 1};
    if (end > 0.0)
        r.frame_end = r.frame_start + static_cast<int64_t>(std::min(std::ceil(end * r.fps), 1e6));
}

}  // namespace spangle::gltf
