#include "render/systems.h"

#include <chrono>
#include <cmath>
#include <map>

#include "core/files.h"
#include "core/memory.h"
#include "geometry/mesh_load.h"
#include "render/environment_load.h"
#include "render/integrator.h"

namespace spangle {

ecs::Schedule<World> make_frame_schedule() {
    ecs::Schedule<World> s;
    s.add<MeshFile>("mesh_load", ecs::RunWhen::AllPresent, system_mesh_load);
    s.add<SubdivSurface>("subdivide", ecs::RunWhen::AllPresent, system_subdivide);
    s.add<MaterialRef>("materials", ecs::RunWhen::AllPresent, system_materials);
    s.add<QuadLight, SphereLight, Emission>("area_lights", ecs::RunWhen::AnyPresent,
                                            system_area_lights);
    s.add<PointLight, DistantLight>("point_lights", ecs::RunWhen::AnyPresent, system_point_lights);
    s.add<Environment, EnvironmentMapFile>("environment", ecs::RunWhen::AnyPresent,
                                           system_environment);
    s.add<TriangleMeshRef, QuadLight, SphereLight>("accelerate", ecs::RunWhen::AnyPresent,
                                                   system_accelerate);
    s.add<QuadLight, SphereLight, Emission, PointLight, DistantLight, EnvironmentMapFile>(
        "light_selection", ecs::RunWhen::AnyPresent, system_light_selection);
    s.add<Camera, Film>("render", ecs::RunWhen::AllPresent, system_render);
    return s;
}

void system_mesh_load(ecs::Registry& r, World& w) {
    auto& pool = r.pool<MeshFile>();
    std::map<std::string, uint32_t> loaded;  // one load per distinct file
    std::vector<std::pair<ecs::Entity, uint32_t>> refs;
    for (std::size_t i = 0; i < pool.size(); ++i) {
        const std::string& path = pool.columns().path[i];
        auto it = loaded.find(path);
        if (it == loaded.end()) {
            w.geometry.meshes.push_back(build_cached(
                w.cache, &BuildCache::meshes, "meshes",
                [&] { return "mesh|" + file_identity(path); },
                [&] {
                    return std::make_shared<const TriangleMesh>(
                        load_mesh(path, pool.columns().loc[i]));
                },
                "mesh " + path));
            it = loaded.emplace(path, static_cast<uint32_t>(w.geometry.meshes.size() - 1)).first;
        }
        refs.emplace_back(pool.entities()[i], it->second);
    }
    for (const auto& [e, mesh] : refs) r.put(e, TriangleMeshRef{mesh});
    w.mesh_file_count = static_cast<uint32_t>(w.geometry.meshes.size());
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
        pixel_angle =
            2.0f * std::tan(0.5f * cam.fov_deg * kPi / 180.0f) / static_cast<float>(height);
        camera = &cam;
    }
    std::vector<std::pair<ecs::Entity, uint32_t>> refs;
    for (std::size_t i = 0; i < pool.size(); ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        const SubdivSurface s = pool.columns().get(i);
        const ecs::Entity e = pool.entities()[i];
        const std::string file = w.cache ? file_identity(s.path) : std::string();
        const std::shared_ptr<const Cage> cage_ptr = build_cached(
            w.cache, &BuildCache::cages, "cages", [&] { return "cage|" + file; },
            [&] { return std::make_shared<const Cage>(load_cage(s.path, s.loc)); }, "");
        const Cage& cage = *cage_ptr;
        SubdivOptions options = s.options;
        SubdivReport rep;
        rep.cage = s.path;
        rep.cage_faces = cage.face_count();
        if (options.level < 0) {
            rep.from_camera = true;
            options.level = s.max_level;
            if (camera) {
                const Affine xf = r.get<Transform>(e).to_world;
                // Distance from the eye to the nearest point of the cage's bounding sphere.
                Vec3 lo(1e30f), hi(-1e30f);
                for (std::size_t v = 0; v < cage.vertex_count(); ++v) {
                    const Vec3 p = xf.apply_point({cage.positions[3 * v], cage.positions[3 * v + 1],
                                                   cage.positions[3 * v + 2]});
                    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
                    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
                }
                const Vec3 c = (lo + hi) * 0.5f;
                const double dist = std::max(
                    1e-3, static_cast<double>(length(c - cam.position) - 0.5f * length(hi - lo)));
                options.level = level_for_camera(longest_edge(cage, xf), dist, pixel_angle,
                                                 s.pixel_budget, s.max_level);
            }
        }
        rep.level = options.level;
        const std::shared_ptr<const TriangleMesh> mesh = build_cached(
            w.cache, &BuildCache::meshes, "subdivided meshes",
            [&] {
                return fmt::format(
                    "subdiv|{}|{}|{}|{}|{}|{}|{}|{}|{}", file, static_cast<int>(options.scheme),
                    static_cast<int>(options.boundary), static_cast<int>(options.uv_interpolation),
                    options.level, fmt::join(options.crease_vertices, ","),
                    fmt::join(options.crease_sharpness, ","),
                    fmt::join(options.corner_vertices, ","),
                    fmt::join(options.corner_sharpness, ","));
            },
            [&] {
                check_subdivision_memory(cage, options, rep.from_camera, s.loc);
                return std::make_shared<const TriangleMesh>(subdivide(cage, options, s.loc));
            },
            fmt::format("subdivision of {} at level {}", s.path, options.level));
        rep.triangles = mesh->triangle_count();
        w.geometry.meshes.push_back(mesh);
        rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        w.subdiv.push_back(rep);
        refs.emplace_back(e, static_cast<uint32_t>(w.geometry.meshes.size() - 1));
    }
    for (const auto& [e, mesh] : refs) r.put(e, TriangleMeshRef{mesh});
}

