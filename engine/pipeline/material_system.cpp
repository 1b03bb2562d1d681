// The materials system: one plugin instance per [[material]] that an object uses, and a warning
// for objects whose material lays a pattern out in uv on a mesh without usable uvs.

#include <algorithm>
#include <filesystem>

#include <map>
#include <set>

#include "core/files.h"
#include "geometry/rest_pose.h"
#include "pipeline/systems.h"

namespace spangle {
namespace {

/** The cache key of a material: its name, plugin, model, the plugin library's identity (a
 *  rebuilt plugin makes new instances) and every parameter as written, textures by file. */
std::string material_key(const World& w, const Material& m) {
    const std::shared_ptr<LoadedPlugin> plugin = w.plugins->open(m.plugin, m.plugin_loc);
    std::string key = fmt::format("material|{}|{}|{}|{}", m.name, m.plugin, m.model,
                                  file_identity(plugin->path()));
    for (const ParamList* list : {&m.params, &m.maps})
        for (const ParamEntry& p : *list) {
            key += fmt::format("|{}:{}:{}:{}:{}:{}:{}", p.name, static_cast<int>(p.kind),
                               p.number[0], p.number[1], p.number[2], p.is_integer, p.text);
            // A texture: how it is looked up, and the file's identity (an edited image makes
            // a new material).
            if (p.kind != ParamEntry::Kind::Texture) continue;
            const TextureRef& t = p.texture;
            key += fmt::format(":{}:{}:{}:{}:{}", file_identity(t.path), t.space,
                               fmt::join(t.scale, ","), fmt::join(t.uv, ","), t.wraps());
            key += fmt::format(":{}:{}:{}:{}", t.amount, t.filter, t.channel, t.vertex_color);
        }
    return key;
}

/** Warns about materials that read vertex colours none of their meshes has (they read 1). */
void warn_about_missing_colors(const ecs::Registry& r, const World& w, const MaterialSet& set) {
    const auto& refs = *r.find_pool<MaterialRef>();
    std::vector<int> state(set.instances.size(), 0);  // 1: reads them, 2: some mesh has them
    for (std::size_t m = 0; m < set.instances.size(); ++m)
        if (const MaterialInstance* mat = set.instances[m].get())
            for (const TextureBinding& t : mat->textures())
                if (t.ref.vertex_color) state[m] = 1;
    // Said at the first object that wears the material (it had no place).
    std::vector<std::string> where(set.instances.size());
    for (std::size_t i = 0; i < refs.size(); ++i) {
        const uint32_t m = refs.columns().material[i];
        const ecs::Entity e = refs.entities()[i];
        if (m < state.size() && state[m] == 1 && where[m].empty() && r.has<ObjectInfo>(e))
            if (const std::string at = r.get<ObjectInfo>(e).loc.str(); !at.empty())
                where[m] = at + ": ";
        if (m < state.size() && state[m] == 1 && r.has<TriangleMeshRef>(e) &&
            !mesh_of(w, r.get<TriangleMeshRef>(e)).colors.empty())
            state[m] = 2;
    }
    for (std::size_t m = 0; m < state.size(); ++m)
        if (state[m] == 1 && w.log)
            w.log->warn(
                "{}material '{}' reads vertex colours (vertex_color), but none of its "
                "meshes has any: it reads 1 (white) everywhere",
                where[m], set.instances[m]->name());
}

/** Warns about objects whose material needs uvs their mesh lacks. */
void warn_about_missing_uvs(const ecs::Registry& r, const World& w, const MaterialSet& set) {
    // A material that lays a pattern out in uv (SPANGLE_REQUIRES_UV) loses it on a mesh without
    // usable uvs: say so, naming the object, rather than render it silently without.
    const auto& refs = *r.find_pool<MaterialRef>();
    for (std::size_t i = 0; i < refs.size(); ++i) {
        const ecs::Entity e = refs.entities()[i];
        const MaterialInstance* mat = set.instances[refs.columns().material[i]].get();
        if (!mat || !r.has<TriangleMeshRef>(e)) continue;
        // Textures and normal or bump maps are laid out in uv too.
        const bool textured =
            std::any_of(mat->textures().begin(), mat->textures().end(),
                        [](const TextureBinding& t) { return t.texture != nullptr; }) ||
            mat->map_kind() != MapKind::None || mat->alpha().texels != nullptr;
        const bool plugin_needs =
            mat->model().requirements &&
            (mat->model().requirements(mat->instance()) & SPANGLE_REQUIRES_UV);
        if (!textured && !plugin_needs) continue;
        const TriangleMesh& mesh = mesh_of(w, r.get<TriangleMeshRef>(e));
        const double mapped = mesh.uv_mapped_fraction();
        if (mapped >= 0.5) continue;
        const ObjectInfo info = r.has<ObjectInfo>(e) ? r.get<ObjectInfo>(e) : ObjectInfo{};
        // Without uvs each triangle takes (0, 0), (1, 0), (0, 1) at its corners: a texture is
        // repeated per triangle, not laid out; a uv pattern (flakes) gets no layout at all.
        w.log->warn(
            "{}: object {}(mesh {}) has {}; material '{}' lays {} out in uv and will render {} "
            "there{}",
            info.loc.str(), info.name.empty() ? std::string() : fmt::format("'{}' ", info.name),
            mesh.source,
            mesh.uvs.empty() ? std::string("no uvs")
                             : fmt::format("degenerate uvs ({:.0f}% of its area maps to no uv "
                                           "area)",
                                           100.0 * (1.0 - mapped)),
            mat->name(), textured ? "its textures" : "its pattern",
            textured ? (mesh.uvs.empty()
                            ? "them once per triangle (corners at uv (0, 0), (1, 0), (0, 1))"
                            : "them stretched or flat")
                     : "without it",
            plugin_needs ? " (for flakes, density_space = \"object\" or \"auto\" places them "
                           "by object-space position instead)"
                         : "");
    }
}

/** Warns, once per material, about meshes whose rest pose (a deforming mesh's, or a glTF skin's
 *  or morph's written shape) leaves triangles without area where the material lays its pattern
 *  out in object space: they get none of it (flakes: a patch without glitter). Said by the
 *  material that loses it: the mesh system said it of every posed mesh, whatever its material,
 *  once per glTF primitive and naming the file. */
void warn_about_flat_rest_poses(const ecs::Registry& r, const World& w, const MaterialSet& set) {
    if (!w.log) return;
    const auto& refs = *r.find_pool<MaterialRef>();
    std::set<std::pair<const MaterialInstance*, const TriangleMesh*>> seen;
    struct Found {
        std::size_t meshes = 0;
        std::string first;
    };
    std::map<const MaterialInstance*, Found> found;
    std::vector<const MaterialInstance*> order;
    for (std::size_t i = 0; i < refs.size(); ++i) {
        const ecs::Entity e = refs.entities()[i];
        const MaterialInstance* mat = set.instances[refs.columns().material[i]].get();
        if (!mat || !mat->model().requirements || !r.has<TriangleMeshRef>(e)) continue;
        const uint32_t req = mat->model().requirements(mat->instance());
        if (!(req & (SPANGLE_REQUIRES_OBJECT_SPACE | SPANGLE_REQUIRES_OBJECT_SPACE_WITHOUT_UV)))
            continue;
        const TriangleMesh& mesh = mesh_of(w, r.get<TriangleMeshRef>(e));
        if (mesh.rest_positions.empty() || !seen.insert({mat, &mesh}).second) continue;
        if (!(req & SPANGLE_REQUIRES_OBJECT_SPACE) && mesh.uv_mapped_fraction() >= 0.5) continue;
        const std::size_t flat = flat_in_rest_pose(mesh);
        if (!flat) continue;
        Found& f = found[mat];
        if (f.meshes++ == 0) {
            order.push_back(mat);
            const ObjectInfo info = r.has<ObjectInfo>(e) ? r.get<ObjectInfo>(e) : ObjectInfo{};
            f.first = fmt::format(
                "{}: object {}(mesh {}): {} of the {} triangles have no area in the rest pose",
                info.loc.str(), info.name.empty() ? std::string() : fmt::format("'{}' ", info.name),
                mesh.source, flat, mesh.triangle_count());
        }
    }
    for (const MaterialInstance* mat : order) {
        const Found& f = found[mat];
        w.log->warn(
            "{}; material '{}' lays its pattern out there, in object space, and those triangles "
            "get none of it (no flakes: a patch without glitter){}",
            f.first, mat->name(),
            f.meshes > 1 ? fmt::format(" ({} more meshes of this material alike)", f.meshes - 1)
                         : std::string());
    }
}

void system_materials(ecs::Registry& r, World& w) {
    const auto& names = w.info->material_names;
    std::vector<bool> used(names.size(), false);
    for (uint32_t m : r.pool<MaterialRef>().columns().material) used[m] = true;
    MaterialSet set;
    set.instances.resize(names.size());
    const auto& pool = r.pool<Material>();
    const auto count = static_cast<std::size_t>(std::count(used.begin(), used.end(), true));
    std::size_t made_so_far = 0;
    std::set<std::string> plugins_seen;  // each plugin's file is looked at once
    for (std::size_t i = 0; i < pool.size(); ++i) {
        const Material m = pool.columns().get(i);
        std::size_t index = 0;
        while (names[index] != m.name) ++index;
        if (!used[index]) {
            // Nothing uses it: its plugin is not opened (only what the scene needs runs).
            if (!m.quiet_unused)
                w.log->warn("{}: material '{}' is not used by any object", m.loc.str(), m.name);
            continue;
        }
        set.instances[index] = build_cached(
            w.cache, &BuildCache::materials, "materials", [&] { return material_key(w, m); },
            [&] {
                // A plugin may take seconds here (the flake plugin builds its tables): the
                // progress names the material, so a slow one is seen while it is made.
                const std::string what = fmt::format("making material '{}' (plugin {}, {} of {})",
                                                     m.name, m.plugin, made_so_far + 1, count);
                if (w.options.work_progress) w.options.work_progress(what, 0.0);
                auto made = create_material(*w.plugins, m, *w.host);
                if (w.options.work_progress) w.options.work_progress(what, 1.0);
                return made;
            },
            fmt::format("material '{}'", m.name));
        ++made_so_far;
        // An edited plugin library or texture makes the material anew.
        const MaterialInstance& made = *set.instances[index];
        w.read_file("plugin", made.plugin().path());
        if (plugins_seen.insert(m.plugin).second) {
            // A reload that opened a plugin from another file than the live scene's, that file
            // gone (a build folder's library removed, a later folder's copy taken): said, not
            // silent.
            const std::filesystem::path now(made.plugin().path());
            if (w.previous && w.log)
                if (const auto sys = w.previous->files.find(w.system);
                    sys != w.previous->files.end())
                    for (const auto& [old_path, read] : sys->second) {
                        const std::filesystem::path was(old_path);
                        std::error_code ec;
                        if (read.kind == "plugin" && was.filename() == now.filename() &&
                            was != now && !std::filesystem::exists(was, ec))
                            w.log->warn("plugin '{}': {} is gone; opened {} instead", m.plugin,
                                        old_path, now.string());
                    }
            // And where a library would be found before it, absent now (a developer's build
            // folder given by --plugin-path whose library was removed, a copy beside the binary
            // taken instead): putting it back there reloads (it was ignored, and every rebuild
            // of it). Watched, not hashed into the scene (kAbsentPluginKind).
            for (const std::string& before : w.plugins->searched_before(m.plugin, now.string()))
                w.read_file(kAbsentPluginKind, before);
        }
        for (const TextureBinding& t : made.textures())
            if (!t.ref.path.empty()) w.read_file("texture", t.ref.path);
        if (made.map_kind() != MapKind::None) w.read_file("texture", made.map().ref.path);
        if (!made.alpha().ref.path.empty()) w.read_file("texture", made.alpha().ref.path);
    }
    warn_about_missing_uvs(r, w, set);
    warn_about_flat_rest_poses(r, w, set);
    warn_about_missing_colors(r, w, set);
    w.products.put(std::move(set));
}

}  // namespace

ecs::System<World> materials_system() {
    // The uv check reads the meshes too, but only to warn: a mesh edit does not remake materials.
    return ecs::system<World>("materials", system_materials)
        .needs_all<MaterialRef>()
        .reading<Material>()
        .writing<MaterialSet>();
}

}  // namespace spangle
