#pragma once
// The expectation of the discrete flake lobe (cap_integral.h defines it) computed in the slope
// plane of the flake normals, fast enough to fill the smooth lobe's tables in milliseconds and to
// evaluate the lobe directly where a table would need too many nodes.
//
// A normal m is written through its slope in units of alpha, t = (m_x, m_y) / (alpha m_z), so
// that m is proportional to M = (alpha t, 1). In these coordinates the visible-normal measure of
// wo is (Heitz 2014, eq. 2; the slope density of GGX)
//
//     dP = G1(wo) / wo_z (wo.M) dt / (pi (1 + |t|^2)^2),
//
// and both conditions on a flake are conics: "r(m) lies within gamma of wi" is
// 2 (wo.M)(wi.M) - (wo.wi + cos gamma) |M|^2 >= 0 and "r(m) is above the horizon" is
// 2 (wo.M) - wo_z |M|^2 >= 0 (which implies wo.m > 0, so visibility needs no test). Along a ray
// t = rho e from the origin (the normal itself) each conic is a quadratic in rho and the radial
// integral of dP is closed form; only the angle of e is summed: Gauss-Legendre over the arc of
// directions that meet the region (its ends, where the rays are tangent to the conic, with the
// substitution phi = c + h sin(theta) that removes their square-root singularity), split where
// the horizon takes over from the cone as the bound, or the periodic trapezoid rule when the
// region contains the origin. Fresnel is averaged along each ray at two mass quantiles.

#include "field.h"
#include "palette.h"

namespace spangle::flake {

/** 3-point Gauss-Legendre on [0, 1]: nodes and weights (the table integrals' inner rule). */
inline constexpr double kGauss3Nodes[3] = {0.112701665379258311, 0.5, 0.887298334620741689};
inline constexpr double kGauss3Weights[3] = {0.277777777777777778, 0.444444444444444444,
                                             0.277777777777777778};

/** I_F (RGB, Fresnel-weighted; zero without `fresnel`) and I_1 at (wo, wi), the same quantities
 *  as cap_integral(): the visible-normal probability that a flake reflects wo within gamma of wi
 *  and above the horizon. Zero when wo or wi is under the horizon. Relative accuracy about 1e-4
 *  (tests/stat/test_flake_tables.cpp holds it against a brute force of the definition and
 *  against cap_integral, which it beats where they differ: cones 100 times narrower or 400
 *  times wider than the flake lobe, grazing views). */
void slope_integral(float alpha, double sin2_half, const FresnelTable* fresnel, V3 wo, V3 wi,
                    float i_f[3], float& i_1);

/** M(wo) = E[A(r.z) 1[r.z > 0]] over wo's visible normals, r their mirror directions and A the
 *  share of a cone of half-angle gamma around r above the horizon: the exact mass of the smooth
 *  lobe over wi before Fresnel and shadowing. To about 1e-8 relative. */
double lobe_mass(float alpha, double sin2_half, V3 wo);

}  // namespace spangle::flake
