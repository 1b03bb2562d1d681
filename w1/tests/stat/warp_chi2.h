#pragma once
// Chi-square of a BSDF's sample() against its pdf() in a warped domain (for the statistical
// tests of every plugin).
//
// Binning. Plain bins on the sphere cannot resolve a GGX lobe of alpha 0.001 (a few milliradians
// wide), so samples are binned in a warped domain: each direction wi is mapped to the microfacet
// normal h that produces it (the half vector; for transmission the generalised half vector of
// Walter et al. 2007), h to its slope divided by alpha (where every alpha looks alike), and the
// slope to log-polar coordinates u1 = L / (L + 2), L = ln(1 + |slope|), u2 = angle / 2 pi. A
// diffuse base lands at large normalised slopes, still well inside (0, 1). The expected count of a
// bin is N times the integral over the bin of pdf(wi(u)) |d wi / d u|, integrated numerically.

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "bsdf_harness.h"
#include "chi2.h"

namespace spangle::test {

/** The warped domain of one test case; lobe 0 = reflection, lobe 1 = transmission. */
struct Warp {
    Vec3 wo;
    float ax, ay;  ///< alphas that normalise the slopes
    float eta;     ///< relative index for the transmission lobe; 0 = reflection only
    static constexpr double kC = 2.0;

    int lobes() const { return eta > 0.0f ? 2 : 1; }

    /** Maps a sampled direction to (lobe, u1, u2); false when it has no place (never, for a
     *  valid sample of a correct BSDF). */
    bool to_u(Vec3 wi, int& lobe, double& u1, double& u2) const {
        Vec3 h;
        if (wi.z > 0.0f) {
            lobe = 0;
            h = normalize(wo + wi);
        } else {
            if (eta <= 0.0f) return false;
            lobe = 1;
            h = normalize(wo + wi * eta);
            if (h.z < 0.0f) h = -h;
        }
        if (h.z <= 0.0f) return false;
        const double tx = -h.x / (static_cast<double>(h.z) * ax),
                     ty = -h.y / (static_cast<double>(h.z) * ay);
        const double r = std::hypot(tx, ty);
        const double l = std::log1p(r);
        u1 = l / (l + kC);
        u2 = std::atan2(ty, tx) / (2.0 * M_PI) + 0.5;
        return true;
    }