void system_materials(ecs::Registry& r, World& w) {
    const auto& names = w.info->material_names;
    std::vector<bool> used(names.size(), false);
    for (uint32_t m : r.pool<MaterialRef>().columns().material) used[m] = true;
    w.materials.clear();
    w.materials.resize(names.size());
    const auto& pool = r.pool<Material>();
    for (std::size_t i = 0; i < pool.size(); ++i) {
        const Material m = pool.columns().get(i);
        std::size_t index = 0;
        while (names[index] != m.name) ++index;
        if (!used[index]) {
            // Nothing uses it: its plugin is not opened (only what the scene needs runs).
            w.log->warn("{}: material '{}' is not used by any object", m.loc.str(), m.name);
            continue;
        }
        // Keyed by the plugin library's identity too: a rebuilt plugin makes new instances.
        w.materials[index] = build_cached(
            w.cache, &BuildCache::materials, "materials",
            [&] {
                const std::shared_ptr<LoadedPlugin> plugin =
                    w.plugins->open(m.plugin, m.plugin_loc);
                std::string key = fmt::format("material|{}|{}|{}|{}", m.name, m.plugin, m.model,
                                              file_identity(plugin->path()));
                for (const ParamList* list : {&m.params, &m.maps})
                    for (const ParamEntry& p : *list) {
                        key += fmt::format("|{}:{}:{}:{}:{}:{}:{}", p.name,
                                           static_cast<int>(p.kind), p.number[0], p.number[1],
                                           p.number[2], p.is_integer, p.text);
                        // A texture: how it is looked up, and the file's identity (an edited
                        // image makes a new material).
                        if (p.kind != ParamEntry::Kind::Texture) continue;
                        const TextureRef& t = p.texture;
                        key += fmt::format(":{}:{}:{}:{}:{}", file_identity(t.path), t.space,
                                           fmt::join(t.scale, ","), fmt::join(t.uv, ","), t.wrap);
                        key += fmt::format(":{}:{}", t.amount, t.filter);
                    }
                return key;
            },
            [&] { return create_material(*w.plugins, m, *w.host); },
            fmt::format("material '{}'", m.name));
    }
    warn_about_missing_uvs(r, w);
}

