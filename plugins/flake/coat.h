#pragma once
// The optional clear coat over the flake material: a dielectric interface of index coat_ior,
// smooth or GGX-rough, layered by albedo scaling (Kulla and Conty 2017):
//
//     f = f_coat + (1 - E(wo)) (1 - E(wi)) f_under
//
// with the diffuse base's part of f_under divided by 1 - E_avg (E_avg the cosine-weighted
// average of E): the light the coat reflects back down onto a diffuse base comes out again after
// bounces between them, so a white base under a coat reflects everything, as the smooth plugin's
// plastic does (it reflected 0.91: the inter-reflection was lost). The flakes' part keeps single
// scattering: their light the coat sends back down is lost (a few per cent at most), which keeps
// every glint where it is and the layering from ever gaining energy.
// E is the coat's directional albedo. The layering never gains energy as long as E(wo) is at
// least the coat's true albedo at wo: then albedo(wo) <= E + (1 - E) * 1. For a smooth coat E is
// the exact Fresnel reflectance, at any angle. For a rough coat E comes from a table over
// sqrt(cos theta) (dense at grazing, node 0 at cos = 1e-6) whose entries are quadratures of the
// single-scattering microfacet reflection, raised by their error bound, and read as the larger of
// the two neighbouring entries (the albedo only grows towards grazing). The table is built once
// per (ior, roughness) on all cores and kept in the persistent table cache (table_cache.h).

#include <mutex>

#include "field.h"
#include "table_cache.h"

namespace spangle::flake {

struct Coat {
    static constexpr int kNodes = 65;
    bool on = false;
    bool smooth = true;         ///< roughness below 1e-4: a delta reflection
    float ior = 1.5f;           ///< index of the coat relative to the outside
    float alpha = 0.0f;         ///< GGX roughness of a rough coat
    float albedo[kNodes] = {};  ///< rough coat: E at cos = max(1e-6, (i / (kNodes - 1))^2)
    /** The cosine-weighted average of albedo_at() over the hemisphere, 2 int E(mu) mu dmu: the
     *  share of a diffuse base's light the coat sends back down (0 when off). */
    float e_avg = 0.0f;

    void init(bool on_, float ior_, float roughness, const TableCache* cache = nullptr);
    /** Sets e_avg from albedo_at() (on, with its table filled). */
    void set_average();
    /** Its GGX roughness, 0 for a smooth coat (a delta reflection). */
    float roughness() const { return smooth ? 0.0f : alpha; }
    /** 1 / (1 - e_avg): what the diffuse base's part is divided by (1 when off). */
    float base_gain() const { return on ? 1.0f / (1.0f - e_avg) : 1.0f; }
    /** E(cos theta): exact for a smooth coat, an upper bound for a rough one; 0 when off. */
    float albedo_at(float cos_theta) const;
    /** A rough coat's f and the density of sample_rough() at wi. */
    void eval_rough(V3 wo, V3 wi, float& f, float& pdf) const;
    /** A rough coat's reflection of a visible normal (u0, u1); false under the horizon. */
    bool sample_rough(V3 wo, float u0, float u1, V3& wi) const;
};

/** Rough versions of a coat for path regularisation (the host's roughness floor): one per
 *  level of kLevels, each made on first use (its albedo table is a few tens of milliseconds, or
 *  a read from the table cache) so that a scene that never asks for a floor never pays for it. A
 *  floor is rounded up to the next level: never sharper than the host asks. */
class CoatFloors {
public:
    static constexpr int kCount = 3;
    static constexpr float kLevels[kCount] = {0.125f, 0.25f, 0.5f};

    /** `own`: the material's coat (its ior, and the roughness a floor must exceed to matter),
     *  which must outlive this; `cache`: where the tables are kept between processes. */
    CoatFloors(const Coat& own, const TableCache& cache);
    /** The coat a point with GGX floor `floor` uses: `own` when the floor does not exceed its
     *  roughness, else the rough coat of the level at or above the floor. */
    const Coat& at(float floor) const;

private:
    const Coat& own_;
    TableCache cache_;
    mutable std::once_flag once_[kCount];
    mutable Coat coats_[kCount];
};

}  // namespace spangle::flake