    /** Direction at (lobe, u) and the Jacobian |d wi / d u|; false where no direction maps. */
    bool from_u(int lobe, double u1, double u2, Vec3& wi, double& jac) const {
        const double l = kC * u1 / (1.0 - u1);
        const double r = std::expm1(l);
        const double phi = 2.0 * M_PI * (u2 - 0.5);
        const double sx = ax * r * std::cos(phi), sy = ay * r * std::sin(phi);
        const double hz = 1.0 / std::sqrt(1.0 + sx * sx + sy * sy);
        const Vec3 h(static_cast<float>(-sx * hz), static_cast<float>(-sy * hz),
                     static_cast<float>(hz));
        const double cos_oh = dot(wo, h);
        if (cos_oh <= 0.0) return false;
        // |d t / d u| for t = r (cos phi, sin phi): r dr dphi with dr/du1 = (r + 1) c / (1 - u1)^2.
        const double dt_du = r * (r + 1.0) * kC / ((1.0 - u1) * (1.0 - u1)) * 2.0 * M_PI;
        const double dh_dt = hz * hz * hz * ax * ay;  // solid angle of h per unit normalised slope
        double dwi_dh;
        if (lobe == 0) {
            wi = h * static_cast<float>(2.0 * cos_oh) - wo;
            if (wi.z <= 0.0f) return false;
            dwi_dh = 4.0 * cos_oh;
        } else {
            const double sin2_t = (1.0 - cos_oh * cos_oh) / (static_cast<double>(eta) * eta);
            if (sin2_t >= 1.0) return false;
            const double cos_t = std::sqrt(1.0 - sin2_t);
            wi = normalize(wo * static_cast<float>(-1.0 / eta) +
                           h * static_cast<float>(cos_oh / eta - cos_t));
            if (wi.z >= 0.0f) return false;
            const double denom = dot(wi, h) + cos_oh / eta;
            dwi_dh = denom * denom / std::fabs(static_cast<double>(dot(wi, h)));
        }
        jac = dwi_dh * dh_dt * dt_du;
        return std::isfinite(jac);
    }
};

/** Bins per axis and lobe of warped_chi2(). */
constexpr int kWarpBins = 24;

/** Chi-square of `n` samples of the prepared harness against its pdf in the warped domain. When
 *  `dump` is not empty and the test fails at `significance`, writes the histograms to
 *  chi2_<dump>.txt. `total` receives the pdf's integral over the domain. */
inline Chi2Result warped_chi2(const BsdfHarness& bsdf, const Warp& warp, uint32_t n, uint64_t seed,
                              double significance, const std::string& dump, double& total) {
    constexpr int kBins = kWarpBins;
    const int lobes = warp.lobes();
    const std::size_t cells = static_cast<std::size_t>(lobes) * kBins * kBins;
    // Observed: the last cell counts invalid samples.
    std::vector<double> observed(cells + 1, 0.0);
    for (const auto& s : bsdf.sample(n, seed)) {
        int lobe;
        double u1, u2;
        if (s.flags == 0 || !warp.to_u(s.wi, lobe, u1, u2)) {
            observed[cells] += 1.0;  // a valid sample outside the domain would fail the test here
            continue;
        }
        const auto b1 = std::min(kBins - 1, static_cast<int>(u1 * kBins));
        const auto b2 = std::min(kBins - 1, static_cast<int>(u2 * kBins));
        observed[static_cast<std::size_t>((lobe * kBins + b1) * kBins + b2)] += 1.0;
    }

    // Expected: integrate the pdf over each bin with a midpoint rule, refined in bins that the
    // domain's validity boundary (the horizon, total internal reflection) may cut through.
    std::vector<double> expected(cells + 1, 0.0);
    std::vector<Vec3> wi;
    std::vector<double> jac;
    std::vector<std::size_t> cell_of;
    const auto integrate = [&](int lobe, int b1, int b2, int sub) {
        for (int i = 0; i < sub; ++i)
            for (int j = 0; j < sub; ++j) {
                const double u1 = (b1 + (i + 0.5) / sub) / kBins,
                             u2 = (b2 + (j + 0.5) / sub) / kBins;
                Vec3 w;
                double J;
                if (!warp.from_u(lobe, u1, u2, w, J)) continue;
                wi.push_back(w);
                jac.push_back(J / (static_cast<double>(sub) * sub * kBins * kBins));
                cell_of.push_back(static_cast<std::size_t>((lobe * kBins + b1) * kBins + b2));
            }
    };
    for (int lobe = 0; lobe < lobes; ++lobe)
        for (int b1 = 0; b1 < kBins; ++b1)
            for (int b2 = 0; b2 < kBins; ++b2) {
                const std::size_t before = wi.size();
                integrate(lobe, b1, b2, 8);
                const std::size_t valid = wi.size() - before;
                // A bin not entirely valid may be cut by the boundary, possibly in a sliver the
                // coarse probe missed: redo it finely.
                if (valid != 64) {
                    wi.resize(before);
                    jac.resize(before);
                    cell_of.resize(before);
                    integrate(lobe, b1, b2, 48);
                }
            }
    std::vector<Vec3> f;
    std::vector<float> pdf;
    bsdf.eval(wi, f, pdf);
    total = 0.0;
    for (std::size_t k = 0; k < wi.size(); ++k) {
        const double p = static_cast<double>(pdf[k]) * jac[k];
        expected[cell_of[k]] += n * p;
        total += p;
    }
    expected[cells] = std::max(0.0, n * (1.0 - total));

    const Chi2Result r = chi2_test(observed, expected);
    if (!dump.empty() && !(r.p_value > significance)) {
        std::ofstream out("chi2_" + dump + ".txt");
        out << "# lobe b1 b2 observed expected; last line: invalid samples\n";
        for (std::size_t k = 0; k < cells; ++k)
            out << k / (kBins * kBins) << ' ' << (k / kBins) % kBins << ' ' << k % kBins << ' '
                << observed[k] << ' ' << expected[k] << '\n';
        out << "invalid " << observed[cells] << ' ' << expected[cells] << '\n';
    }
    return r;
}

}  // namespace spangle::test
