// The light systems: each kind of light into its own set (area_lights, point_lights,
// environment), and light_selection, which puts every set into one table sized by the scene.

#include <cmath>
#include <map>

#include "core/files.h"
#include "pipeline/environment_load.h"
#include "pipeline/systems.h"
#include "shading/material.h"

namespace spangle {
namespace {

/** Emission images read through the scene's texture service: the colour at a point filtered
 *  over nothing (the finest level, bilinear), times the table's `scale`; non-negative. */
class TexturedEmission final : public EmissionImages {
public:
    TexturedEmission(const TextureService& textures, const ColorConfig& color)
        : textures_(textures) {
        rec709_.init(color);
    }

    /** The index of the image `ref` looks up, opened (through `open`) on its first use: many
     *  objects emitting one image share it. */
    template <class Open>
    uint32_t add(const TextureRef& ref, Open&& open) {
        for (std::size_t i = 0; i < entries_.size(); ++i)
            if (entries_[i].ref == ref) return static_cast<uint32_t>(i);
        entries_.push_back({ref, open()});
        return static_cast<uint32_t>(entries_.size() - 1);
    }

    Vec3 at(uint32_t index, float u, float v) const override {
        thread_local TextureQuery q;
        q.resize(1);
        texture_st(entries_[index].ref, u, v, q.s[0], q.t[0]);
        q.dsdx[0] = q.dtdx[0] = q.dsdy[0] = q.dtdy[0] = 0.0f;
        float out[3] = {0, 0, 0};
        lookup(index, q, 1, out);
        return {out[0], out[1], out[2]};
    }

    /** The luminance of image `index` averaged over each triangle of `mesh` (its uvs; a
     *  mesh without reads the image at (0, 0)): the texture filtered over the triangle's
     *  footprint in the image, at its centroid. */
    std::vector<float> triangle_means(uint32_t index, const TriangleMesh& mesh) const {
        const std::size_t n = mesh.triangle_count();
        TextureQuery q;
        q.resize(n);
        const TextureRef& ref = entries_[index].ref;
        for (std::size_t t = 0; t < n; ++t) {
            float s[3], tt[3];
            for (int k = 0; k < 3; ++k) {
                // Without uvs, uv (0, 0), as at() reads it there.
                const uint32_t i = mesh.indices[3 * t + static_cast<std::size_t>(k)];
                const bool uv = !mesh.uvs.empty();
                texture_st(ref, uv ? mesh.uvs[2 * i] : 0.0f, uv ? mesh.uvs[2 * i + 1] : 0.0f, s[k],
                           tt[k]);
            }
            q.s[t] = (s[0] + s[1] + s[2]) / 3.0f;
            q.t[t] = (tt[0] + tt[1] + tt[2]) / 3.0f;
            q.dsdx[t] = s[1] - s[0];
            q.dtdx[t] = tt[1] - tt[0];
            q.dsdy[t] = s[2] - s[0];
            q.dtdy[t] = tt[2] - tt[0];
        }
        std::vector<float> rgb(3 * n);
        lookup(index, q, n, rgb.data());
        std::vector<float> out(n);
        for (std::size_t t = 0; t < n; ++t)
            out[t] = luminance(Vec3(rgb[3 * t], rgb[3 * t + 1], rgb[3 * t + 2]));
        return out;
    }

private:
    struct Entry {
        TextureRef ref;
        std::shared_ptr<const Texture> tex;
    };

    void lookup(uint32_t index, const TextureQuery& q, std::size_t n, float* out) const {
        const Entry& e = entries_[index];
        try {
            textures_.lookup(*e.tex, e.ref, q, n, 3, out);
        } catch (...) {  // a lookup that failed emits nothing (this runs inside the render)
            std::fill(out, out + 3 * n, 0.0f);
        }
        // A coloured factor (glTF's emissiveFactor, linear Rec.709) multiplies in Rec.709.
        const bool rec709 =
            !Rec709Factor::grey(e.ref.scale) && e.ref.space != "raw" && e.ref.space != "data";
        if (rec709) {
            const Vec3 f(e.ref.scale[0], e.ref.scale[1], e.ref.scale[2]);
            for (std::size_t t = 0; t < n; ++t) {
                const Vec3 v = rec709_.apply(Vec3(out[3 * t], out[3 * t + 1], out[3 * t + 2]), f);
                out[3 * t] = v.x;
                out[3 * t + 1] = v.y;
                out[3 * t + 2] = v.z;
            }
        }
        for (std::size_t i = 0; i < 3 * n; ++i) {
            const float x = rec709 ? out[i] : out[i] * e.ref.scale[i % 3];
            out[i] = x > 0.0f && std::isfinite(x) ? x : 0.0f;
        }
    }

