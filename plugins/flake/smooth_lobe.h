#pragma once
// The smooth flake lobe: the expectation of the discrete lobe over flake realisations (see
// cap_integral.h for its definition), fast enough for every shading point.
//
//     f_s(wo, wi) = c G1(wi) F_blur(wo, wi) rho(wo, wi) / (cos(theta_i) V(wo))
//     rho = I_1 / sigma = p(wi) A(wi) R(wo, wi),   p(wi) = G1(wo) D(h) / (4 cos(theta_o))
//
// p is the density of mirror directions of visible GGX normals (the lobe of an infinitely
// narrow cone), A the share of wi's cone above the horizon (flakes reflecting under it are
// skipped; closed form) and R the ratio the cone's blur multiplies the rest by. R and the blurred
// Fresnel (as a ratio to F(wo.h)) are tabulated at create() from the exact integral
// (slope_integral.h), for every view angle at once, against the view angle and the half vector's
// slope (in units of alpha, compactified so that the table reaches infinity, where R = 1); R is
// read bicubically, the Fresnel ratios bilinearly. Each view angle's table, and the table halfway
// between two view angles as eval interpolates it, is scaled so that its integral over wi equals
// the exact one (lobe_mass): the smooth lobe never gains energy, whatever the interpolation error.
// V is tabulated exactly. The lobe is sampled with a GGX of widened roughness (closed-form pdf):
// the density reported is always exactly the density sampled.

#include <cstdint>
#include <memory>
#include <vector>

#include "cap_integral.h"

namespace spangle::flake {

class TableCache;

/** The blur table of one (alpha, gamma, Fresnel): n_o view angles x n_y x n_x compactified
 *  half-vector slopes, four floats per node (R and the blurred Fresnel's ratio to F(wo.h) per
 *  channel), and the mass corrections between view angles. Read-only once built. */
struct BlurTable {
    float alpha = 0.15f, kappa = 0.0f, sigma = 0.0f;
    double sin2_half = 0.0;
    int n_o = 0, n_x = 0, n_y = 0;
    std::vector<float> data;  ///< node k, row j, column i: 4 floats at ((k n_y + j) n_x + i) 4
    /** Mass corrections at view-node positions 0, 1/2, 1, ... (index 2 k is node k, 1 there). */
    std::vector<float> correction;
    const float* node(int k) const { return &data[static_cast<std::size_t>(k) * n_x * n_y * 4]; }
};

/** Constants and tables of the smooth lobe of one material. Read-only after init(). */
struct SmoothLobe {
    static constexpr int kValidNodes = 257;
    float alpha = 0.15f;     ///< GGX roughness of the flake normals
    double sin2_half = 0.0;  ///< sin^2(gamma / 2), in double (gamma may be 0.01 degrees)
    float sigma = 0.0f;      ///< solid angle of the cone, 4 pi sin^2(gamma / 2)
    float kappa = 0.0f;      ///< tan(gamma / 2) / alpha: the cone's reach in half-vector slope
    bool blur_negligible = false;           ///< gamma << alpha: R = 1 to 1e-4
    const FresnelTable* fresnel = nullptr;  ///< not owned
    float valid[kValidNodes] = {};          ///< V at cos_o = i / (kValidNodes - 1) (0: at 1e-7)
    /** The blur table (null when the blur is negligible), shared by materials with the same
     *  roughness, cone and Fresnel. */
    std::shared_ptr<const BlurTable> table;
    /** Where the tables came from, for --stats and the tests. */
    bool from_cache = false;
    double build_ms = 0.0;  ///< time spent building (0 when read from the cache)

    /** Sets the constants and builds (or reads from `cache`, when given and enabled) V and the
     *  blur table for every view angle. */
    void init(float alpha_, float gamma_rad, const FresnelTable* fresnel_,
              const TableCache* cache = nullptr);
    /** V(wo) by linear interpolation in cos(theta_o). */
    float valid_fraction(float cos_o) const;
    /** R and the Fresnel ratios at a view angle and a half vector h in wo's azimuthal frame
     *  (wo in the xz-plane, h.y >= 0). */
    void blur(float cos_o, V3 h, float out[4]) const;
    /** The widened roughness (along and across wo's plane) sample_smooth() uses. */
    void proposal_alpha(float cos_o, float& ax, float& ay) const;
    /** V and the blur table as bytes (the disk cache's payload), and back; unpack() is false
     *  (leaving the lobe unusable until rebuilt) when the bytes do not fit this lobe. */
    std::vector<uint8_t> pack() const;
    bool unpack(const std::vector<uint8_t>& bytes);
};

/** Builds the blur table of (alpha, gamma, fresnel) from the exact integral, every view angle,
 *  on up to `threads` threads (the result does not depend on their number). */
std::shared_ptr<BlurTable> build_blur_table(float alpha, double sin2_half,
                                            const FresnelTable& fresnel, int threads);

/** The smooth lobe at wi: f (RGB per unit flake colour, without G1(wi) and the colour) and the
 *  density of sample_smooth(), which integrates to at most 1 (samples under the horizon fail).
 *  v_o is lobe.valid_fraction(wo.z). */
void eval_smooth(const SmoothLobe& lobe, V3 wo, float v_o, V3 wi, float f[3], float& pdf);

/** A direction from the widened GGX (u0, u1): its visible normal's mirror direction. False when
 *  it falls under the horizon. */
bool sample_smooth(const SmoothLobe& lobe, V3 wo, float u0, float u1, V3& wi);

/** The fraction of a cone of half-angle gamma around r (r.z >= 0) that lies above the horizon. */
double cone_fraction_above(double r_z, double sin2_half);

}  // namespace spangle::flake
