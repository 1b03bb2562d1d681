// Zoom: as a camera dollies in, a pixel's footprint shrinks about its centre and keeps the flakes
// that stay inside it. Measured through the plugin ABI: the correlation, over footprints, of the
// lobe of a footprint and that of its copy scaled by `shrink` about the same centre.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "core/hash.h"
#include "flake_support.h"

namespace spangle::test::flake_zoom {
namespace {

double zoom_correlation(const char* algorithm, double lambda, float shrink, float cos_o) {
    auto m = flake_material(true, {{"flake_roughness", {0.15f}}, {"gamma", {3.0f}}},
                            {{"algorithm", algorithm}});
    const Vec3 wo = dir(cos_o, 0.3f);
    const std::vector<Vec3> wis = fan(mirror(wo), 0.045f, 3, 0.05f);
    constexpr int kFootprints = 600;
    std::vector<std::vector<float>> big(kFootprints), small(kFootprints);
    std::vector<Vec3> f;
    std::vector<float> pdf;
    for (int k = 0; k < kFootprints; ++k) {
        BsdfHarness::Point b = random_footprint(lambda, 501, static_cast<uint64_t>(k));
        BsdfHarness::Point s = b;
        s.dudx *= shrink;
        s.dvdy *= shrink;
        m->prepare(wo, b);
        m->eval(wis, f, pdf);
        for (const Vec3& x : f) big[k].push_back(x.y);
        m->prepare(wo, s);
        m->eval(wis, f, pdf);
        for (const Vec3& x : f) small[k].push_back(x.y);
    }
    return mean_correlation(big, small);
}

TEST(FlakeZoom, AFootprintHalfAsWideKeepsTheLargerOnesGlints) {
    // A camera dollying in: each pixel's footprint shrinks about its centre. The enumeration's
    // lobes of a footprint and of its half-size copy are correlated by sqrt(1/4) = 0.5 (the small
    // one's flakes are a quarter of the large one's). The counting algorithm's stand-ins were
    // virtual flakes of the cells of the footprint's quad-tree level: a footprint half as wide
    // is one level down, in new cells, with new stand-ins, and the correlation was 0 (-0.004 to
    // 0.009 at lambda 1000 to 1e5): every glint changed. Stand-ins now lie where they lie at
    // every footprint size (classes of virtual flakes, nested as the footprint shrinks), and
    // the correlation is the share of the large footprint's stand-ins the small one keeps, the
    // area ratio 1/4 (0.24 to 0.25 measured): a fixed number of stand-ins per footprint cannot
    // reach sqrt(1/4), which needs all of the flakes. Lambda 3000 and more: every cell counted
    // at both sizes.
    const double e = zoom_correlation("enumerate", 3000.0, 0.5f, 0.8f);
    EXPECT_NEAR(e, 0.5, 0.05) << "the enumeration: sqrt of the area ratio";
    for (double lambda : {3000.0, 30000.0}) {
        const double t = zoom_correlation("tree", lambda, 0.5f, 0.8f);
        EXPECT_GT(t, 0.7 * 0.25) << "lambda " << lambda;
        EXPECT_LT(t, 0.5) << "lambda " << lambda;
    }
}

TEST(FlakeZoom, ACellThatBecomesFewEnoughToEnumerateKeepsItsGlints) {
    // Lambda 600 to 1500 at this view (the tree enumerates cells of up to 420 flakes): the large
    // footprint's cells are counted, the half-size copy's enumerated. The stand-ins were virtual
    // flakes, which the enumeration does not have: the correlation was 0.005 to 0.014, every glint
    // changed where a cell switched. They are now the field's ranked classes, real flakes: the
    // small footprint's enumeration holds the large one's stand-ins inside it. Its lobe then
    // shares with the large one's what a quarter of the K stand-ins carry, each sqrt(k / K) of
    // a flake's weight: correlation sqrt(K / k) / 2 for K of the large one's k flakes (0.11 to
    // 0.16 measured; 0.5 would need all of its flakes, as the enumeration at both sizes has).
    for (double lambda : {600.0, 1000.0, 1500.0}) {
        const double t = zoom_correlation("tree", lambda, 0.5f, 0.8f);
        EXPECT_GT(t, 0.08) << "lambda " << lambda;
        EXPECT_LT(t, 0.5) << "lambda " << lambda;
    }
}
}  // namespace
}  // namespace spangle::test::flake_zoom
