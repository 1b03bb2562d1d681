#include "scene/pbrt/pbrt_spectra.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace spangle::pbrt {

namespace {

/** A lobe of the piecewise Gaussian fit: its width left and right of the peak differ. */
double lobe(double l, double mu, double left, double right) {
    const double t = (l - mu) / (l < mu ? left : right);
    return std::exp(-0.5 * t * t);
}

/** The CIE 1931 2-degree colour-matching functions by the multi-lobe fit of Wyman, Sloan and
 *  Shirley 2013 ("Simple Analytic Approximations to the CIE XYZ Color Matching Functions",
 *  JCGT 2(2)), within about 1% of the tables over the visible range. */
std::array<double, 3> cie_xyz(double l) {
    const double x = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) -
                     0.065 * lobe(l, 501.1, 20.4, 26.2);
    const double y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
    const double z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
    return {x, y, z};
}

/** CIE XYZ -> linear Rec.709 (D65 white), IEC 61966-2-1. */
Vec3 xyz_to_rec709(double x, double y, double z) {
    return {static_cast<float>(3.2404542 * x - 1.5371385 * y - 0.4985314 * z),
            static_cast<float>(-0.9692660 * x + 1.8760108 * y + 0.0415560 * z),
            static_cast<float>(0.0556434 * x - 0.2040259 * y + 1.0572252 * z)};
}

/** XYZ of the spectrum s(lambda), 1 nm steps over 360..830 nm, normalised by the integral of y. */
template <class S>
std::array<double, 3> integrate_xyz(const S& s) {
    double x = 0, y = 0, z = 0, norm = 0;
    for (int i = 360; i <= 830; ++i) {
        const double l = i;
        const std::array<double, 3> c = cie_xyz(l);
        const double v = s(l);
        x += v * c[0];
        y += v * c[1];
        z += v * c[2];
        norm += c[1];
    }
    return {x / norm, y / norm, z / norm};
}

/** Linear Rec.709 of the spectrum s(lambda) as light (no white adaptation). */
template <class S>
Vec3 integrate(const S& s) {
    const std::array<double, 3> c = integrate_xyz(s);
    return xyz_to_rec709(c[0], c[1], c[2]);
}

/** Planck's law: spectral radiance at wavelength `nm` of a blackbody at `kelvin` (W/m^3/sr). */
double planck(double nm, double kelvin) {
    constexpr double c = 299792458.0, h = 6.62606957e-34, kb = 1.3806488e-23;
    const double l = nm * 1e-9;
    return (2.0 * h * c * c) / (std::pow(l, 5) * (std::exp((h * c) / (l * kb * kelvin)) - 1.0));
}

}  // namespace

Vec3 xyz_to_rec709(Vec3 xyz) {
    return xyz_to_rec709(static_cast<double>(xyz.x), static_cast<double>(xyz.y),
                         static_cast<double>(xyz.z));
}

double spectrum_at(const std::vector<double>& pairs, double l) {
    const std::size_t n = pairs.size() / 2;
    if (n == 0) return 0.0;
    if (l <= pairs[0]) return pairs[1];
    for (std::size_t i = 1; i < n; ++i)
        if (l <= pairs[2 * i]) {
            const double l0 = pairs[2 * i - 2], l1 = pairs[2 * i];
            const double t = l1 > l0 ? (l - l0) / (l1 - l0) : 1.0;
            return pairs[2 * i - 1] + t * (pairs[2 * i + 1] - pairs[2 * i - 1]);
        }
    return pairs[2 * n - 1];
}

Vec3 sampled_spectrum_rgb(const std::vector<double>& pairs) {
    if (pairs.size() < 2) return Vec3(0.0f);
    return integrate([&](double l) { return spectrum_at(pairs, l); });
}

Vec3 reflectance_spectrum_rgb(const std::vector<double>& pairs) {
    if (pairs.size() < 2) return Vec3(0.0f);
    // A reflectance is a ratio, seen under the working space's white (D65), as pbrt-v4 takes it:
    // XYZ under equal energy, adapted to D65 by the Bradford transform (a flat spectrum is then
    // grey; as light, integrate() above, a flat spectrum is the pinkish equal-energy white).
    const std::array<double, 3> c = integrate_xyz([&](double l) { return spectrum_at(pairs, l); });
    static const std::array<double, 3> e = integrate_xyz([](double) { return 1.0; });
    static constexpr double kBradford[3][3] = {
        {0.8951, 0.2664, -0.1614}, {-0.7502, 1.7135, 0.0367}, {0.0389, -0.0685, 1.0296}};
    static constexpr double kInverse[3][3] = {{0.9869929, -0.1470543, 0.1599627},
                                              {0.4323053, 0.5183603, 0.0492912},
                                              {-0.0085287, 0.0400428, 0.9684867}};
    const double d65[3] = {0.95047, 1.0, 1.08883};
    const auto cone = [&](const double* xyz, int i) {
        return kBradford[i][0] * xyz[0] + kBradford[i][1] * xyz[1] + kBradford[i][2] * xyz[2];
    };
    double lms[3];
    for (int i = 0; i < 3; ++i) lms[i] = cone(c.data(), i) * cone(d65, i) / cone(e.data(), i);
    double xyz[3];
    for (int i = 0; i < 3; ++i)
        xyz[i] = kInverse[i][0] * lms[0] + kInverse[i][1] * lms[1] + kInverse[i][2] * lms[2];
    return xyz_to_rec709(xyz[0], xyz[1], xyz[2]);
}