void warn_about_missing_uvs(ecs::Registry& r, World& w) {
    // A material that lays a pattern out in uv (SPANGLE_REQUIRES_UV) loses it on a mesh without
    // usable uvs: say so, naming the object, rather than render it silently without.
    auto& refs = r.pool<MaterialRef>();
    for (std::size_t i = 0; i < refs.size(); ++i) {
        const ecs::Entity e = refs.entities()[i];
        const MaterialInstance* mat = w.materials[refs.columns().material[i]].get();
        if (!mat || !r.has<TriangleMeshRef>(e)) continue;
        // Textures and normal or bump maps are laid out in uv too.
        const bool textured = !mat->textures().empty() || mat->map_kind() != MapKind::None;
        const bool plugin_needs =
            mat->model().requirements &&
            (mat->model().requirements(mat->instance()) & SPANGLE_REQUIRES_UV);
        if (!textured && !plugin_needs) continue;
        const TriangleMesh& mesh = w.geometry.mesh(r.get<TriangleMeshRef>(e).mesh);
        const double mapped = mesh.uv_mapped_fraction();
        if (mapped >= 0.5) continue;
        const ObjectInfo info = r.has<ObjectInfo>(e) ? r.get<ObjectInfo>(e) : ObjectInfo{};
        w.log->warn(
            "{}: object {}(mesh {}) has {}; material '{}' lays {} out in uv and will render "
            "without {} there{}",
            info.loc.str(), info.name.empty() ? std::string() : fmt::format("'{}' ", info.name),
            mesh.source,
            mesh.uvs.empty() ? std::string("no uvs")
                             : fmt::format("degenerate uvs ({:.0f}% of its area maps to no uv "
                                           "area)",
                                           100.0 * (1.0 - mapped)),
            mat->name(), textured ? "its textures" : "its pattern", textured ? "them" : "it",
            plugin_needs ? " (for flakes, density_space = \"object\" or \"auto\" places them "
                           "by object-space position instead)"
                         : "");
    }
}

namespace {

/** The light group of entity e (every light entity has one from the loader). */
uint32_t light_group(ecs::Registry& r, ecs::Entity e) {
    return r.has<LightGroup>(e) ? r.get<LightGroup>(e).group : 0;
}

}  // namespace

