// Light sampling against closed forms: every light type's next-event estimate of irradiance,
// pdf consistency between sample() and the pdf functions MIS uses, and the environment map's
// importance sampling.

#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "chi2.h"
#include "core/hash.h"
#include "render/lights.h"

namespace spangle::test::lights {
namespace {

/** Irradiance at p with normal n from the table by NEE: mean of L cos / pdf over n samples
 *  (no occlusion), with its standard error. */
std::pair<double, double> nee_irradiance(const LightTable& t, Vec3 p, Vec3 n, uint32_t count) {
    double sum = 0.0, sum2 = 0.0;
    for (uint32_t i = 0; i < count; ++i) {
        const LightSample s =
            t.sample(p, sample_1d(3, i, 0, 0), sample_1d(3, i, 0, 1), sample_1d(3, i, 0, 2));
        double v = 0.0;
        if (s.pdf > 0.0f)
            v = static_cast<double>(s.radiance.y) * std::max(0.0f, dot(s.wi, n)) / s.pdf;
        sum += v;
        sum2 += v * v;
    }
    const double mean = sum / count;
    return {mean, std::sqrt(std::max(0.0, sum2 / count - mean * mean) / count)};
}

/** Lambert's formula: irradiance at p (normal n) from a polygon of uniform radiance L, in double
 *  with atan2 for the edge angles (acos of nearly parallel float vectors is too coarse for a
 *  reference when the polygon is small and far). */
double polygon_irradiance(Vec3 p, Vec3 n, const std::vector<Vec3>& poly, double radiance) {
    using D3 = std::array<double, 3>;
    const auto sub = [](Vec3 a, Vec3 b) {
        return D3{double(a.x) - b.x, double(a.y) - b.y, double(a.z) - b.z};
    };
    const auto dotd = [](D3 a, D3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
    const auto crossd = [](D3 a, D3 b) {
        return D3{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    };
    const D3 nd{n.x, n.y, n.z};
    double sum = 0.0;
    for (std::size_t i = 0; i < poly.size(); ++i) {
        const D3 a = sub(poly[i], p), b = sub(poly[(i + 1) % poly.size()], p);
        const D3 c = crossd(a, b);
        const double len = std::sqrt(dotd(c, c));
        const double theta = std::atan2(len, dotd(a, b));
        sum += theta * dotd(c, nd) / len;
    }
    return 0.5 * radiance * std::fabs(sum);
}

AreaEmitter triangle(Vec3 a, Vec3 b, Vec3 c, float radiance) {
    AreaEmitter e;
    e.p0 = a;
    e.e1 = b - a;
    e.e2 = c - a;
    e.area = 0.5f * length(cross(e.e1, e.e2));
    e.n = normalize(cross(e.e1, e.e2));
    e.radiance = Vec3(radiance);
    return e;
}

TEST(LightSampling, TriangleMatchesLambertsFormulaNearAndFar) {
    // Near: large solid angle (Arvo's spherical triangle sampling); far: tiny (area sampling).
    for (float height : {0.3f, 1.0f, 200.0f}) {
        const Vec3 a(-1, height, -1), b(1.5f, height, -0.5f), c(0, height, 1.2f);
        LightTable t;
        t.add_area(triangle(a, b, c, 2.0f));  // (b - a) x (c - a) points down (-y)
        t.finalize(10.0f);
        const Vec3 p(0.1f, 0, 0), n(0, 1, 0);
        ASSERT_LT(t.area(0).n.y, 0.0f);
        const double exact = polygon_irradiance(p, n, {a, b, c}, 2.0);
        const auto [mean, err] = nee_irradiance(t, p, n, 200000);
        // 4 standard errors, plus float rounding of the far case's tiny values.
        EXPECT_NEAR(mean, exact, 4.0 * err + 1e-6 * exact) << "height " << height;
        const double omega = triangle_solid_angle(p, a, b, c);
        EXPECT_EQ(use_solid_angle_sampling(omega), height < 100.0f) << "height " << height;
    }
}

TEST(LightSampling, SamplePdfEqualsTheMisPdf) {
    LightTable t;
    t.add_area(triangle({-1, 1, -1}, {1, 1, -1}, {0, 1, 1}, 3.0f));  // faces down, towards p
    AreaEmitter quad;
    quad.p0 = {2, 2, 0};
    quad.e1 = {1, 0, 0};
    quad.e2 = {0, 0, 1};  // e1 x e2 points down
    quad.n = normalize(cross(quad.e1, quad.e2));
    quad.area = 1.0f;
    quad.radiance = Vec3(5.0f);
    quad.parallelogram = true;
    t.add_area(quad);
    t.add_sphere({{-2, 1, 0}, 0.5f, Vec3(4.0f)});
    t.finalize(10.0f);
    const Vec3 p(0.2f, 0, 0.1f);
    int checked = 0;
    for (uint32_t i = 0; i < 3000; ++i) {
        const LightSample s =
            t.sample(p, sample_1d(4, i, 0, 0), sample_1d(4, i, 0, 1), sample_1d(4, i, 0, 2));
        if (!(s.pdf > 0.0f)) continue;
        const Vec3 q = p + s.wi * s.dist;
        float mis_pdf;
        if (length(q - Vec3(-2, 1, 0)) < 0.51f)
            mis_pdf = t.sphere_pdf(0, p);
        else if (q.y > 1.5f)
            mis_pdf = t.area_pdf(1, p, q);
        else
            mis_pdf = t.area_pdf(0, p, q);
        EXPECT_NEAR(mis_pdf, s.pdf, 2e-3f * s.pdf) << "sample " << i;
        ++checked;
    }
    EXPECT_GT(checked, 2500);
}

TEST(LightSampling, SphereIrradiance) {
    // A sphere of radius r and radiance L seen face-on from distance d gives E = pi L r^2 / d^2.
    LightTable t;
    t.add_sphere({{0, 3, 0}, 0.5f, Vec3(2.0f)});
    t.finalize(10.0f);
    const auto [mean, err] = nee_irradiance(t, {0, 0, 0}, {0, 1, 0}, 100000);
    EXPECT_NEAR(mean, M_PI * 2.0 * 0.25 / 9.0, 4.0 * err + 1e-6);
}

TEST(LightSampling, PointSpotAndDistant) {
    {
        LightTable t;
        t.add_point({{0, 2, 0}, Vec3(8.0f), {0, -1, 0}, -1.0f, -1.0f});
        t.finalize(10.0f);
        EXPECT_NEAR(nee_irradiance(t, {0, 0, 0}, {0, 1, 0}, 10).first, 8.0 / 4.0, 1e-5)
            << "I / d^2";
    }
    {
        LightTable t;  // a 20 degree spot pointing down
        t.add_point({{0, 2, 0}, Vec3(8.0f), {0, -1, 0}, std::cos(0.349f), std::cos(0.3f)});
        t.finalize(10.0f);
        EXPECT_NEAR(nee_irradiance(t, {0, 0, 0}, {0, 1, 0}, 10).first, 2.0, 1e-5)
            << "inside the cone";
        EXPECT_EQ(nee_irradiance(t, {2, 0, 0}, {0, 1, 0}, 10).first, 0.0) << "outside the cone";
    }
    for (const bool quartic : {false, true}) {
        // Half way through the falloff (t = 1/2): smoothstep gives 1/2, pbrt-v3's t^4 1/16.
        LightTable t;
        const float outer = 0.4f, inner = 0.2f;
        PointEmitter e{{0, 2, 0}, Vec3(8.0f), {0, -1, 0}, std::cos(outer), std::cos(inner)};
        e.quartic = quartic;
        t.add_point(e);
        t.finalize(10.0f);
        const float c = 0.5f * (std::cos(outer) + std::cos(inner));  // t = 1/2 in the cosine
        const float s = std::sqrt(1.0f - c * c);
        const Vec3 p{2.0f * s / c, 0.0f, 0.0f};  // on the floor, seen at that angle
        const double d2 = static_cast<double>(dot(p - Vec3(0, 2, 0), p - Vec3(0, 2, 0)));
        const double want = 8.0 / d2 * static_cast<double>(c) * (quartic ? 1.0 / 16.0 : 0.5);
        EXPECT_NEAR(nee_irradiance(t, p, {0, 1, 0}, 10).first, want, 1e-4 * want)
            << (quartic ? "quartic" : "smoothstep");
    }
    for (float radius_deg : {0.0f, 0.27f, 5.0f}) {
        LightTable t;
        DistantEmitter d;
        d.direction = normalize(Vec3(0, 1, 1));
        if (radius_deg > 0.0f) {
            const float r = radius_deg * kPi / 180.0f;
            d.cos_radius = std::cos(r);
            d.solid_angle = 4.0f * kPi * std::sin(0.5f * r) * std::sin(0.5f * r);
            d.radiance = Vec3(3.0f / (kPi * std::sin(r) * std::sin(r)));
        } else {
            d.radiance = Vec3(3.0f);
        }
        t.add_distant(d);
        t.finalize(10.0f);
        // Irradiance 3 at normal incidence, on a surface tilted 45 degrees away: 3 cos 45.
        const auto [mean, err] = nee_irradiance(t, {0, 0, 0}, {0, 1, 0}, 20000);
        // Float rounding (1e-6) for the deterministic delta case; the cone's cosine varies
        // across a disk of finite size, which costs 2e-3 per degree of radius.
        EXPECT_NEAR(mean, 3.0 * std::sqrt(0.5), 4.0 * err + 1e-6 + 2e-3 * radius_deg)
            << "radius " << radius_deg;
    }
}

/** A small synthetic map: a bright blob, a dim sky, a black band. */
EnvironmentMap test_map(float rotation) {
    const int w = 32, h = 16;
    std::vector<float> rgb(static_cast<std::size_t>(w * h * 3));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float v = y < 8 ? 0.5f + 0.1f * static_cast<float>(x % 5) : 0.05f;
            if (y == 9) v = 0.0f;
            if (x == 20 && y == 3) v = 400.0f;
            for (int c = 0; c < 3; ++c) rgb[static_cast<std::size_t>(3 * (y * w + x) + c)] = v;
        }
    return EnvironmentMap(std::move(rgb), w, h, rotation);
}

TEST(EnvironmentMap, PdfIntegratesToOne) {
    const EnvironmentMap env = test_map(30.0f);
    // Midpoint rule over (theta, phi) with the sin(theta) Jacobian, which makes the integrand
    // bounded (in cos theta the pdf has an integrable 1 / sin singularity at the poles that a
    // midpoint rule resolves badly). 1600 x 3200 cells are 100 per pixel row and column; the
    // rotated pixel edges cut cells, an error of order 1/100 of a cell row: well under 1e-3.
    double sum = 0.0;
    const int nt = 1600, np = 3200;
    for (int i = 0; i < nt; ++i) {
        const double theta = (i + 0.5) * M_PI / nt, st = std::sin(theta);
        for (int j = 0; j < np; ++j) {
            const double phi = (j + 0.5) * 2.0 * M_PI / np;
            sum += st * env.pdf({static_cast<float>(st * std::cos(phi)),
                                 static_cast<float>(std::cos(theta)),
                                 static_cast<float>(st * std::sin(phi))});
        }
    }
    EXPECT_NEAR(sum * (M_PI / nt) * (2.0 * M_PI / np), 1.0, 1e-3);
}

TEST(EnvironmentMap, SamplesFollowLuminanceTimesSinTheta) {
    const EnvironmentMap env = test_map(0.0f);
    const int w = 32, h = 16;
    constexpr uint32_t kN = 200000;
    std::vector<double> observed(static_cast<std::size_t>(w * h), 0.0),
        expected(observed.size(), 0.0);
    for (uint32_t i = 0; i < kN; ++i) {
        float pdf;
        const Vec3 d = env.sample(sample_1d(8, i, 0, 0), sample_1d(8, i, 0, 1), pdf);
        ASSERT_GT(pdf, 0.0f);
        EXPECT_NEAR(env.pdf(d), pdf, 1e-3f * pdf) << "sample() and pdf() disagree";
        ASSERT_GT(env.eval(d).y, 0.0f) << "sampled a black pixel";
        const float u = 0.5f + std::atan2(d.x, -d.z) / (2.0f * kPi);
        const float v = std::atan2(std::sqrt(d.x * d.x + d.z * d.z), d.y) / kPi;
        const int x = std::min(w - 1, static_cast<int>(u * w)),
                  y = std::min(h - 1, static_cast<int>(v * h));
        observed[static_cast<std::size_t>(y * w + x)] += 1.0;
    }
    // Expected share of a pixel: its luminance times the solid angle of its row band.
    const auto lum = [&](int x, int y) {
        float v = y < 8 ? 0.5f + 0.1f * static_cast<float>(x % 5) : 0.05f;
        if (y == 9) v = 0.0f;
        if (x == 20 && y == 3) v = 400.0f;
        return static_cast<double>(v);
    };
    double total = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double band = std::cos(M_PI * y / h) - std::cos(M_PI * (y + 1) / h);
            expected[static_cast<std::size_t>(y * w + x)] = lum(x, y) * band;
            total += lum(x, y) * band;
        }
    // The sampler uses sin(theta) at the pixel centre, the exact band uses the integral: their
    // ratio differs from 1 by under 0.2% for 16 rows, far below the test's resolution.
    for (double& e : expected) e *= kN / total;
    const test::Chi2Result r = test::chi2_test(observed, expected);
    EXPECT_GT(r.p_value, 0.01) << "chi2 " << r.statistic << " dof " << r.dof;
}

TEST(EnvironmentMap, RotationTurnsTheMap) {
    const EnvironmentMap a = test_map(0.0f), b = test_map(90.0f);
    const Vec3 d = normalize(Vec3(0.3f, 0.2f, -1.0f));
    // Rotating the map by 90 degrees about +y moves what was at d to d rotated by 90 degrees.
    const Vec3 rotated(d.x * 0.0f - d.z * 1.0f, d.y, d.x * 1.0f + d.z * 0.0f);
    // Bilinear weights come from u computed along two float paths: equal to rounding.
    const Vec3 ea = a.eval(d), eb = b.eval(rotated);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(ea[c], eb[c], 1e-4f * std::max(1.0f, ea[c]));
}

}  // namespace
}  // namespace spangle::test::lights
