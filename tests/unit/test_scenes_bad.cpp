// Every file in tests/scenes_bad/ is a broken scene whose first line reads
//   # expect: LINE:COL | message substring     (or "-" for a whole-file error)
// Loading it must fail with exactly that location and a message containing the substring.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "pipeline/frame.h"
#include "test_support.h"

namespace spangle::test_scenes_bad {
namespace {

namespace fs = std::filesystem;

/** The broken scenes, relative to tests/scenes_bad/: TOML scenes there, pbrt scenes in pbrt/. */
std::vector<std::string> bad_scenes() {
    std::vector<std::string> names;
    const std::string dir = test::test_dir() + "/scenes_bad";
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().extension() == ".toml") names.push_back(e.path().filename().string());
    for (const auto& e : fs::directory_iterator(dir + "/pbrt"))
        if (e.path().extension() == ".pbrt")
            names.push_back("pbrt/" + e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

/** A test name for a bad scene: its stem, "pbrt_" before a pbrt scene's. */
std::string test_name(const std::string& file) {
    const fs::path p(file);
    const std::string stem = p.stem().string();
    return p.has_parent_path() ? p.parent_path().string() + "_" + stem : stem;
}

class BadScene : public ::testing::TestWithParam<std::string> {};

TEST_P(BadScene, FailsWithLocationAndMessage) {
    const std::string path = test::test_dir() + "/scenes_bad/" + GetParam();
    std::ifstream in(path);
    std::string first;
    std::getline(in, first);
    const std::string tag = "# expect: ";
    ASSERT_EQ(first.rfind(tag, 0), 0u) << path << " lacks its '# expect:' line";
    const std::size_t bar = first.find(" | ");
    ASSERT_NE(bar, std::string::npos);
    const std::string loc = first.substr(tag.size(), bar - tag.size());
    const std::string substring = first.substr(bar + 3);
    const std::string prefix = loc == "-" ? path + ": error: " : path + ":" + loc + ": error: ";

    FrameRequest req;
    req.scene = path;
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    req.options.threads = 1;
    try {
        render_frame(req);
        FAIL() << path << " rendered, but it is broken";
    } catch (const SpangleError& e) {
        const std::string msg = e.what();
        EXPECT_EQ(msg.rfind(prefix, 0), 0u) << "expected location " << prefix << "\n got: " << msg;
        EXPECT_NE(msg.find(substring), std::string::npos)
            << "expected: " << substring << "\n got: " << msg;
    }
}

INSTANTIATE_TEST_SUITE_P(ScenesBad, BadScene, ::testing::ValuesIn(bad_scenes()),
                         [](const ::testing::TestParamInfo<std::string>& p) {
                             return test_name(p.param);
                         });

TEST(ScenesBad, AtLeastTenDistinctCases) {
    EXPECT_GE(bad_scenes().size(), 10u);
}

TEST(ScenesBad, MissingSceneFile) {
    FrameRequest req;
    req.scene = test::test_dir() + "/scenes_bad/no_such_file.toml";
    req.ocio_config = test::shipped_ocio();
    req.log = &test::quiet_log();
    try {
        render_frame(req);
        FAIL();
    } catch (const SpangleError& e) {
        EXPECT_NE(std::string(e.what()).find("scene file"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("not found"), std::string::npos);
    }
}

}  // namespace
}  // namespace spangle::test_scenes_bad