void system_area_lights(ecs::Registry& r, World& w) {
    // Emissive meshes: one emitter per world-space triangle.
    if (auto* emission = r.find_pool<Emission>()) {
        std::vector<std::pair<ecs::Entity, int32_t>> refs;
        for (std::size_t i = 0; i < emission->size(); ++i) {
            const ecs::Entity e = emission->entities()[i];
            if (!r.has<TriangleMeshRef>(e)) continue;
            const TriangleMesh& mesh = w.geometry.mesh(r.get<TriangleMeshRef>(e).mesh);
            const Affine xf = r.get<Transform>(e).to_world;
            const Affine nxf = xf.normal_matrix();
            const uint32_t group = light_group(r, e);
            refs.emplace_back(e, static_cast<int32_t>(w.lights.area_count()));
            for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
                const uint32_t i0 = mesh.indices[3 * t], i1 = mesh.indices[3 * t + 1],
                               i2 = mesh.indices[3 * t + 2];
                AreaEmitter a;
                a.p0 = xf.apply_point(mesh.position(i0));
                a.e1 = xf.apply_point(mesh.position(i1)) - a.p0;
                a.e2 = xf.apply_point(mesh.position(i2)) - a.p0;
                const Vec3 c = cross(a.e1, a.e2);
                a.area = 0.5f * length(c);
                a.n = a.area > 0.0f ? normalize(c) : Vec3(0, 0, 1);
                if (!mesh.normals.empty()) {
                    // The emitting side follows the authored normals, as shading does.
                    Vec3 sum(0.0f);
                    for (uint32_t v : {i0, i1, i2})
                        sum += Vec3(mesh.normals[3 * v], mesh.normals[3 * v + 1],
                                    mesh.normals[3 * v + 2]);
                    const Vec3 nw = nxf.apply_vector(sum);
                    if (dot(nw, a.n) < 0.0f) a.n = -a.n;
                }
                a.radiance = emission->columns().radiance[i];
                a.group = group;
                w.lights.add_area(a);
            }
        }
        for (const auto& [e, first] : refs) r.put(e, EmitterRef{first});
    }
    w.quad_light_first = static_cast<uint32_t>(w.lights.area_count());
    if (auto* quads = r.find_pool<QuadLight>()) {
        for (std::size_t i = 0; i < quads->size(); ++i) {
            const QuadLight q = quads->columns().get(i);
            AreaEmitter a;
            a.p0 = q.corner;
            a.e1 = q.edge1;
            a.e2 = q.edge2;
            const Vec3 c = cross(q.edge1, q.edge2);
            a.area = length(c);
            a.n = normalize(c);
            a.radiance = q.radiance;
            a.parallelogram = true;
            a.two_sided = q.two_sided;
            a.group = light_group(r, quads->entities()[i]);
            w.lights.add_area(a);
            w.quad_vertices.insert(
                w.quad_vertices.end(),
                {q.corner, q.corner + q.edge1, q.corner + q.edge1 + q.edge2, q.corner + q.edge2});
        }
    }
    if (auto* spheres = r.find_pool<SphereLight>()) {
        for (std::size_t i = 0; i < spheres->size(); ++i) {
            const SphereLight l = spheres->columns().get(i);
            w.lights.add_sphere(
                {l.center, l.radius, l.radiance, light_group(r, spheres->entities()[i])});
            w.sphere_lights.insert(w.sphere_lights.end(),
                                   {l.center.x, l.center.y, l.center.z, l.radius});
        }
    }
}

void system_point_lights(ecs::Registry& r, World& w) {
    if (auto* points = r.find_pool<PointLight>())
        for (std::size_t i = 0; i < points->size(); ++i) {
            const PointLight p = points->columns().get(i);
            w.lights.add_point({p.position, p.intensity, p.axis, p.cos_outer, p.cos_inner,
                                light_group(r, points->entities()[i])});
        }
    if (auto* distant = r.find_pool<DistantLight>())
        for (std::size_t i = 0; i < distant->size(); ++i) {
            const DistantLight d = distant->columns().get(i);
            DistantEmitter e;
            e.direction = d.direction;
            e.group = light_group(r, distant->entities()[i]);
            // Below 1e-3 radians (0.057 degrees; the sun is 0.27) a cone's cosine is 1 to float
            // precision and its sampling breaks down (a radius of 1e-20 rendered black): such a
            // light is its limit, a delta direction with the same irradiance.
            const float rad = d.angular_radius_deg * kPi / 180.0f;
            if (rad >= 1e-3f) {
                const float half = std::sin(0.5f * rad);
                e.cos_radius = std::cos(rad);
                e.solid_angle = 4.0f * kPi * half * half;  // 2 pi (1 - cos r) without cancellation
                // A disk of uniform radiance L gives irradiance L pi sin^2 r at normal incidence.
                const float s = std::sin(rad);
                e.radiance = d.irradiance * (1.0f / (kPi * s * s));
            } else {
                e.radiance = d.irradiance;
            }
            w.lights.add_distant(e);
        }
}

void system_environment(ecs::Registry& r, World& w) {
    w.environment = Vec3(0.0f);
    if (auto* pool = r.find_pool<Environment>())
        for (std::size_t i = 0; i < pool->size(); ++i) {
            w.environment += pool->columns().radiance[i];
            w.environment_group = light_group(r, pool->entities()[i]);
        }
    if (auto* maps = r.find_pool<EnvironmentMapFile>())
        for (std::size_t i = 0; i < maps->size(); ++i) {
            const EnvironmentMapFile f = maps->columns().get(i);
            if (!w.cache) {  // one frame: no copy of the map
                w.lights.set_environment(load_environment_map(f, *w.color),
                                         light_group(r, maps->entities()[i]));
                continue;
            }
            const auto env = build_cached(
                w.cache, &BuildCache::environments, "environment maps",
                [&] {
                    return fmt::format("env|{}|{}|{}|{}", file_identity(f.path), f.color_space,
                                       f.rotation_deg, f.intensity);
                },
                [&] {
                    return std::make_shared<const EnvironmentMap>(
                        load_environment_map(f, *w.color));
                },
                "environment map " + f.path);
            w.lights.set_environment(*env, light_group(r, maps->entities()[i]));
        }
}

