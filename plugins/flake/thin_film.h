#pragma once
// Interference flakes: a thin transparent film on each flake (pearlescent paint, holographic
// glitter). A flake's reflectance is the Airy reflectance of the film (index film_ior, thickness
// d) over the flake's own material, at the angle of incidence on the flake, so its colour shifts
// with the view. Each flake draws its thickness from [film_thickness_min, film_thickness_max] by
// its own hash, one of kLevels stratified thicknesses, so the discrete lobe's expected Fresnel is
// exactly the mean of the kLevels tables, which the smooth lobe is built from.
//
// Spectral to RGB: each channel is the mean reflectance at kWavelengths wavelengths spaced 15 nm
// around the Rec.709 primary's dominant wavelength (630, 532, 465 nm: where the metal presets'
// indices are given), with equal weights, so a channel is a convex combination of spectral
// reflectances and never exceeds 1; the Rec.709 result is carried into the working space as the
// metal presets are (clamped to [0, 1]).

#include <spangle/plugin.h>

#include <complex>
#include <cstdint>
#include <string>
#include <vector>

#include "field.h"
#include "palette.h"

namespace spangle::flake {

/** The Fresnel tables of flakes with a film, one per thickness level (empty: no film). */
struct FilmTables {
    static constexpr int kLevels = 64;
    static constexpr int kWavelengths = 5;
    std::vector<FresnelTable> levels;
    /** The table of the flake whose own hash is `id`: its level, each equally likely; `bare`
     *  without a film. */
    /** Whether flakes carry films (each its own table); else every flake has `bare`. */
    bool varies() const { return !levels.empty(); }
    const FresnelTable& pick(uint64_t id, const FresnelTable& bare) const {
        if (levels.empty()) return bare;
        return levels[static_cast<std::size_t>(mix(id, 0xf11b) >> 58)];
    }
};
static_assert(FilmTables::kLevels == 64, "pick() takes the top 6 bits of a hash");

/** Reflectance (unpolarised, the mean of s and p) of a film of index n_film and thickness
 *  d_nm over a substrate of complex index n_sub (k > 0 absorbing), from air, at cos_i of the
 *  angle of incidence and wavelength lambda_nm: the Airy sum of the film's multiple reflections
 *  (Born and Wolf 1999, 1.6.4). d = 0 or n_film = 1 give the substrate's own Fresnel
 *  reflectance. */
double airy_reflectance(double cos_i, double lambda_nm, double d_nm, double n_film,
                        std::complex<double> n_sub);

/** Builds the film's tables from `film_thickness_min`, `film_thickness_max`, `film_ior` and the
 *  flake's material (`fresnel`, `preset`, `flake_ior`, `flake_f0`; Schlick flakes are taken as
 *  the dielectric of the same f0), and sets `mean` to their mean. Nothing when the film is off
 *  (film_thickness_max = 0). False with `why` on bad parameters or a colour failure. */
bool build_film(FilmTables& film, FresnelTable& mean, const SpangleParams_v3* p,
                const SpangleHost_v3* host, std::string& why);

}  // namespace spangle::flake
