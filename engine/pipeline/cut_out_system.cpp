// The cut-outs system: for each instance whose material has an alpha, what the ray tracer asks
// whether a ray crossing one of its triangles meets it there (EmbreeScene's CutOut).

#include "pipeline/systems.h"

namespace spangle {
namespace {

float coverage(const void* self, uint32_t prim, float b1, float b2) {
    const auto* c = static_cast<const AlphaCoverage*>(self);
    return alpha_at(c->material->alpha(), *c->mesh, prim, b1, b2);
}

void system_cut_outs(ecs::Registry&, World& w) {
    CutOutSet out;
    const SceneGeometry* g = w.products.find<SceneGeometry>();
    const MaterialSet* m = w.products.find<MaterialSet>();
    if (g && m) {
        out.per_instance.resize(g->instances.size());
        bool any = false;
        for (std::size_t i = 0; i < g->instances.size(); ++i) {
            const Instance& inst = g->instances[i];
            if (inst.material >= m->instances.size() || inst.mesh >= g->geometry.meshes.size())
                continue;
            const std::shared_ptr<MaterialInstance>& mat = m->instances[inst.material];
            if (!mat || !mat->alpha().active) continue;
            const AlphaMap& a = mat->alpha();
            // A constant alpha the cutoff passes whole, or 1, is opaque: no filter to run.
            if (!a.texels && (a.value >= 1.0f || (a.cutoff >= 0.0f && a.value >= a.cutoff)))
                continue;
            auto c = std::make_unique<AlphaCoverage>();
            c->material = mat;
            c->mesh = g->geometry.meshes[inst.mesh];
            out.per_instance[i] = CutOut{coverage, c.get(), a.cutoff};
            out.coverage.push_back(std::move(c));
            any = true;
            // An emitting instance: its light is cut where its surface is (light sampling
            // weighs each point by the share of rays that meet it there).
            if (inst.emitter >= 0) {
                const auto first = static_cast<std::size_t>(inst.emitter);
                const std::size_t count = g->geometry.meshes[inst.mesh]->triangle_count();
                if (out.emitters.size() < first + count) out.emitters.resize(first + count);
                for (std::size_t t = 0; t < count; ++t)
                    out.emitters[first + t] = {static_cast<int32_t>(i), static_cast<uint32_t>(t)};
            }
        }
        if (!any) out.per_instance.clear();  // nothing cut (the emitters' table is empty too)
    }
    w.products.put(std::move(out));
}

}  // namespace

ecs::System<World> cut_outs_system() {
    return ecs::system<World>("cut_outs", system_cut_outs)
        .needs_all<AlphaCutOut>()
        .reading<SceneGeometry, MaterialSet>()
        .writing<CutOutSet>();
}

}  // namespace spangle
