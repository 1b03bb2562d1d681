// The systems that make triangle meshes: mesh_load (OBJ and PLY files, and the meshes a scene
// file holds itself) and subdivide (cages refined by OpenSubdiv).

#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>

#include "core/files.h"
#include "geometry/mesh_load.h"
#include "geometry/rest_pose.h"
#include "pipeline/systems.h"
#include "render/camera.h"

namespace spangle {
namespace {

namespace fs = std::filesystem;

/** The mesh in `path` (named at `loc`), from the cache when the file has not changed. */
std::shared_ptr<const TriangleMesh> cached_mesh(World& w, const std::string& path,
                                                const FileLoc& loc) {
    w.read_file("mesh", path);
    return build_cached(
        w.cache, &BuildCache::meshes, "meshes", [&] { return "mesh|" + file_identity(path); },
        [&] {
            auto mesh = std::make_shared<const TriangleMesh>(load_mesh(path, loc));
            // What the reader left out, said once per read of the file.
            if (w.log)
                for (const std::string& note : mesh->notes)
                    w.log->warn("{}: mesh '{}': {}", loc.str(), path, note);
            return mesh;
        },
        "mesh " + path);
}

/** `mesh` (of f.path) with the rest pose in f.rest (geometry/rest_pose.h), cached by both
 *  files' identities so that a reload that changes neither keeps the very same mesh (and its
 *  BVH). */
std::shared_ptr<const TriangleMesh> posed_mesh(World& w, std::shared_ptr<const TriangleMesh> mesh,
                                               const MeshFile& f) {
    const std::shared_ptr<const TriangleMesh> rest = cached_mesh(w, f.rest, f.rest_loc);
    return build_cached(
        w.cache, &BuildCache::meshes, "meshes",
        [&] { return "posed|" + file_identity(f.path) + "|" + file_identity(f.rest); },
        [&] { return with_rest_pose(mesh, *rest, f.loc); }, "");
}

/** The meshes of the mesh files, one per distinct file (and rest pose), referenced from their
 *  objects. */
void load_mesh_files(ecs::Registry& r, World& w, LoadedMeshes& out,
                     std::vector<std::pair<ecs::Entity, uint32_t>>& refs) {
    auto* pool = r.find_pool<MeshFile>();
    if (!pool) return;
    std::map<std::string, uint32_t> loaded;  // one load per distinct file
    // Progress by bytes: the files' sizes (0 for one that cannot be read: its load says why).
    std::map<std::string, double> sizes;
    double total = 0.0, done = 0.0;
    for (const std::string& path : pool->columns().path)
        if (sizes.emplace(path, 0.0).second) {
            std::error_code ec;
            const auto bytes = fs::file_size(path, ec);
            total += sizes[path] = ec ? 0.0 : static_cast<double>(bytes);
        }
    const auto report = [&] {
        if (w.options.work_progress && total > 0.0)
            w.options.work_progress(
                fmt::format("reading {} mesh file{}", sizes.size(), sizes.size() == 1 ? "" : "s"),
                std::min(1.0, done / total));
    };
    report();
    for (std::size_t i = 0; i < pool->size(); ++i) {
        const MeshFile f = pool->columns().get(i);
        // A mesh with a rest pose is its own mesh: the same file without one is shared apart.
        const std::string key = f.rest.empty() ? f.path : f.path + '\n' + f.rest;
        auto it = loaded.find(key);
        if (it == loaded.end()) {
            std::shared_ptr<const TriangleMesh> mesh = cached_mesh(w, f.path, f.loc);
            if (!f.rest.empty()) mesh = posed_mesh(w, std::move(mesh), f);
            out.meshes.push_back(std::move(mesh));
            it = loaded.emplace(key, static_cast<uint32_t>(out.meshes.size() - 1)).first;
            done += sizes[f.path];
            report();
        }
        refs.emplace_back(pool->entities()[i], it->second);
    }
}

bool same_content(const TriangleMesh& a, const TriangleMesh& b) {
    return a.positions == b.positions && a.normals == b.normals && a.uvs == b.uvs &&
           a.colors == b.colors && a.indices == b.indices && a.rest_positions == b.rest_positions;
}

/** An inline mesh, or the equal one the last load used (so that its BVH is reused). */
std::shared_ptr<const TriangleMesh> reuse_inline(World& w, const InlineMesh& m) {
    if (!w.cache) return m.mesh;
    const std::string key = fmt::format("inline|{:016x}", m.content);
    w.cache->used[key] = w.cache->owner;
    auto it = w.cache->meshes.find(key);
    if (it != w.cache->meshes.end() && same_content(*it->second, *m.mesh)) {
        ++w.cache->reused["meshes"];
        return it->second;
    }
    w.cache->meshes[key] = m.mesh;
    return m.mesh;
}

/** The meshes a scene file holds itself, one per distinct mesh (instances share one). */
void take_inline_meshes(ecs::Registry& r, World& w, LoadedMeshes& out,
                        std::vector<std::pair<ecs::Entity, uint32_t>>& refs) {
    auto* pool = r.find_pool<InlineMesh>();
    if (!pool) return;
    std::map<const TriangleMesh*, uint32_t> taken;
    for (std::size_t i = 0; i < pool->size(); ++i) {
        const InlineMesh m = pool->columns().get(i);
        auto it = taken.find(m.mesh.get());
        if (it == taken.end()) {
            out.meshes.push_back(reuse_inline(w, m));
            it = taken.emplace(m.mesh.get(), static_cast<uint32_t>(out.meshes.size() - 1)).first;
        }
        refs.emplace_back(pool->entities()[i], it->second);
    }
}

void system_mesh_load(ecs::Registry& r, World& w) {
    LoadedMeshes out;
    std::vector<std::pair<ecs::Entity, uint32_t>> refs;
    load_mesh_files(r, w, out, refs);
    take_inline_meshes(r, w, out, refs);
    for (const auto& [e, mesh] : refs) r.put(e, TriangleMeshRef{MeshSource::File, mesh});
    w.products.put(std::move(out));
}

/** Whether any surface chooses its level from the camera (then subdivide reads the camera). */
bool levels_from_camera(const ecs::Registry& r) {
    if (const auto* p = r.find_pool<SubdivSurface>())
        for (const SubdivOptions& o : p->columns().options)
            if (o.level < 0) return true;
    return false;
}

/** The level of a surface whose level is chosen from the camera: its longest refined edge about
 *  `pixel_budget` pixels seen from the nearest point of the cage's bounding sphere (pixel_angle
 *  is a pixel's width at distance 1, or on the film of an orthographic camera). */
int camera_level(const Cage& cage, const SubdivSurface& s, const Affine& xf, const Camera& cam,
                 float pixel_angle) {
    Vec3 lo(1e30f), hi(-1e30f);
    for (std::size_t v = 0; v < cage.vertex_count(); ++v) {
        const Vec3 p = xf.apply_point(
            {cage.positions[3 * v], cage.positions[3 * v + 1], cage.positions[3 * v + 2]});
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
    const Vec3 c = (lo + hi) * 0.5f;
    // Orthographic: pixel_angle is a pixel's width itself, at any distance.
    const double dist = cam.ortho_height > 0.0f && !cam.equirect
                            ? 1.0
                            : std::max(1e-3, static_cast<double>(length(c - cam.position) -
                                                                 0.5f * length(hi - lo)));
    return level_for_camera(longest_edge(cage, xf), dist, pixel_angle, s.pixel_budget, s.max_level);
}

/** The cache key of a refinement: the cage file's identity and every option. */
std::string subdiv_key(const std::string& file, const SubdivOptions& o) {
    return fmt::format("subdiv|{}|{}|{}|{}|{}|{}|{}|{}|{}", file, static_cast<int>(o.scheme),
                       static_cast<int>(o.boundary), static_cast<int>(o.uv_interpolation), o.level,
                       fmt::join(o.crease_vertices, ","), fmt::join(o.crease_sharpness, ","),
                       fmt::join(o.corner_vertices, ","), fmt::join(o.corner_sharpness, ","));
}

/** An inline cage, or the equal one the last load used: its key then finds the refinement that
 *  load made, so an identical cage read again is not subdivided again. Equal hashes of unequal
 *  cages (a collision) take the new cage under a key of its own. */
std::shared_ptr<const Cage> reuse_inline_cage(World& w, std::string& key,
                                              const std::shared_ptr<const Cage>& cage) {
    if (!w.cache) return cage;
    const std::string k = "cage|" + key;
    w.cache->used[k] = w.cache->owner;
    auto it = w.cache->cages.find(k);
    if (it == w.cache->cages.end()) {
        w.cache->cages[k] = cage;
        return cage;
    }
    if (same_cage_content(*it->second, *cage)) {
        ++w.cache->reused["cages"];
        return it->second;
    }
    key += fmt::format("|{}", static_cast<const void*>(cage.get()));
    w.cache->cages["cage|" + key] = cage;
    w.cache->used["cage|" + key] = w.cache->owner;
    return cage;
}

/** `mesh`, the refinement (cache key `key`) of `cage`, the cage of surface `s`, with the rest
 *  pose of s.rest refined with the same options (geometry/rest_pose.h): the rest cage must have
 *  the cage's topology, and then its refinement has the mesh's. */
std::shared_ptr<const TriangleMesh> posed_refinement(World& w, const SubdivSurface& s,
                                                     const Cage& cage, const SubdivOptions& options,
                                                     const std::string& key,
                                                     std::shared_ptr<const TriangleMesh> mesh) {
    w.read_file("cage", s.rest);
    const std::string rest_file = w.cache ? file_identity(s.rest) : std::string();
    const std::shared_ptr<const Cage> rest_cage = build_cached(
        w.cache, &BuildCache::cages, "cages", [&] { return "cage|" + rest_file; },
        [&] { return std::make_shared<const Cage>(load_cage(s.rest, s.rest_loc)); }, "");
    check_same_topology(cage, *rest_cage, s.loc);
    const std::shared_ptr<const TriangleMesh> rest = build_cached(
        w.cache, &BuildCache::meshes, "subdivided meshes",
        [&] { return subdiv_key(rest_file, options); },
        [&] {
            return std::make_shared<const TriangleMesh>(subdivide(*rest_cage, options, s.rest_loc));
        },
        fmt::format("subdivision of {} at level {}", s.rest, options.level));
    return build_cached(
        w.cache, &BuildCache::meshes, "subdivided meshes",
        [&] { return "posed|" + key + "|" + rest_file; },
        [&] { return with_rest_pose(mesh, *rest, s.loc); }, "");
}

void system_subdivide(ecs::Registry& r, World& w) {
    auto& pool = r.pool<SubdivSurface>();
    // The camera decides "auto" levels: a far object is not tessellated as finely as a near one.
    const Camera* camera = nullptr;
    Camera cam;
    float pixel_angle = 0.0f;
    if (r.count<Camera>() > 0 && r.count<Film>() > 0) {
        cam = r.pool<Camera>().columns().get(0);
        const Film film = r.pool<Film>().columns().get(0);
        const uint32_t height = w.options.height_override ? w.options.height_override : film.height;
        const uint32_t width = w.options.width_override ? w.options.width_override : film.width;
        // A pixel's width at distance 1 as the renderer's camera makes it (screen window, fov on
        // the shorter side, a panorama's pi / height), or on an orthographic camera's film,
        // the same at every distance.
        const CameraModel model = CameraModel::of(cam, width, height);
        pixel_angle = model.pixel_width() > 0.0f ? model.pixel_width() : model.pixel_angle();
        camera = &cam;
    }
    SubdividedMeshes out;
    std::vector<std::pair<ecs::Entity, uint32_t>> refs;
    for (std::size_t i = 0; i < pool.size(); ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        const SubdivSurface s = pool.columns().get(i);
        const ecs::Entity e = pool.entities()[i];
        std::string file;
        std::shared_ptr<const Cage> cage;
        if (s.cage) {
            file = fmt::format("inline|{:016x}", s.cage_content);
            cage = reuse_inline_cage(w, file, s.cage);
        } else {
            w.read_file("cage", s.path);
            if (w.cache) file = file_identity(s.path);
            cage = build_cached(
                w.cache, &BuildCache::cages, "cages", [&] { return "cage|" + file; },
                [&] {
                    auto loaded = std::make_shared<const Cage>(load_cage(s.path, s.loc));
                    if (loaded->turned_faces > 0 && w.log)
                        w.log->warn(
                            "{}: {} of the {} faces of cage '{}' are wound against their "
                            "neighbours: turned (OpenSubdiv needs one winding; a reversed face "
                            "stayed a flat panel with seams)",
                            s.loc.str(), loaded->turned_faces, loaded->face_count(), s.path);
                    return loaded;
                },
                "");
        }
        SubdivOptions options = s.options;
        SubdivReport rep;
        rep.cage = s.cage ? fmt::format("inline cage at {}", s.loc.str()) : s.path;
        rep.cage_faces = cage->face_count();
        if (options.level < 0) {
            rep.from_camera = true;
            options.level =
                camera ? camera_level(*cage, s, r.get<Transform>(e).to_world, cam, pixel_angle)
                       : s.max_level;
        }
        rep.level = options.level;
        std::shared_ptr<const TriangleMesh> mesh = build_cached(
            w.cache, &BuildCache::meshes, "subdivided meshes",
            [&] { return subdiv_key(file, options); },
            [&] {
                check_subdivision_memory(*cage, options, rep.from_camera, s.loc);
                return std::make_shared<const TriangleMesh>(
                    subdivide(*cage, options, s.loc, w.options.work_progress,
                              fmt::format("subdividing {} at level {}", s.path, options.level)));
            },
            fmt::format("subdivision of {} at level {}", s.path, options.level));
        if (!s.rest.empty())
            mesh = posed_refinement(w, s, *cage, options, subdiv_key(file, options), mesh);
        rep.triangles = mesh->triangle_count();
        out.meshes.push_back(mesh);
        rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        out.reports.push_back(rep);
        refs.emplace_back(e, static_cast<uint32_t>(out.meshes.size() - 1));
    }
    for (const auto& [e, mesh] : refs) r.put(e, TriangleMeshRef{MeshSource::Subdivision, mesh});
    w.products.put(std::move(out));
}

}  // namespace

ecs::System<World> mesh_load_system() {
    return ecs::system<World>("mesh_load", system_mesh_load)
        .needs_any<MeshFile, InlineMesh>()
        .writing<TriangleMeshRef, LoadedMeshes>();
}

ecs::System<World> subdivide_system() {
    // A level chosen from the camera follows the camera, the film and the object's placement.
    return ecs::system<World>("subdivide", system_subdivide)
        .needs_all<SubdivSurface>()
        .reading_if<Camera, Film, Transform>(levels_from_camera)
        .writing<TriangleMeshRef, SubdividedMeshes>();
}

const TriangleMesh& mesh_of(const World& w, const TriangleMeshRef& ref) {
    if (ref.source == MeshSource::File) return *w.products.get<LoadedMeshes>().meshes[ref.mesh];
    return *w.products.get<SubdividedMeshes>().meshes[ref.mesh];
}

}  // namespace spangle
