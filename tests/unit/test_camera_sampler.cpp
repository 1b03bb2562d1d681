#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/camera.h"
#include "render/sampler.h"
#include "render/surface.h"

namespace spangle::test_camera_sampler {
namespace {

TEST(Sobol, TablesMatchTheBitSerialDefinition) {
    for (uint32_t i : {0u, 1u, 2u, 3u, 255u, 256u, 65535u, 0x12345678u, 0xffffffffu})
        EXPECT_EQ(sobol_1(i), sobol_1_reference(i)) << i;
}

TEST(Sobol, EveryElementaryIntervalHoldsOnePoint) {
    // Owen scrambling keeps Sobol's (0, 2)-net property: 256 points of one pixel and dimension
    // pair fall one in each cell of every 2^a x 2^b grid with a + b = 8.
    for (uint32_t pixel : {0u, 17u, 12345u})
        for (uint32_t pair : {0u, 3u, 9u}) {
            for (int a = 0; a <= 8; ++a) {
                const int cx = 1 << a, cy = 1 << (8 - a);
                std::vector<int> cells(static_cast<std::size_t>(cx * cy), 0);
                for (uint32_t i = 0; i < 256; ++i) {
                    float u, v;
                    sobol_2d(7, pixel, i, pair, u, v);
                    ASSERT_GE(u, 0.0f);
                    ASSERT_LT(u, 1.0f);
                    ++cells[static_cast<std::size_t>(static_cast<int>(v * static_cast<float>(cy)) *
                                                         cx +
                                                     static_cast<int>(u * static_cast<float>(cx)))];
                }
                for (int c : cells)
                    ASSERT_EQ(c, 1)
                        << "pixel " << pixel << " pair " << pair << " grid " << cx << "x" << cy;
            }
        }
}

TEST(Sobol, ThirdDimensionTablesMatchTheBitSerialDefinition) {
    // The third dimension's first direction numbers, m = 1, 3, 3, 9, 29 (Sobol's x^2 + x + 1).
    EXPECT_EQ(sobol_2_reference(1), 0x80000000u);
    EXPECT_EQ(sobol_2_reference(2), 0xc0000000u);
    EXPECT_EQ(sobol_2_reference(4), 3u << 29);
    EXPECT_EQ(sobol_2_reference(8), 9u << 28);
    EXPECT_EQ(sobol_2_reference(16), 29u << 27);
    for (uint32_t i : {0u, 1u, 2u, 3u, 255u, 256u, 65535u, 0x12345678u, 0xffffffffu})
        EXPECT_EQ(sobol_2_reversed(i), reverse_bits(sobol_2_reference(i))) << i;
}

TEST(Sobol, TriplesAreStratifiedJointly) {
    // The first three Sobol dimensions form a (1, 3)-sequence, which Owen scrambling and the
    // index shuffle keep: 256 points of one pixel and set fall two in each box of every
    // 2^a x 2^b x 2^c grid with a + b + c = 7. So the samples whose third number makes one
    // choice (a lobe, a light) are stratified in the first two. The first two are the pair's.
    for (uint64_t key : {3ull, 977ull, 0x123456789abcdefull})
        for (uint32_t set : {1u, 6u}) {
            float u[256][3];
            for (uint32_t i = 0; i < 256; ++i) {
                sobol_3d_keyed(key, i, set, u[i][0], u[i][1], u[i][2]);
                float p0, p1;
                sobol_2d_keyed(key, i, set, p0, p1);
                ASSERT_EQ(p0, u[i][0]);
                ASSERT_EQ(p1, u[i][1]);
            }
            for (int a = 0; a <= 7; ++a)
                for (int b = 0; a + b <= 7; ++b) {
                    const int c = 7 - a - b;
                    std::vector<int> cells(std::size_t{1} << 7, 0);
                    for (const auto& p : u) {
                        const int x = static_cast<int>(p[0] * static_cast<float>(1 << a));
                        const int y = static_cast<int>(p[1] * static_cast<float>(1 << b));
                        const int z = static_cast<int>(p[2] * static_cast<float>(1 << c));
                        ++cells[static_cast<std::size_t>((z << (a + b)) | (y << a) | x)];
                    }
                    for (int n : cells)
                        ASSERT_EQ(n, 2) << "key " << key << " set " << set << " grid 2^" << a
                                        << " x 2^" << b << " x 2^" << c;
                }
        }
    // The check can fail: a third number drawn from another pair (as the lobe choice was before)
    // is not stratified with the first two.
    int uneven = 0;
    for (int a = 0; a <= 7; ++a) {
        std::vector<int> cells(std::size_t{1} << 7, 0);
        for (uint32_t i = 0; i < 256; ++i) {
            float u0, u1, other, spare;
            sobol_2d_keyed(3, i, 1, u0, u1);
            sobol_2d_keyed(3, i, 2, other, spare);
            const int c = 7 - a;
            ++cells[static_cast<std::size_t>(
                (static_cast<int>(other * static_cast<float>(1 << c)) << a) |
                static_cast<int>(u0 * static_cast<float>(1 << a)))];
        }
        for (int n : cells) uneven += n != 2 ? 1 : 0;
    }
    EXPECT_GT(uneven, 0);
}

TEST(Sobol, PairsAndPixelsAreDecorrelated) {
    // The same sample index in two pairs (or two pixels) must not give the same point.
    int same = 0;
    for (uint32_t i = 0; i < 1000; ++i) {
        float a0, a1, b0, b1;
        sobol_2d(7, 5, i, 0, a0, a1);
        sobol_2d(7, 5, i, 1, b0, b1);
        same += (a0 == b0);
    }
    EXPECT_LT(same, 5);
}

/** Checks that a Blackman-Harris sampler of radius r puts its stratified samples inside
 *  [-r, r] with the window's mass in each of `bins` bins (the only error is the 256-bin
 *  tabulation, well under 1%). */
void expect_blackman_harris(const FilterSampler& f, double r, int bins) {
    constexpr int kN = 160000;
    std::vector<double> hist(static_cast<std::size_t>(bins), 0.0);
    for (int i = 0; i < kN; ++i) {
        const float x = f.sample((static_cast<float>(i) + 0.5f) / kN);
        ASSERT_GE(x, -r);
        ASSERT_LE(x, r);
        hist[static_cast<std::size_t>(
            std::min(bins - 1, static_cast<int>((x + r) / (2.0 * r) * bins)))] += 1.0;
    }
    const auto window = [r](double x) {
        const double t = 2.0 * M_PI * (x / (2.0 * r) + 0.5);
        return 0.35875 - 0.48829 * std::cos(t) + 0.14128 * std::cos(2 * t) -
               0.01168 * std::cos(3 * t);
    };
    double total = 0.0;
    std::vector<double> expect(static_cast<std::size_t>(bins), 0.0);
    for (int b = 0; b < bins; ++b) {
        for (int k = 0; k < 100; ++k)
            expect[static_cast<std::size_t>(b)] +=
                window(-r + (b + (k + 0.5) / 100.0) * 2.0 * r / bins);
        total += expect[static_cast<std::size_t>(b)];
    }
    for (int b = 0; b < bins; ++b)
        EXPECT_NEAR(hist[static_cast<std::size_t>(b)] / kN,
                    expect[static_cast<std::size_t>(b)] / total, 0.002)
            << "radius " << r << " bin " << b;
}

TEST(FilterSampler, SamplesFollowTheFilter) {
    // Blackman-Harris over [-2, 2] (its own radius): the histogram matches the window.
    expect_blackman_harris(FilterSampler(FilterKind::BlackmanHarris), 2.0, 16);
    const FilterSampler box(FilterKind::Box);
    EXPECT_NEAR(box.sample(0.25f), -0.25f, 1e-3f);
}

TEST(FilterSampler, TheRadiusStretchesTheFilter) {
    // [render] filter_radius: Blackman-Harris over [-1.5, 1.5] (Cycles' default filter, width
    // 1.5); the Gaussian's sigma is radius / 3: radius 3 has twice the default's spread (that
    // the default, 1.5 and sigma 0.5, draws the same bits as before is the pixel hashes' to say).
    expect_blackman_harris(FilterSampler(FilterKind::BlackmanHarris, 1.5f), 1.5, 12);
    const FilterSampler g(FilterKind::Gaussian), g3(FilterKind::Gaussian, 3.0f);
    double v1 = 0.0, v3 = 0.0;
    for (int i = 0; i < 4096; ++i) {
        const float u = (static_cast<float>(i) + 0.5f) / 4096.0f;
        v1 += static_cast<double>(g.sample(u)) * g.sample(u);
        v3 += static_cast<double>(g3.sample(u)) * g3.sample(u);
    }
    EXPECT_NEAR(std::sqrt(v3 / v1), 2.0, 0.01);
    EXPECT_EQ(g3.radius(), 3.0f);
    const FilterSampler box(FilterKind::Box, 1.0f);
    EXPECT_NEAR(box.sample(0.25f), -0.5f, 1e-3f);
}

TEST(SharedFilter, WeightsSpreadAsWideAsTheFilter) {
    // A box within its pixel spreads nothing.
    EXPECT_EQ(spread_weights(FilterKind::Box, 0.0f), std::vector<double>{1.0});
    EXPECT_EQ(spread_weights(FilterKind::Box, 0.3f), std::vector<double>{1.0});
    // A box of radius 1 has variance 1/3; the pixel's own box 1/12, so the weights make up 1/4:
    // a quarter of the weight on the two neighbours, 1/8 each.
    const std::vector<double> b1 = spread_weights(FilterKind::Box, 1.0f);
    ASSERT_EQ(b1.size(), 3u);
    // (To the quadrature of the filter's variance: 4096 midpoints, relative error 2e-8.)
    EXPECT_NEAR(b1[0], 0.125, 1e-7);
    EXPECT_NEAR(b1[1], 0.75, 1e-7);
    EXPECT_EQ(b1[0], b1[2]);
    // Every filter: weights summing to 1, even, and as wide as the filter (the variance of the
    // weights plus the pixel's own 1/12 is the filter's, by quadrature); a filter narrower than
    // the pixel itself (variance below 1/12) cannot be matched and spreads nothing.
    const auto variance = [](FilterKind k, double r) {
        double m0 = 0.0, m2 = 0.0;
        for (int i = 0; i < 200000; ++i) {
            const double x = -r + (i + 0.5) * 2.0 * r / 200000, f = filter_value(k, x, r);
            m0 += f;
            m2 += x * x * f;
        }
        return m2 / m0;
    };
    for (const FilterKind k : {FilterKind::Box, FilterKind::Gaussian, FilterKind::BlackmanHarris})
        for (const float r : {0.8f, 1.0f, 1.5f, 2.0f, 3.3f, 6.0f}) {
            const std::vector<double> w = spread_weights(k, r);
            if (variance(k, r) < 1.0 / 12.0) {
                EXPECT_EQ(w, std::vector<double>{1.0}) << static_cast<int>(k) << " radius " << r;
                continue;
            }
            const int reach = static_cast<int>(w.size() / 2);
            ASSERT_EQ(w.size() % 2, 1u);
            double sum = 0.0, var = 0.0;
            for (int o = -reach; o <= reach; ++o) {
                const double x = w[static_cast<std::size_t>(o + reach)];
                EXPECT_EQ(x, w[static_cast<std::size_t>(reach - o)]);
                EXPECT_GE(x, 0.0);
                sum += x;
                var += o * o * x;
            }
            EXPECT_NEAR(sum, 1.0, 1e-12);
            EXPECT_NEAR(var + 1.0 / 12.0, variance(k, r), 2e-4 * variance(k, r))
                << "filter " << static_cast<int>(k) << " radius " << r;
        }
    EXPECT_NEAR(variance(FilterKind::Box, 1.0), 1.0 / 3.0, 1e-6);
    // Blackman-Harris of its own radius 2 (variance 0.307): three pixels, 0.1118 on each side.
    const std::vector<double> bh = spread_weights(FilterKind::BlackmanHarris, 0.0f);
    ASSERT_EQ(bh.size(), 3u);
    EXPECT_NEAR(bh[0], 0.1118, 2e-4);
}

TEST(SharedFilter, SpreadsAnImpulseAsTheKernelAndKeepsAConstantAtTheEdges) {
    const std::vector<double> w = spread_weights(FilterKind::BlackmanHarris, 2.5f);
    const int reach = static_cast<int>(w.size() / 2);
    ASSERT_EQ(reach, 2);
    const uint32_t n = 9;
    // Channel 0: an impulse at (4, 4); channel 1: a constant; channel 2: left alone.
    std::vector<float> v(n * n * 3, 0.0f);
    for (uint32_t i = 0; i < n * n; ++i) {
        v[3 * i + 1] = 2.0f;
        v[3 * i + 2] = static_cast<float>(i);
    }
    v[3 * (4 * n + 4)] = 1.0f;
    const PixelRect all{0, 0, n, n};
    spread_pixels(v.data(), 3, {true, true, false}, all, all, w);
    for (uint32_t y = 0; y < n; ++y)
        for (uint32_t x = 0; x < n; ++x) {
            const std::size_t i = y * n + x;
            const int dx = static_cast<int>(x) - 4, dy = static_cast<int>(y) - 4;
            const double expect = std::abs(dx) <= reach && std::abs(dy) <= reach
                                      ? w[static_cast<std::size_t>(dx + reach)] *
                                            w[static_cast<std::size_t>(dy + reach)]
                                      : 0.0;
            EXPECT_NEAR(v[3 * i], expect, 1e-7) << x << ", " << y;
            // Renormalised where neighbours are missing: the corners stay 2.
            EXPECT_NEAR(v[3 * i + 1], 2.0f, 1e-6f) << x << ", " << y;
            EXPECT_EQ(v[3 * i + 2], static_cast<float>(i));
        }
}

TEST(SharedFilter, AWindowWithItsNeighboursGivesTheWholeFramesBits) {
    // Noise over a 23 x 81 frame (rows spread in blocks of 32), spread whole; then windows spread
    // from a copy of each grown by the reach (2) alone: the same bits, at the frame's edges and
    // across blocks too. And the whole frame against the two passes written out plainly.
    const std::vector<double> w = spread_weights(FilterKind::Gaussian, 2.2f);
    const uint32_t fw = 23, fh = 81;
    std::vector<float> frame(fw * fh);
    uint32_t state = 12345;
    for (float& x : frame) {
        state = state * 1664525u + 1013904223u;
        x = static_cast<float>(state >> 8) * 0x1p-24f;
    }
    std::vector<float> whole = frame;
    spread_pixels(whole.data(), 1, {true}, PixelRect{0, 0, fw, fh}, PixelRect{0, 0, fw, fh}, w);
    const uint32_t reach = static_cast<uint32_t>(w.size() / 2);
    const int r = static_cast<int>(w.size() / 2);
    for (uint32_t y = 0; y < fh; ++y)
        for (uint32_t x = 0; x < fw; ++x) {
            double acc = 0.0, wy = 0.0;
            for (int oy = -r; oy <= r; ++oy) {
                const int yy = static_cast<int>(y) + oy;
                if (yy < 0 || yy >= static_cast<int>(fh)) continue;
                double h = 0.0, wx = 0.0;
                for (int ox = -r; ox <= r; ++ox) {
                    const int xx = static_cast<int>(x) + ox;
                    if (xx < 0 || xx >= static_cast<int>(fw)) continue;
                    h += w[static_cast<std::size_t>(ox + r)] *
                         static_cast<double>(frame[static_cast<std::size_t>(yy) * fw + xx]);
                    wx += w[static_cast<std::size_t>(ox + r)];
                }
                acc += w[static_cast<std::size_t>(oy + r)] * (h / wx);
                wy += w[static_cast<std::size_t>(oy + r)];
            }
            EXPECT_EQ(whole[y * fw + x], static_cast<float>(acc / wy)) << x << ", " << y;
        }
    for (const PixelRect to : {PixelRect{5, 3, 12, 9}, PixelRect{0, 0, 6, 4},
                               PixelRect{20, 62, 23, 81}, PixelRect{3, 20, 19, 70}}) {
        const PixelRect have{to.x0 > reach ? to.x0 - reach : 0, to.y0 > reach ? to.y0 - reach : 0,
                             std::min(fw, to.x1 + reach), std::min(fh, to.y1 + reach)};
        std::vector<float> part;
        for (uint32_t y = have.y0; y < have.y1; ++y)
            for (uint32_t x = have.x0; x < have.x1; ++x) part.push_back(frame[y * fw + x]);
        spread_pixels(part.data(), 1, {true}, have, to, w);
        for (uint32_t y = to.y0; y < to.y1; ++y)
            for (uint32_t x = to.x0; x < to.x1; ++x)
                EXPECT_EQ(part[(y - have.y0) * (have.x1 - have.x0) + (x - have.x0)],
                          whole[y * fw + x])
                    << x << ", " << y;
    }
}

TEST(RayDifferentials, HeadOnPlaneFootprintIsThePixel) {
    // A camera 3 m in front of a plane z = 0 whose uv is (x / 2, y / 2), looking straight at it.
    const uint32_t w = 320, h = 200;
    const float fov = 30.0f;
    const CameraModel cam({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, fov, 0.0f, 3.0f, w, h);
    const RayDifferential r = cam.generate(160.0f, 100.0f, 0.5f, 0.5f);
    SurfacePoint sp;
    const float t = -r.o.z / r.d.z;
    sp.p = r.o + r.d * t;
    sp.ng = sp.n = {0, 0, 1};
    sp.dpdu = {2, 0, 0};
    sp.dpdv = {0, 2, 0};
    bool has_diff = true;
    footprint_at(sp, r, has_diff, 0.0f);
    ASSERT_TRUE(has_diff);
    // One pixel spans 2 d tan(fov / 2) / height metres at distance d; uv is metres / 2.
    const double pixel = 2.0 * 3.0 * std::tan(fov * M_PI / 360.0) / h;
    EXPECT_NEAR(sp.dudx, pixel / 2.0, 1e-4 * pixel);
    EXPECT_NEAR(sp.dvdy, -pixel / 2.0, 1e-4 * pixel) << "image y runs down, v runs up";
    EXPECT_NEAR(sp.dudy, 0.0, 1e-6);
    EXPECT_NEAR(sp.dvdx, 0.0, 1e-6);
}

TEST(RayDifferentials, WidenedFootprintWhenDifferentialsAreGone) {
    SurfacePoint sp;
    sp.p = {0, 0, 0};
    sp.ng = sp.n = {0, 0, 1};
    sp.s = {1, 0, 0};
    sp.t = {0, 1, 0};
    sp.dpdu = {4, 0, 0};
    sp.dpdv = {0, 0.5f, 0};
    RayDifferential r{};
    bool has_diff = false;
    footprint_at(sp, r, has_diff, 0.2f);
    EXPECT_FALSE(has_diff);
    EXPECT_FLOAT_EQ(sp.dudx, 0.05f);
    EXPECT_FLOAT_EQ(sp.dvdy, 0.4f);
    EXPECT_FLOAT_EQ(sp.footprint, 0.2f);
}

}  // namespace
}  // namespace spangle::test_camera_sampler

namespace spangle {
namespace {

/** p (row vector, w = 1) times the row-major 4x4 m. */
std::array<float, 4> times(Vec3 p, const std::array<float, 16>& m) {
    std::array<float, 4> out{};
    const float v[4] = {p.x, p.y, p.z, 1.0f};
    for (std::size_t j = 0; j < 4; ++j)
        for (std::size_t k = 0; k < 4; ++k) out[j] += v[k] * m[k * 4 + j];
    return out;
}

TEST(CameraMatrices, ProjectPointsToThePixelsTheirRaysCameFrom) {
    // A point on the ray CameraModel makes through film position (fx, fy) lands, through
    // worldToNDC, at (fx / width, fy / height); worldToCamera puts the camera at the origin,
    // looking along +z, x to the image's right and y up.
    const Vec3 pos(1.0f, 2.0f, 5.0f), at(-0.5f, 0.3f, 0.2f), up(0.1f, 1.0f, 0.0f);
    const uint32_t w = 320, h = 180;
    const CameraModel cam(pos, at, up, 35.0f, 0.0f, 1.0f, w, h);
    const CameraMatrices m = cam.matrices();
    const auto origin = times(pos, m.world_to_camera);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(origin[static_cast<std::size_t>(k)], 0.0f, 1e-5f);
    for (const auto& [fx, fy] : {std::pair{0.0f, 0.0f},
                                 {320.0f, 180.0f},
                                 {17.5f, 150.25f},
                                 {160.0f, 90.0f},
                                 {300.0f, 3.0f}}) {
        const RayDifferential r = cam.generate(fx, fy, 0.5f, 0.5f);
        const Vec3 p = r.o + r.d * 3.7f;
        const auto ndc = times(p, m.world_to_ndc);
        ASSERT_GT(ndc[3], 0.0f);
        EXPECT_NEAR(ndc[0] / ndc[3], fx / static_cast<float>(w), 1e-4f) << fx << ", " << fy;
        EXPECT_NEAR(ndc[1] / ndc[3], fy / static_cast<float>(h), 1e-4f) << fx << ", " << fy;
        const auto c = times(p, m.world_to_camera);
        EXPECT_NEAR(c[2], 3.7f * dot(r.d, normalize(at - pos)), 1e-4f) << "z is the depth";
        if (std::fabs(fx - 160.0f) > 1.0f) {
            EXPECT_EQ(c[0] > 0.0f, fx > 160.0f) << "x to the right";
        }
        if (std::fabs(fy - 90.0f) > 1.0f) {
            EXPECT_EQ(c[1] > 0.0f, fy < 90.0f) << "y up";
        }
    }
}

TEST(OrthographicCamera, ParallelRaysOverTheViewHeight) {
    // ortho_height 4 on a 320 x 200 image: rays leave the plane through the position, all along
    // the view, over 4 units up and 6.4 across; a pixel is 4 / 200 units wide at every depth,
    // which the differentials carry as an offset of the origin, not of the direction.
    const Vec3 pos(1.0f, 2.0f, 5.0f), at(1.0f, 2.0f, -1.0f);
    const uint32_t w = 320, h = 200;
    FilmLayout layout;
    layout.ortho_height = 4.0f;
    const CameraModel cam(pos, at, {0, 1, 0}, 40.0f, 0.0f, 6.0f, w, h, layout);
    EXPECT_EQ(cam.pixel_angle(), 0.0f);
    EXPECT_NEAR(cam.pixel_width(), 4.0f / 200.0f, 1e-7f);
    const RayDifferential c = cam.generate(160.0f, 100.0f, 0.5f, 0.5f);
    EXPECT_NEAR(length(c.o - pos), 0.0f, 1e-6f);
    const RayDifferential corner = cam.generate(0.0f, 0.0f, 0.5f, 0.5f);
    EXPECT_NEAR(corner.o.x, 1.0f - 3.2f, 1e-5f) << "the image's left edge";
    EXPECT_NEAR(corner.o.y, 2.0f + 2.0f, 1e-5f) << "its top";
    EXPECT_NEAR(corner.o.z, 5.0f, 1e-6f);
    for (const RayDifferential* r : {&c, &corner}) {
        EXPECT_NEAR(r->d.z, -1.0f, 1e-7f);
        EXPECT_EQ(r->dx_d.z, r->d.z);
        EXPECT_NEAR(r->dx_o.x - r->o.x, 0.02f, 1e-6f);
        EXPECT_NEAR(r->dy_o.y - r->o.y, -0.02f, 1e-6f) << "image y runs down";
    }
    // The matrices put a point at any depth on the pixel its ray came from.
    const CameraMatrices m = cam.matrices();
    for (const float depth : {0.5f, 3.0f, 300.0f}) {
        const RayDifferential r = cam.generate(17.5f, 150.25f, 0.5f, 0.5f);
        const auto ndc = times(r.o + r.d * depth, m.world_to_ndc);
        EXPECT_NEAR(ndc[0] / ndc[3], 17.5f / w, 1e-5f) << depth;
        EXPECT_NEAR(ndc[1] / ndc[3], 150.25f / h, 1e-5f) << depth;
    }
    // Through a lens, every ray of a film point meets at the plane in focus, straight ahead.
    FilmLayout lens = layout;
    const CameraModel thin(pos, at, {0, 1, 0}, 40.0f, 0.3f, 6.0f, w, h, lens);
    for (const auto& [lu, lv] : {std::pair{0.1f, 0.9f}, {0.7f, 0.2f}}) {
        const RayDifferential r = thin.generate(0.0f, 0.0f, lu, lv);
        const float t = 6.0f / -r.d.z;
        const Vec3 hit = r.o + r.d * t;
        EXPECT_NEAR(hit.x, corner.o.x, 1e-4f);
        EXPECT_NEAR(hit.y, corner.o.y, 1e-4f);
        EXPECT_GT(length(r.o - corner.o), 1e-3f) << "the ray leaves from the lens";
    }
}

TEST(EquirectangularCamera, EveryDirectionOnceAcrossTheImage) {
    // The image centre looks along the view, x runs round the horizon (to the right first, the
    // edges behind), y from straight up to straight down; differentials are a pixel's turn.
    const Vec3 pos(1.0f, 2.0f, 3.0f), at(1.0f, 2.0f, -5.0f);  // looking down -z, y up
    const uint32_t w = 360, h = 180;
    FilmLayout layout;
    layout.equirect = true;
    const CameraModel cam(pos, at, {0, 1, 0}, 40.0f, 0.5f, 6.0f, w, h, layout);
    EXPECT_FALSE(cam.projects_to_ndc());
    const auto dir = [&](float fx, float fy) {
        const RayDifferential r = cam.generate(fx, fy, 0.3f, 0.7f);
        EXPECT_EQ(r.o, pos) << "every ray leaves the position (no lens)";
        return r.d;
    };
    const auto near = [](Vec3 a, Vec3 b) { return length(a - b) < 1e-5f; };
    EXPECT_TRUE(near(dir(180.0f, 90.0f), {0, 0, -1})) << "the view at the centre";
    EXPECT_TRUE(near(dir(270.0f, 90.0f), {1, 0, 0})) << "the right a quarter to the right";
    EXPECT_TRUE(near(dir(90.0f, 90.0f), {-1, 0, 0})) << "the left a quarter to the left";
    EXPECT_TRUE(near(dir(0.0f, 90.0f), {0, 0, 1})) << "behind at the edge";
    EXPECT_TRUE(near(dir(360.0f, 90.0f), {0, 0, 1})) << "behind at the other edge";
    EXPECT_TRUE(near(dir(123.0f, 0.0f), {0, 1, 0})) << "up at the top";
    EXPECT_TRUE(near(dir(17.0f, 180.0f), {0, -1, 0})) << "down at the bottom";
    EXPECT_TRUE(near(dir(180.0f, 45.0f), normalize(Vec3(0, 1, -1)))) << "45 degrees up";
    // A pixel is a degree of azimuth on the horizon and a degree of elevation.
    const RayDifferential r = cam.generate(200.0f, 90.0f, 0.5f, 0.5f);
    EXPECT_NEAR(std::acos(std::clamp(dot(r.d, r.dx_d), -1.0f, 1.0f)), kPi / 180.0f, 1e-4f);
    EXPECT_NEAR(std::acos(std::clamp(dot(r.d, r.dy_d), -1.0f, 1.0f)), kPi / 180.0f, 1e-4f);
    EXPECT_NEAR(cam.pixel_angle(), kPi / 180.0f, 1e-7f);
}

}  // namespace
}  // namespace spangle
