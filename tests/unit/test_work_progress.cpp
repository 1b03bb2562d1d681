// Progress of the long work before a render (core/progress.h): reading mesh files, subdividing
// cages and building BVHs each report fractions that only grow, within [0, 1], and end at 1.

#include <gtest/gtest.h>

#include <map>

#include "geometry/cage.h"
#include "geometry/subdivision.h"
#include "pipeline/session.h"
#include "test_support.h"

namespace spangle::test_work_progress {
namespace {

/** Every report, by the work it names. */
struct Recorder {
    std::map<std::string, std::vector<double>> seen;
    WorkProgress callback() {
        return [this](const std::string& what, double f) { seen[what].push_back(f); };
    }
};

void expect_monotone_to_one(const Recorder& rec) {
    for (const auto& [what, fractions] : rec.seen) {
        SCOPED_TRACE(what);
        ASSERT_FALSE(fractions.empty());
        for (std::size_t i = 0; i < fractions.size(); ++i) {
            EXPECT_GE(fractions[i], 0.0);
            EXPECT_LE(fractions[i], 1.0);
            if (i > 0) {
                EXPECT_GE(fractions[i], fractions[i - 1]);
            }
        }
        EXPECT_EQ(fractions.back(), 1.0);
    }
}

bool has_prefix(const Recorder& rec, const std::string& prefix) {
    for (const auto& [what, fractions] : rec.seen)
        if (what.rfind(prefix, 0) == 0) return true;
    return false;
}

TEST(WorkProgress, ASubdivisionReportsFromZeroToOneThroughEachPhase) {
    const Cage cage = load_cage(test::asset_dir() + "/meshes/beetle_body.obj", {});
    SubdivOptions o;
    o.level = 4;  // tens of thousands of faces: the triangle loop reports along the way
    Recorder rec;
    const TriangleMesh mesh = subdivide(cage, o, {}, rec.callback(), "body");
    ASSERT_EQ(rec.seen.size(), 1u);
    const std::vector<double>& f = rec.seen.at("body");
    EXPECT_EQ(f.front(), 0.0);
    EXPECT_GE(f.size(), 6u);  // start, topology, limit, uvs, triangles (at least one), end
    expect_monotone_to_one(rec);
    EXPECT_GT(mesh.triangle_count(), 0u);
}

TEST(WorkProgress, ALoadReportsReadingSubdivisionAndBvhBuildsAndAReloadOnlyWhatItRedoes) {
    RenderOptions options;
    options.threads = 2;
    options.spp_override = 1;
    options.width_override = 16;
    options.height_override = 16;
    Recorder rec;
    options.work_progress = rec.callback();
    Session files({}, test::shipped_ocio(), options, test::quiet_log());
    files.load(test::test_dir() + "/scenes/small_lit.toml");
    EXPECT_TRUE(has_prefix(rec, "reading "));
    EXPECT_TRUE(has_prefix(rec, "building BVHs "));
    expect_monotone_to_one(rec);

    rec.seen.clear();
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(test::test_dir() + "/scenes/subdiv_near_far.toml");
    EXPECT_TRUE(has_prefix(rec, "subdividing "));
    EXPECT_TRUE(has_prefix(rec, "building BVHs "));
    expect_monotone_to_one(rec);

    // A reload that changes nothing rebuilds nothing, and says nothing.
    rec.seen.clear();
    session.load(test::test_dir() + "/scenes/subdiv_near_far.toml");
    EXPECT_TRUE(rec.seen.empty());
}

}  // namespace
}  // namespace spangle::test_work_progress