Vec3 blackbody_rgb(double kelvin) {
    if (!(kelvin > 0.0)) return Vec3(0.0f);
    // Wien's displacement law places the peak that normalises the spectrum.
    const double peak = planck(2.8977721e-3 / kelvin * 1e9, kelvin);
    return integrate([&](double l) { return planck(l, kelvin) / peak; });
}

Vec3 unit_luminance(Vec3 rgb) {
    const float y = luminance(rgb);
    return y > 0.0f ? rgb / y : Vec3(0.0f);
}

std::optional<NamedMetal> named_metal(const std::string& name) {
    std::string metal = name;
    for (const char* suffix : {"-eta", "-k"}) {
        const std::string s = suffix;
        if (metal.size() > s.size() && metal.compare(metal.size() - s.size(), s.size(), s) == 0)
            metal.resize(metal.size() - s.size());
    }
    if (metal == "metal-Au") return NamedMetal{"gold", {}, {}, false};
    if (metal == "metal-Ag") return NamedMetal{"silver", {}, {}, false};
    if (metal == "metal-Cu") return NamedMetal{"copper", {}, {}, false};
    if (metal == "metal-Al") return NamedMetal{"aluminium", {}, {}, false};
    // Brass, magnesium oxide and titanium dioxide: no data here; copper is the nearest colour
    // of brass, and the two oxides are dielectrics (k ~ 0) of index ~1.74 and ~2.6 (rutile).
    if (metal == "metal-CuZn") return NamedMetal{"copper", {}, {}, true};
    if (metal == "metal-MgO") return NamedMetal{"custom", Vec3(1.74f), Vec3(0.0f), true};
    if (metal == "metal-TiO2") return NamedMetal{"custom", Vec3(2.6f), Vec3(0.0f), true};
    return std::nullopt;
}

std::optional<double> named_glass_ior(const std::string& name) {
    // Refractive index n_d at 587.6 nm from the Schott optical glass catalogue (N-BK7, N-BAF10,
    // N-FK51A, N-LASF9, SF5, SF10, SF11), the glasses pbrt-v4's named spectra tabulate.
    static const std::pair<const char*, double> kGlasses[] = {
        {"glass-BK7", 1.5168},   {"glass-BAF10", 1.6700}, {"glass-FK51A", 1.4866},
        {"glass-LASF9", 1.8503}, {"glass-F5", 1.6727},    {"glass-F10", 1.7283},
        {"glass-F11", 1.7847}};
    for (const auto& [n, ior] : kGlasses)
        if (name == n) return ior;
    return std::nullopt;
}

std::optional<Vec3> named_illuminant(const std::string& name, bool& exact) {
    exact = true;
    // D65 is Rec.709's white point: white.
    if (name == "stdillum-D65") return Vec3(1.0f);
    // Illuminant A is a blackbody at 2856 K by definition (CIE 15:2004).
    if (name == "stdillum-A") return unit_luminance(blackbody_rgb(2856.0));
    exact = false;
    // The other D illuminants by their correlated colour temperatures.
    if (name == "stdillum-D50") return unit_luminance(blackbody_rgb(5003.0));
    if (name == "illum-acesD60") return unit_luminance(blackbody_rgb(6004.0));
    // The fluorescent F1-F12 by their correlated colour temperatures (CIE 15:2004); they were
    // white, while the warning said a blackbody stood in.
    static constexpr std::pair<const char*, double> kFluorescent[] = {
        {"stdillum-F1", 6430.0},  {"stdillum-F2", 4230.0},  {"stdillum-F3", 3450.0},
        {"stdillum-F4", 2940.0},  {"stdillum-F5", 6350.0},  {"stdillum-F6", 4150.0},
        {"stdillum-F7", 6500.0},  {"stdillum-F8", 5000.0},  {"stdillum-F9", 4150.0},
        {"stdillum-F10", 5000.0}, {"stdillum-F11", 4000.0}, {"stdillum-F12", 3000.0}};
    for (const auto& [n, kelvin] : kFluorescent)
        if (name == n) return unit_luminance(blackbody_rgb(kelvin));
    return std::nullopt;
}

}  // namespace spangle::pbrt
