#pragma once
// pbrt's spectra in RGB: sampled spectra and blackbodies integrated against the CIE 1931
// colour-matching functions into linear Rec.709, and the named spectra of pbrt-v4 (metals,
// glasses, standard illuminants) as the nearest thing Spangle's models take.

#include <optional>
#include <string>
#include <vector>

#include "core/math.h"

namespace spangle::pbrt {

/** Linear Rec.709 RGB of a spectrum given as (lambda nm, value) pairs, linear between samples
 *  and constant beyond them: XYZ = integral S(l) xyz(l) dl / integral y(l) dl, 360 to 830 nm. */
Vec3 sampled_spectrum_rgb(const std::vector<double>& lambda_value_pairs);

/** The same spectrum as a reflectance (a ratio, not light): seen under the working white (D65),
 *  by Bradford adaptation from equal energy, so that a flat spectrum is grey of its value. */
Vec3 reflectance_spectrum_rgb(const std::vector<double>& lambda_value_pairs);

/** CIE XYZ -> linear Rec.709 (D65 white), IEC 61966-2-1. */
Vec3 xyz_to_rec709(Vec3 xyz);

/** The value of a (lambda nm, value) spectrum at `nm`, linear between samples. */
double spectrum_at(const std::vector<double>& lambda_value_pairs, double nm);

/** Linear Rec.709 RGB of a blackbody at `kelvin`, its spectrum scaled so that its peak is 1 (as
 *  pbrt-v3's "blackbody" [T scale] is before its scale). */
Vec3 blackbody_rgb(double kelvin);

/** `rgb` scaled so that its Rec.709 luminance is 1 (pbrt-v4 normalises light spectra so); black
 *  stays black. */
Vec3 unit_luminance(Vec3 rgb);

/** A named metal of pbrt-v4 ("metal-Cu-eta" / "metal-Cu-k" name the same metal). */
struct NamedMetal {
    std::string preset;     ///< the smooth conductor's preset, or "custom"
    Vec3 eta, k;            ///< with "custom": the index per Rec.709 band
    bool stand_in = false;  ///< no published data here: the nearest metal stands in
};

/** The metal `name` names (its -eta or -k spectrum), or none when it is no metal of pbrt-v4. */
std::optional<NamedMetal> named_metal(const std::string& name);

/** The index of refraction at the d line (587.6 nm) of pbrt-v4's named glass, or none. */
std::optional<double> named_glass_ior(const std::string& name);

/** Linear Rec.709 RGB (unit luminance) of pbrt-v4's named illuminant, or none; `exact` is false
 *  where a blackbody of its correlated colour temperature stands in. */
std::optional<Vec3> named_illuminant(const std::string& name, bool& exact);

}  // namespace spangle::pbrt