    const TextureService& textures_;
    Rec709Factor rec709_;
    std::vector<Entry> entries_;
};

/** The length of v, in double: a light's edges of 2e10 have a cross product whose square is
 *  beyond a float (its area was inf and its normal 0: the light was dropped without a word). */
float length_of(Vec3 v) {
    return static_cast<float>(
        std::hypot(static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)));
}

/** One emitter per world-space triangle of an emissive mesh, facing its authored normals (or
 *  both ways, when two-sided). */
void add_mesh_emitters(const TriangleMesh& mesh, const Affine& xf, const Emission& emission,
                       uint32_t group, std::vector<AreaEmitter>& out, int32_t image = -1,
                       const std::vector<float>* image_means = nullptr) {
    const Affine nxf = xf.normal_matrix();
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
        if (std::isinf(a.area)) {
            a.area = 0.5f * length_of(c);
            a.n = c / (2.0f * a.area);
        }
        if (!mesh.normals.empty()) {
            // The emitting side follows the authored normals, as shading does.
            Vec3 sum(0.0f);
            for (uint32_t v : {i0, i1, i2})
                sum += Vec3(mesh.normals[3 * v], mesh.normals[3 * v + 1], mesh.normals[3 * v + 2]);
            const Vec3 nw = nxf.apply_vector(sum);
            if (dot(nw, a.n) < 0.0f) a.n = -a.n;
        }
        a.radiance = emission.radiance;
        a.two_sided = emission.two_sided;
        a.group = group;
        if (image >= 0) {
            a.image = image;
            a.image_mean = (*image_means)[t];
            if (!mesh.uvs.empty())
                for (int k = 0; k < 3; ++k) {
                    const uint32_t v = mesh.indices[3 * t + static_cast<std::size_t>(k)];
                    a.uv[2 * k] = mesh.uvs[2 * v];
                    a.uv[2 * k + 1] = mesh.uvs[2 * v + 1];
                }
        }
        out.push_back(a);
    }
}

void system_area_lights(ecs::Registry& r, World& w) {
    AreaLightSet set;
    std::shared_ptr<TexturedEmission> images;
    // Each (mesh, image)'s triangle means, once (instances of one emissive mesh share them).
    std::map<std::pair<const TriangleMesh*, uint32_t>, std::vector<float>> means_of;
    if (auto* emission = r.find_pool<Emission>()) {
        std::vector<std::pair<ecs::Entity, int32_t>> refs;
        for (std::size_t i = 0; i < emission->size(); ++i) {
            const ecs::Entity e = emission->entities()[i];
            if (!r.has<TriangleMeshRef>(e)) continue;
            refs.emplace_back(e, static_cast<int32_t>(set.areas.size()));
            const TriangleMesh& mesh = mesh_of(w, r.get<TriangleMeshRef>(e));
            int32_t image = -1;
            const std::vector<float>* means = nullptr;
            if (r.has<EmissionImage>(e) && w.host) {
                // An emission image: opened (converted to the working space) as a colour
                // texture, and its mean over each triangle for light selection.
                const EmissionImage& ei = r.get<EmissionImage>(e);
                w.read_file("texture", ei.texture.path);
                if (!images)
                    images =
                        std::make_shared<TexturedEmission>(w.host->textures(), w.host->color());
                const uint32_t index = images->add(
                    ei.texture, [&] { return w.host->textures().open(ei.texture, true, ei.loc); });
                image = static_cast<int32_t>(index);
                auto [it, fresh] = means_of.try_emplace({&mesh, index});
                if (fresh) it->second = images->triangle_means(index, mesh);
                means = &it->second;
                if (mesh.uv_mapped_fraction() <= 0.0 && w.log)
                    w.log->warn(
                        "{}: an emission image on mesh '{}', which has no uvs: it emits one "
                        "colour everywhere (the image's lookup at uv (0, 0))",
                        ei.loc.str(), mesh.source);
            }
            add_mesh_emitters(mesh, r.get<Transform>(e).to_world, emission->columns().get(i),
                              light_group(r, e), set.areas, image, means);
        }
        for (const auto& [e, first] : refs) r.put(e, EmitterRef{first});
    }
    set.quad_first = static_cast<uint32_t>(set.areas.size());
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
            if (std::isinf(a.area)) {
                a.area = length_of(c);
                a.n = c / a.area;
            }
            a.radiance = q.radiance;
            a.parallelogram = true;
            a.two_sided = q.two_sided;
            a.transparent = q.transparent;
            a.group = light_group(r, quads->entities()[i]);
            set.areas.push_back(a);
        }
    }
    if (auto* spheres = r.find_pool<SphereLight>())
        for (std::size_t i = 0; i < spheres->size(); ++i) {
            const SphereLight l = spheres->columns().get(i);
            set.spheres.push_back(
                {l.center, l.radius, l.radiance, light_group(r, spheres->entities()[i])});
        }
    set.images = std::move(images);
    w.products.put(std::move(set));
}

