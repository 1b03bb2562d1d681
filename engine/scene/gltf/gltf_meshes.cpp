// glTF mesh primitives as Spangle triangle meshes: positions, normals and the first texture
// coordinate set (v flipped: glTF's t runs down the image, Spangle's v up), triangles, strips
// and fans as indexed triangles, COLOR_0 as the mesh's vertex colours (which its material's base
// colour multiplies: has_vertex_colors). What a TriangleMesh cannot hold (tangents -- Spangle
// derives them from the uvs --, a second uv or colour set, a colour's alpha) is one note each.
// Skins and morph targets deform the mesh per node (gltf_deform.cpp).

#include <algorithm>
#include <cmath>

#include "scene/gltf/gltf_accessors.h"
#include "scene/gltf/gltf_parts.h"

namespace spangle::gltf {
namespace {

/** Notes the attributes a TriangleMesh has no room for, once per kind. */
void note_dropped(Context& ctx, const tinygltf::Primitive& p, const std::string& pp, int set) {
    for (const auto& [name, index] : p.attributes) {
        (void)index;
        const FileLoc at = ctx.at(pp + "/attributes/" + name);
        if (name == "TANGENT")
            ctx.note("TANGENT", at,
                     "TANGENT attributes are dropped: Spangle derives tangents from TEXCOORD_0");
        else if (name.rfind("COLOR_", 0) == 0 && name != "COLOR_0")
            ctx.note("COLOR_n", at,
                     name + " is dropped: Spangle meshes hold one set of vertex colours (COLOR_0)");
        else if (name.rfind("TEXCOORD_", 0) == 0 && name != fmt::format("TEXCOORD_{}", set))
            ctx.note("TEXCOORD_n", at,
                     fmt::format("{} is dropped: Spangle meshes hold one uv set (TEXCOORD_{}, "
                                 "the one the primitive's material reads)",
                                 name, set));
    }
}

/** Triangles of a strip or fan (glTF 2.0, 3.7.2.1) as a triangle list. */
std::vector<uint32_t> to_triangle_list(const std::vector<uint32_t>& v, int mode) {
    std::vector<uint32_t> out;
    if (v.size() < 3) return out;
    out.reserve(3 * (v.size() - 2));
    for (std::size_t i = 0; i + 2 < v.size(); ++i) {
        if (mode == TINYGLTF_MODE_TRIANGLE_FAN)
            out.insert(out.end(), {v[0], v[i + 1], v[i + 2]});
        else if (i % 2 == 0)
            out.insert(out.end(), {v[i], v[i + 1], v[i + 2]});
        else
            out.insert(out.end(), {v[i + 1], v[i], v[i + 2]});
    }
    return out;
}

/** Normals made unit length; false when one is zero (then the mesh uses face normals). */
bool normalize_normals(std::vector<float>& n) {
    for (std::size_t i = 0; i + 2 < n.size(); i += 3) {
        const float len = std::sqrt(n[i] * n[i] + n[i + 1] * n[i + 1] + n[i + 2] * n[i + 2]);
        if (!(len > 1e-12f)) return false;
        for (std::size_t c = 0; c < 3; ++c) n[i + c] /= len;
    }
    return true;
}

}  // namespace

bool has_vertex_colors(const Context& ctx, int material) {
    for (const tinygltf::Mesh& mesh : ctx.model.meshes)
        for (const tinygltf::Primitive& p : mesh.primitives) {
            const bool valid = p.material >= 0 &&
                               static_cast<std::size_t>(p.material) < ctx.model.materials.size();
            if ((valid ? p.material : -1) == material && p.attributes.count("COLOR_0")) return true;
        }
    return false;
}

std::shared_ptr<const TriangleMesh> read_primitive(Context& ctx, int mesh, int prim) {
    const auto key = std::pair{mesh, prim};
    if (auto it = ctx.meshes.find(key); it != ctx.meshes.end()) return it->second;
    const std::string pp = fmt::format("meshes/{}/primitives/{}", mesh, prim);
    const tinygltf::Primitive& p =
        ctx.model.meshes[static_cast<std::size_t>(mesh)].primitives[static_cast<std::size_t>(prim)];
    const int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        ctx.note(fmt::format("mode {}", mode), ctx.at(pp + "/mode"),
                 fmt::format("primitives of points or lines (mode {}) are not drawn", mode));
        return ctx.meshes[key] = nullptr;
    }
    const auto pos = p.attributes.find("POSITION");
    if (pos == p.attributes.end())
        throw_error(ctx.at(pp + "/attributes"), "mesh {} primitive {} has no POSITION", mesh, prim);
    int set = uv_set_of(ctx, p.material);
    if (!p.attributes.count(fmt::format("TEXCOORD_{}", set))) set = 0;
    auto m = std::make_shared<TriangleMesh>();
    m->source = ctx.path;
    m->positions = read_floats(ctx, pos->second, 3, "POSITION", pp + "/attributes/POSITION");
    const std::size_t nv = m->vertex_count();
    const auto attribute = [&](const char* name, int comps, std::vector<float>& out,
                               bool finite = true) {
        const auto a = p.attributes.find(name);
        if (a == p.attributes.end()) return;
        out = read_per_vertex(ctx, a->second, comps, nv, name, pp + "/attributes/" + name, finite);
    };
    // A NaN normal (some exporters write them for degenerate faces) is not worth refusing the
    // file for: the mesh takes its face normals, as for a zero normal.
    attribute("NORMAL", 3, m->normals, false);
    if (!std::all_of(m->normals.begin(), m->normals.end(),
                     [](float x) { return std::isfinite(x); })) {
        ctx.note("nan normal", ctx.at(pp + "/attributes/NORMAL"),
                 "a NORMAL is not a finite number: that mesh uses its face normals");
        m->normals.clear();
    }
    if (!normalize_normals(m->normals)) {
        ctx.note("zero normal", ctx.at(pp + "/attributes/NORMAL"),
                 "a NORMAL is zero: that mesh uses its face normals");
        m->normals.clear();
    }
    // The uv set the material's textures read (a mesh whose only uvs are TEXCOORD_1, for a
    // material reading it, was mapped through nothing).
    attribute(fmt::format("TEXCOORD_{}", set).c_str(), 2, m->uvs);
    // COLOR_0: linear rgb or rgba (float, or normalised unsigned byte or short).
    if (const auto c = p.attributes.find("COLOR_0"); c != p.attributes.end()) {
        const std::string ref = pp + "/attributes/COLOR_0";
        accessor_count(ctx, c->second, ref);  // checks that it exists
        const int comps =
            ctx.model.accessors[static_cast<std::size_t>(c->second)].type == TINYGLTF_TYPE_VEC4 ? 4
                                                                                                : 3;
        std::vector<float> rgba;
        attribute("COLOR_0", comps, rgba);
        m->colors.reserve(3 * nv);
        bool translucent = false;
        for (std::size_t i = 0; i < nv; ++i) {
            for (std::size_t k = 0; k < 3; ++k)
                m->colors.push_back(std::max(rgba[i * static_cast<std::size_t>(comps) + k], 0.0f));
            translucent = translucent || (comps == 4 && rgba[4 * i + 3] < 1.0f);
        }
        if (translucent)
            ctx.note("COLOR_0 alpha", ctx.at(ref),
                     "COLOR_0's alpha is dropped: vertex colours tint the base colour only");
    }
    for (std::size_t i = 1; i < m->uvs.size(); i += 2) m->uvs[i] = 1.0f - m->uvs[i];
    std::vector<uint32_t> idx;
    if (p.indices >= 0) {
        idx = read_indices(ctx, p.indices, pp + "/indices");
    } else {
        idx.resize(nv);
        for (std::size_t i = 0; i < nv; ++i) idx[i] = static_cast<uint32_t>(i);
    }
    for (uint32_t i : idx)
        if (i >= nv)
            throw_error(ctx.at(pp + "/indices"),
                        "mesh {} primitive {}: index {} is not below the "
                        "vertex count {}",
                        mesh, prim, i, nv);
    if (mode != TINYGLTF_MODE_TRIANGLES) idx = to_triangle_list(idx, mode);
    if (idx.size() % 3 != 0) {
        ctx.note("trailing indices", ctx.at(pp),
                 fmt::format("mesh {} primitive {}: {} indices are not a whole number of "
                             "triangles; the last {} are dropped",
                             mesh, prim, idx.size(), idx.size() % 3));
        idx.resize(idx.size() - idx.size() % 3);
    }
    m->indices = std::move(idx);
    note_dropped(ctx, p, pp, set);
    if (m->indices.empty()) {
        ctx.note("no triangles", ctx.at(pp),
                 fmt::format("mesh {} primitive {} has no triangles: "
                             "it is not drawn",
                             mesh, prim));
        return ctx.meshes[key] = nullptr;
    }
    return ctx.meshes[key] = std::move(m);
}

}  // namespace spangle::gltf
