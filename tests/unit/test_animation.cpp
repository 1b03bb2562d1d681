// Keyframed animation: tracks interpolate linearly or smoothly (through every key, C1, held
// beyond the ends); a sequence renders frame after frame through one session, rebuilding only
// what moved, and its in-between frame is the still render of the in-between camera and object,
// bit for bit.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include "pipeline/frame.h"
#include "pipeline/session.h"
#include "scene/animation.h"
#include "scene/keyed_motion.h"
#include "test_support.h"

namespace spangle::test_animation {
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
        frames.push_back(session.result().image);
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

/** Renders `text` (a scene) at `time` with `spp` samples; the image. */
std::vector<float> render_text(const test::TempDir& dir, const std::string& text, double time,
                               uint32_t spp) {
    const std::string path = dir.file("scene.toml");
    std::ofstream(path) << text;
    RenderOptions options;
    options.threads = 2;
    options.spp_override = spp;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(path, time);
    session.render();
    return session.result().image;
}

/** Mean of |a - b| over all values. */
double mean_abs_difference(const std::vector<float>& a, const std::vector<float>& b) {
    double sum = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) sum += std::fabs(a[i] - b[i]);
    return sum / static_cast<double>(a.size());
}

// Motion blur: a frame whose shutter is open while things move is the average of the stills
// over the shutter. In motion_blur.toml the plank slides, turns 90 degrees and tips (cut into
// several steps), its shadow moves with it (shadow rays carry the path's time) and the camera
// slides; a distant light and a black sky leave only coverage to average. The blurred frame
// (256 spp) against the mean of 32 stills evenly over the shutter (64 spp each).
TEST(MotionBlur, TheBlurredFrameIsTheAverageOfStillsOverTheShutter) {
    test::TempDir dir("motion_blur");
    const std::string blurred_text = test::scene_text("motion_blur.toml");
    const std::string still_text = test::scene_text("motion_blur.toml", {{"shutter = [0, 1]", ""}});
    const std::vector<float> blurred = render_text(dir, blurred_text, 0.0, 256);
    constexpr int kStills = 32;
    std::vector<float> average(blurred.size(), 0.0f);
    for (int i = 0; i < kStills; ++i) {
        const std::vector<float> still = render_text(dir, still_text, (i + 0.5) / kStills, 64);
        ASSERT_EQ(still.size(), blurred.size());
        for (std::size_t k = 0; k < still.size(); ++k) average[k] += still[k] / kStills;
    }
    const std::vector<float> middle = render_text(dir, still_text, 0.5, 64);
    const double error = mean_abs_difference(blurred, average);
    const double unblurred = mean_abs_difference(middle, average);
    // Worst 4x4 block (mean of its values): streak and shadow edges in the wrong place show here.
    double worst = 0.0;
    const uint32_t w = 64, h = 48;
    for (uint32_t by = 0; by < h; by += 4)
        for (uint32_t bx = 0; bx < w; bx += 4) {
            double sum = 0.0;
            for (uint32_t y = by; y < by + 4; ++y)
                for (uint32_t x = bx; x < bx + 4; ++x)
                    for (uint32_t c = 0; c < 3; ++c) {
                        const std::size_t k = 3 * (static_cast<std::size_t>(y) * w + x) + c;
                        sum += blurred[k] - average[k];
                    }
            worst = std::max(worst, std::fabs(sum) / 48.0);
        }
    std::printf(
        "blurred vs average of stills: mean |diff| %.5f, worst 4x4 block %.5f; the "
        "middle still: %.5f\n",
        error, worst, unblurred);
    // Measured: 0.0007 and 0.0039, against 0.0150 for the middle still. Shadow rays traced at
    // the shutter's opening gave 0.0104 and 0.24; shading with the middle placement 0.0019, 0.044.
    EXPECT_LT(error, 0.0012);
    EXPECT_LT(worst, 0.012);
    EXPECT_GT(unblurred, 10 * 0.0012) << "the test scene hardly moves";
}

TEST(MotionBlur, ASpinOfWholeTurnsPerQuarterOfTheShutterIsBlurred) {
    // A wheel at 1440 degrees over the shutter looks the same at every quarter of it: tested at
    // the quarters alone the motion was "straight" with no step moving, and the frame rendered
    // as a still. Spins of n turns are cut into the most steps; a still stays without any.
    Shutter shutter = frame_shutter(0.0, 24.0, 0.0, 1.0);
    for (const double turns : {1.0, 4.0, 8.0, 20.0}) {
        const auto at = [&](double t) {
            return Affine::rotate(static_cast<float>(360.0 * turns * (t - shutter.open) * 24.0),
                                  {0, 1, 0});
        };
        const KeyedMotion<Affine> m = motion_through<Affine>(shutter, at);
        EXPECT_EQ(m.steps.size(), static_cast<std::size_t>(kMaxMotionSegments + 1)) << turns;
    }
    const KeyedMotion<Affine> still = motion_through<Affine>(shutter, [](double) {
        return Affine::rotate(30.0f, {0, 1, 0});
    });
    EXPECT_TRUE(still.steps.empty());
}

// A shutter of no length is an instant: [s, s] renders the still at time + s frames, bit for bit
// (no time is drawn); so does [0, 1] when nothing moves.
TEST(MotionBlur, AShutterOfNoLengthIsTheStillBitForBit) {
    test::TempDir dir("motion_blur_instant");
    const std::string moving = test::scene_text("moving_camera.toml");
    const auto with = [&](const std::string& shutter) {
        return test::scene_text("moving_camera.toml",
                                {{"fps = 1", "fps = 1\nshutter = " + shutter}});
    };
    const std::vector<float> still = render_text(dir, moving, 1.5, 4);
    EXPECT_EQ(render_text(dir, with("[0.5, 0.5]"), 1.0, 4), still);
    EXPECT_EQ(render_text(dir, with("[0, 0]"), 1.5, 4), still);
    EXPECT_NE(render_text(dir, with("[0, 0]"), 1.0, 4), still);
    // Nothing moves (keys held after the last): a shutter changes nothing.
    EXPECT_EQ(render_text(dir, with("[0, 1]"), 5.0, 4), render_text(dir, moving, 5.5, 4));
}

// An emissive object is not blurred (lights are placed at the shutter's middle): the load says
// so, naming the object, and renders it there.
TEST(MotionBlur, MovingEmittersAreNotBlurredAndTheLoadSaysSo) {
    test::TempDir dir("motion_blur_emitter");
    const std::string text = test::scene_text(
        "motion_blur.toml", {{"material = \"red\"", "material = \"red\"\nemission = [1, 1, 1]"}});
    const std::string path = dir.file("scene.toml");
    std::ofstream(path) << text;
    RenderOptions options;
    Session session({}, test::shipped_ocio(), options, test::quiet_log());
    session.load(path, 0.0);
    const std::vector<std::string>& notes = session.info().notes;
    ASSERT_EQ(notes.size(), 1u);
    EXPECT_NE(notes[0].find("[[object]] #2 moves while the shutter is open but emits light"),
              std::string::npos)
        << notes[0];
    EXPECT_TRUE(session.info().motion_blur) << "the camera still moves";
    // An emission of zero is no light: that object blurs, without a warning.
    std::ofstream(path) << test::scene_text(
        "motion_blur.toml", {{"material = \"red\"", "material = \"red\"\nemission = [0, 0, 0]"}});
    session.load(path, 0.0);
    EXPECT_TRUE(session.info().notes.empty());
}

}  // namespace
}  // namespace spangle::test_animation