/** A light at infinity as the light table samples it. */
DistantEmitter distant_emitter(const DistantLight& d, uint32_t group) {
    DistantEmitter e;
    e.direction = d.direction;
    e.group = group;
    // Below 1e-3 radians (0.0573 degrees; the sun is 0.27) a cone's cosine is 1 to float
    // precision and its sampling breaks down (a radius of 1e-20 rendered black): such a light
    // is its limit, a delta direction with the same irradiance.
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
    return e;
}

void system_point_lights(ecs::Registry& r, World& w) {
    PointLightSet set;
    if (auto* points = r.find_pool<PointLight>())
        for (std::size_t i = 0; i < points->size(); ++i) {
            const PointLight p = points->columns().get(i);
            set.points.push_back({p.position, p.intensity, p.axis, p.cos_outer, p.cos_inner,
                                  light_group(r, points->entities()[i]), p.quartic});
        }
    if (auto* distant = r.find_pool<DistantLight>())
        for (std::size_t i = 0; i < distant->size(); ++i)
            set.distant.push_back(
                distant_emitter(distant->columns().get(i), light_group(r, distant->entities()[i])));
    w.products.put(std::move(set));
}

void system_environment(ecs::Registry& r, World& w) {
    EnvironmentLight env;
    if (auto* pool = r.find_pool<Environment>())
        for (std::size_t i = 0; i < pool->size(); ++i) {
            env.constant += pool->columns().radiance[i];
            env.constant_group = light_group(r, pool->entities()[i]);
        }
    if (auto* maps = r.find_pool<EnvironmentMapFile>())
        for (std::size_t i = 0; i < maps->size(); ++i) {
            const EnvironmentMapFile f = maps->columns().get(i);
            w.read_file("env", f.path);
            env.map = build_cached(
                w.cache, &BuildCache::environments, "environment maps",
                [&] {
                    const auto& m = f.to_map.m;
                    return fmt::format("env|{}|{}|{}|{}|{}|{},{},{},{},{},{},{},{},{}",
                                       file_identity(f.path), f.color_space, f.rotation_deg,
                                       f.intensity, static_cast<int>(f.projection), m[0][0],
                                       m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0],
                                       m[2][1], m[2][2]);
                },
                [&] {
                    return std::make_shared<const EnvironmentMap>(
                        load_environment_map(f, *w.color, w.log));
                },
                "environment map " + f.path);
            env.map_group = light_group(r, maps->entities()[i]);
        }
    w.products.put(std::move(env));
}

void system_light_selection(ecs::Registry&, World& w) {
    SceneLights lights;
    if (const auto* set = w.products.find<AreaLightSet>()) {
        for (const AreaEmitter& a : set->areas) lights.table.add_area(a);
        for (const SphereEmitter& s : set->spheres) lights.table.add_sphere(s);
        lights.table.set_images(set->images);
    }
    if (const auto* set = w.products.find<PointLightSet>()) {
        for (const PointEmitter& p : set->points) lights.table.add_point(p);
        for (const DistantEmitter& d : set->distant) lights.table.add_distant(d);
    }
    if (const auto* env = w.products.find<EnvironmentLight>())
        lights.table.set_environment(env->map, env->map_group);
    // Lights at infinity take their power from the scene's size.
    Vec3 center;
    float radius = 1.0f;
    if (const auto* geometry = w.products.find<SceneGeometry>())
        geometry->accel->bounding_sphere(center, radius);
    lights.table.finalize(std::max(radius, 1e-3f));
    w.products.put(std::move(lights));
}

}  // namespace

uint32_t light_group(const ecs::Registry& r, ecs::Entity e) {
    return r.has<LightGroup>(e) ? r.get<LightGroup>(e).group : 0;
}

ecs::System<World> area_lights_system() {
    // Emissive meshes are placed in world space: their meshes and placements are read too.
    return ecs::system<World>("area_lights", system_area_lights)
        .needs_any<QuadLight, SphereLight, Emission>()
        .reading<LightGroup, Transform, TriangleMeshRef, LoadedMeshes, SubdividedMeshes,
                 EmissionImage>()
        .writing<EmitterRef, AreaLightSet>();
}

ecs::System<World> point_lights_system() {
    return ecs::system<World>("point_lights", system_point_lights)
        .needs_any<PointLight, DistantLight>()
        .reading<LightGroup>()
        .writing<PointLightSet>();
}

ecs::System<World> environment_system() {
    return ecs::system<World>("environment", system_environment)
        .needs_any<Environment, EnvironmentMapFile>()
        .reading<LightGroup>()
        .writing<EnvironmentLight>();
}

ecs::System<World> light_selection_system() {
    // Selection by power: lights at infinity are weighed by the scene's bounds, which take in
    // a moving object's whole sweep (SceneGeometry).
    return ecs::system<World>("light_selection", system_light_selection)
        .needs_any<QuadLight, SphereLight, Emission, PointLight, DistantLight, EnvironmentMapFile>()
        .reading<AreaLightSet, PointLightSet, EnvironmentLight, SceneGeometry>()
        .writing<SceneLights>();
}

}  // namespace spangle