void system_accelerate(ecs::Registry& r, World& w) {
    w.instances.clear();
    if (auto* meshes = r.find_pool<TriangleMeshRef>()) {
        for (std::size_t i = 0; i < meshes->size(); ++i) {
            const ecs::Entity e = meshes->entities()[i];
            Instance inst;
            inst.mesh = meshes->columns().mesh[i];
            inst.material = r.get<MaterialRef>(e).material;
            inst.to_world = r.get<Transform>(e).to_world;
            inst.normal_to_world = inst.to_world.normal_matrix();
            inst.to_object = inst.to_world.inverse();
            if (r.has<EmitterRef>(e)) inst.emitter = r.get<EmitterRef>(e).first;
            if (r.has<Motion>(e)) inst.motion = r.get<Motion>(e).steps;
            if (r.has<ObjectInfo>(e)) inst.object = r.get<ObjectInfo>(e).index;
            w.instances.push_back(inst);
        }
    }
    // A watch session hands the live scene's EmbreeScene over: build() reuses the bottom-level
    // structure of every mesh it already has and rebuilds only the top level.
    if (!w.accel) {
        // A first build: the BVH (Embree's, with its build-time peak) takes about 150 bytes per
        // triangle on top of the meshes already loaded. (A watch session's rebuilds reuse most.)
        double triangles = 0.0;
        for (const auto& m : w.geometry.meshes)
            triangles += static_cast<double>(m->triangle_count());
        constexpr double kBvhBytesPerTriangle = 150.0;
        if (const uint64_t have = memory_short_for(triangles * kBvhBytesPerTriangle))
            throw_error(
                "the scene's {:.0f} triangles need about {} more for the ray-tracing "
                "structure, but only {} of memory is available: lower subdivision levels "
                "or use meshes with fewer triangles",
                triangles, format_bytes(triangles * kBvhBytesPerTriangle),
                format_bytes(static_cast<double>(have)));
        w.accel = std::make_shared<EmbreeScene>();
    }
    w.accel->build(w.geometry, w.instances, w.quad_vertices, w.sphere_lights);
    if (w.cache) {
        if (w.accel->blas_reused() > 0) w.cache->reused["mesh BVHs"] += w.accel->blas_reused();
        if (w.accel->blas_built() > 0)
            w.cache->built.push_back(fmt::format("{} mesh BVH{}", w.accel->blas_built(),
                                                 w.accel->blas_built() == 1 ? "" : "s"));
        w.cache->built.push_back("top-level BVH");
    }
}

void system_light_selection(ecs::Registry&, World& w) {
    Vec3 center;
    float radius = 1.0f;
    if (w.accel) w.accel->bounding_sphere(center, radius);
    w.lights.finalize(std::max(radius, 1e-3f));
}

void system_render(ecs::Registry& r, World& w) {
    const auto& cams = r.pool<Camera>();
    const auto& films = r.pool<Film>();
    Film film = films.columns().get(0);
    if (w.options.width_override) film.width = w.options.width_override;
    if (w.options.height_override) film.height = w.options.height_override;
    const ecs::Entity settings = cams.entities()[0];
    const std::vector<Camera> steps =
        r.has<CameraMotion>(settings) ? r.get<CameraMotion>(settings).steps : std::vector<Camera>{};
    render_image(w, cams.columns().get(0), film, steps);
}

}  // namespace spangle
