// Keyframed animation: tracks interpolate linearly or smoothly (through every key, C1, held
// beyond the ends); a sequence renders frame after frame through one session, rebuilding only
// what moved, and its in-between frame is the still render of the in-between camera and object,
// bit for bit.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "render/frame.h"
#include "render/session.h"
#include "scene/animation.h"
#include "test_support.h"

namespace spangle {
namespace {

TEST(Animation, TracksInterpolateAndHoldTheirEnds) {
    Track t;
    t.times = {0.0, 1.0, 3.0};
    t.values = {{0.0, 10.0}, {1.0, 10.0}, {5.0, 4.0}};
    t.smooth = false;
    EXPECT_EQ(evaluate(t, 0.5), (std::vector<double>{0.5, 10.0}));
    EXPECT_EQ(evaluate(t, 2.0), (std::vector<double>{3.0, 7.0}));
    EXPECT_EQ(evaluate(t, -4.0), t.values.front()) << "held before the first key";
    EXPECT_EQ(evaluate(t, 9.0), t.values.back()) << "held after the last";
    t.smooth = true;
    for (std::size_t k = 0; k < 3; ++k) {
        const std::vector<double> at = evaluate(t, t.times[k]);
        EXPECT_NEAR(at[0], t.values[k][0], 1e-12) << "through key " << k;
    }
    // C1 at the inner key: the slopes on either side agree (Steffen's tangent: secants 1 and 2
    // per second, their spacing-weighted mean 4/3, not above twice the smaller: 4/3).
    const double h = 1e-6;
    const double left = (evaluate(t, 1.0)[0] - evaluate(t, 1.0 - h)[0]) / h;
    const double right = (evaluate(t, 1.0 + h)[0] - evaluate(t, 1.0)[0]) / h;
    EXPECT_NEAR(left, right, 1e-4);
    EXPECT_NEAR(left, 4.0 / 3.0, 1e-4);
    // Monotone between keys: a channel that holds still between two keys stays put (a
    // Catmull-Rom spline would swing to 10.25 here), and one that rises never passes its next key.
    EXPECT_NEAR(evaluate(t, 0.5)[1], 10.0, 1e-12);
    for (double x = 0.0; x <= 3.0; x += 0.01) {
        const std::vector<double> v = evaluate(t, x);
        EXPECT_GE(v[0], 0.0);
        EXPECT_LE(v[0], 5.0 + 1e-12);
        EXPECT_LE(v[1], 10.0 + 1e-12) << "at " << x;
        EXPECT_GE(v[1], 4.0 - 1e-12);
    }
}

TEST(Animation, TheInBetweenFrameIsTheStillOfTheInBetweenPose) {
    const std::string scene = test::test_dir() + "/scenes/moving_camera.toml";
    RenderOptions options;
    options.threads = 2;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    std::vector<std::vector<float>> frames;
    std::vector<ReloadReport> reports;
    for (int f = 0; f <= 2; ++f) {
        reports.push_back(session.load(scene, static_cast<double>(f)));  // fps 1
        EXPECT_TRUE(session.info().animated);
        session.render();
        frames.push_back(session.world().image);
    }
    // Frames after the first rebuild no mesh and no material; the mesh BVHs are reused.
    for (int f = 1; f <= 2; ++f) {
        const auto& ran = reports[static_cast<std::size_t>(f)].ran;
        EXPECT_EQ(std::count(ran.begin(), ran.end(), "mesh_load"), 0) << "frame " << f;
        EXPECT_EQ(std::count(ran.begin(), ran.end(), "materials"), 0) << "frame " << f;
        EXPECT_EQ(reports[static_cast<std::size_t>(f)].reused.at("mesh BVHs"), 2) << "frame " << f;
    }
    EXPECT_NE(frames[0], frames[1]);
    EXPECT_NE(frames[1], frames[2]);

    // The still: the same scene without keys, camera and sphere halfway (linear keys).
    std::string text = test::scene_text("moving_camera.toml");
    const auto cut = [&](const std::string& from, const std::string& to) {
        const std::size_t a = text.find(from), b = text.find(to, a);
        ASSERT_NE(a, std::string::npos) << from;
        ASSERT_NE(b, std::string::npos) << to;
        text.erase(a, b - a);
    };
    cut("[[camera.keys]]", "[environment]");
    cut("[[object.keys]]", "[[light]]");
    const auto set = [&](const std::string& from, const std::string& to) {
        const std::size_t a = text.find(from);
        ASSERT_NE(a, std::string::npos) << from;
        text.replace(a, from.size(), to);
    };
    set("position = [0, 1, 5]\nlook_at = [0, 0.5, 0]",
        "position = [0, 1.25, 4.75]\nlook_at = [0.125, 0.5, 0]");
    set("translate = [0, 0.5, 0]", "translate = [0, 0.75, 0]\nrotate = [0, 45, 0]");
    test::TempDir dir("animation_still");
    std::ofstream(dir.file("still.toml")) << text;
    FrameRequest req;
    req.scene = dir.file("still.toml");
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.threads = 2;
    const FrameResult still = render_frame(req);
    ASSERT_EQ(still.image.size(), frames[1].size());
    EXPECT_EQ(still.image, frames[1]) << "frame 1 differs from the still of the halfway pose";
}

}  // namespace
}  // namespace spangle
