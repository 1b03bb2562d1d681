#include "thin_film.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "../common/microfacet.h"
#include "../common/plugin_support.h"

namespace spangle::flake {

using namespace spangle::plugin_support;
using C = std::complex<double>;

namespace {

/** Amplitude reflection coefficients (s, p) of the interface from medium i to medium j, from
 *  q = n cos(theta) of each side (Snell's invariant sin(theta_1) = n sin(theta) in air). */
void interface_r(C n_i, C q_i, C n_j, C q_j, C& rs, C& rp) {
    rs = (q_i - q_j) / (q_i + q_j);
    const C a = n_j * n_j * q_i, b = n_i * n_i * q_j;
    rp = (a - b) / (a + b);
}

}  // namespace

double airy_reflectance(double cos_i, double lambda_nm, double d_nm, double n_film, C n_sub) {
    const double c = std::clamp(cos_i, 0.0, 1.0);
    const double s2 = 1.0 - c * c;
    const C n1(1.0, 0.0), n2(n_film, 0.0);
    const C q1(c, 0.0), q2 = std::sqrt(n2 * n2 - s2), q3 = std::sqrt(n_sub * n_sub - s2);
    C r12s, r12p, r23s, r23p;
    interface_r(n1, q1, n2, q2, r12s, r12p);
    interface_r(n2, q2, n_sub, q3, r23s, r23p);
    // The round trip through the film: phase 4 pi d n2 cos(theta_2) / lambda.
    const C e = std::exp(C(0.0, 4.0 * M_PI * d_nm / lambda_nm) * q2);
    const C rs = (r12s + r23s * e) / (1.0 + r12s * r23s * e);
    const C rp = (r12p + r23p * e) / (1.0 + r12p * r23p * e);
    return 0.5 * (std::norm(rs) + std::norm(rp));
}

namespace {

/** The flake's material as a complex index per Rec.709 channel. */
void substrate(const SpangleParams_v3* p, C out[3]) {
    const std::string kind = param_string(p, "fresnel");
    if (kind == "dielectric") {
        for (int c = 0; c < 3; ++c) out[c] = C(param_number(p, "flake_ior"), 0.0);
        return;
    }
    if (kind == "schlick") {
        // The dielectric of the same normal-incidence reflectance: f0 = ((n - 1) / (n + 1))^2.
        const double r = std::sqrt(std::clamp(param_number(p, "flake_f0"), 0.0, 0.999999));
        for (int c = 0; c < 3; ++c) out[c] = C((1.0 + r) / (1.0 - r), 0.0);
        return;
    }
    const std::string preset = param_string(p, "preset");
    for (const auto& mp : mf::kMetalPresets)
        if (preset == mp.name) {
            for (int c = 0; c < 3; ++c) out[c] = C(mp.eta[c], mp.k[c]);
            return;
        }
    // "perfect": a conductor of vanishing skin depth (|r| = 1 at every angle).
    for (int c = 0; c < 3; ++c) out[c] = C(0.0, 1e4);
}

}  // namespace

bool build_film(FilmTables& film, FresnelTable& mean, const SpangleParams_v3* p,
                const SpangleHost_v3* host, std::string& why) {
    film.levels.clear();
    const double d_max = param_number(p, "film_thickness_max");
    const double d_min = param_number(p, "film_thickness_min");
    // A minimum alone asks for a film that the maximum's 0 (no film) would drop silently.
    if (d_max <= 0.0 && d_min > 0.0) {
        char text[160];
        std::snprintf(text, sizeof(text),
                      "film_thickness_min is %g nm but film_thickness_max is 0 (no film): give "
                      "film_thickness_max too",
                      d_min);
        why = text;
        return false;
    }
    if (d_max <= 0.0) return true;
    if (d_min > d_max) {
        char text[160];
        std::snprintf(text, sizeof(text),
                      "film_thickness_min (%g nm) must not exceed film_thickness_max (%g nm)",
                      d_min, d_max);
        why = text;
        return false;
    }
    float to_working[9];
    if (!rec709_to_working(host, to_working, why)) return false;
    C sub[3];
    substrate(p, sub);
    const double n_film = param_number(p, "film_ior");
    constexpr double kCentre[3] = {630.0, 532.0, 465.0}, kStep = 15.0;
    film.levels.resize(FilmTables::kLevels);
    std::vector<double> sum(3 * FresnelTable::kNodes, 0.0);
    for (int l = 0; l < FilmTables::kLevels; ++l) {
        const double d = d_min + (d_max - d_min) * (l + 0.5) / FilmTables::kLevels;
        FresnelTable& t = film.levels[static_cast<std::size_t>(l)];
        for (int i = 0; i < FresnelTable::kNodes; ++i) {
            const double cos_i = static_cast<double>(i) / (FresnelTable::kNodes - 1);
            float f[3];
            for (int c = 0; c < 3; ++c) {
                double r = 0.0;
                for (int w = 0; w < FilmTables::kWavelengths; ++w) {
                    const double lambda =
                        kCentre[c] + kStep * (w - 0.5 * (FilmTables::kWavelengths - 1));
                    r += airy_reflectance(cos_i, lambda, d, n_film, sub[c]);
                }
                f[c] = static_cast<float>(r / FilmTables::kWavelengths);
            }
            for (int r = 0; r < 3; ++r) {
                t.rgb[i][r] = std::clamp(to_working[3 * r] * f[0] + to_working[3 * r + 1] * f[1] +
                                             to_working[3 * r + 2] * f[2],
                                         0.0f, 1.0f);
                sum[static_cast<std::size_t>(3 * i + r)] += static_cast<double>(t.rgb[i][r]);
            }
        }
    }
    for (int i = 0; i < FresnelTable::kNodes; ++i)
        for (int r = 0; r < 3; ++r)
            mean.rgb[i][r] =
                static_cast<float>(sum[static_cast<std::size_t>(3 * i + r)] / FilmTables::kLevels);
    return true;
}

}  // namespace spangle::flake
