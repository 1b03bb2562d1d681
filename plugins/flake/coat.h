#pragma once
// The optional clear coat over the flake material: a dielectric interface of index coat_ior,
// smooth or GGX-rough, layered by albedo scaling (Kulla and Conty 2017):
//
//     f = f_coat + (1 - E(wo)) (1 - E(wi)) f_under
//
// E is the coat's directional albedo. The layering never gains energy as long as E(wo) is at
// least the coat's true albedo at wo: then albedo(wo) <= E + (1 - E) * 1. For a smooth coat E is
// the exact Fresnel reflectance, at any angle. For a rough coat E comes from a table over
// sqrt(cos theta) (dense at grazing, node 0 at cos = 1e-6) whose entries are quadratures of the
// single-scattering microfacet reflection, raised by their error bound, and read as the larger of
// the two neighbouring entries (the albedo only grows towards grazing). The table is built once
// per (ior, roughness) on all cores and kept in the persistent table cache (table_cache.h).

#include "field.h"

namespace spangle::flake {

class TableCache;

struct Coat {
    static constexpr int kNodes = 65;
    bool on = false;
    bool smooth = true;         ///< roughness below 1e-4: a delta reflection
    float ior = 1.5f;           ///< index of the coat relative to the outside
    float alpha = 0.0f;         ///< GGX roughness of a rough coat
    float albedo[kNodes] = {};  ///< rough coat: E at cos = max(1e-6, (i / (kNodes - 1))^2)

    void init(bool on_, float ior_, float roughness, const TableCache* cache = nullptr);
    /** E(cos theta): exact for a smooth coat, an upper bound for a rough one; 0 when off. */
    float albedo_at(float cos_theta) const;
    /** A rough coat's f and the density of sample_rough() at wi. */
    void eval_rough(V3 wo, V3 wi, float& f, float& pdf) const;
    /** A rough coat's reflection of a visible normal (u0, u1); false under the horizon. */
    bool sample_rough(V3 wo, float u0, float u1, V3& wi) const;
};

}  // namespace spangle::flake
