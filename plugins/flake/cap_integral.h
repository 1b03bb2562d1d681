#pragma once
// The exact expectation of the discrete flake lobe, integrated directly: the reference the smooth
// lobe's tables are built from and tested against.
//
// A flake of normal m seen from wo reflects into a cone of half-angle gamma around
// r = reflect(wo, m). Flakes are weighted by their projected area towards wo, so the flake that
// lights a direction is distributed as the GGX visible normals (VNDF) of wo, and flakes whose r
// is under the horizon are skipped. With
//
//     I_F(wo, wi) = E_{m ~ VNDF(wo)}[F(wo.m) 1[r(m) within gamma of wi] 1[r(m).z > 0]]
//     V(wo)       = P_{m ~ VNDF(wo)}[r(m).z > 0]
//
// the expected lobe is f_s = c G1(wi) I_F / (sigma cos(theta_i) V), sigma = 4 pi sin^2(gamma/2),
// c the mean flake colour. The set of normals whose reflection falls in the cone is bounded by a
// quadric cone; the VNDF is the image of the cosine-weighted hemisphere under the stretch
// (alpha, alpha, 1) (Heitz 2018), and quadric cones stay quadric cones under linear maps. In the
// unstretched frame the integral is over a convex region bounded by quadrics and planes, done in
// polar coordinates around the preimage of the cone's axis: the radial integral is closed form,
// only the angle is summed (in the parametric angle of the region's tangent ellipse, which keeps
// elongated regions cheap), doubling the steps until the sum settles.

#include "field.h"
#include "palette.h"

namespace spangle::flake {

/** What the integral depends on. */
struct CapParams {
    float alpha = 0.15f;                    ///< GGX roughness of the flake normals
    double sin2_half = 0.0;                 ///< sin^2(gamma / 2), in double
    const FresnelTable* fresnel = nullptr;  ///< null: only I_1
};

/** V(wo) to a relative `tolerance`. */
double valid_fraction_exact(float alpha, V3 wo, double tolerance = 1e-9);

/** I_F (RGB, Fresnel integrated along the region) and I_1 (the same without Fresnel) at
 *  (wo, wi), both zero when either is under the horizon. The angular sum stops when doubling its
 *  steps changes it by less than `tolerance` (relative). */
void cap_integral(const CapParams& p, V3 wo, V3 wi, float i_f[3], float& i_1,
                  double tolerance = 2e-5);

}  // namespace spangle::flake
