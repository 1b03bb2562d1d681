#pragma once
// Helpers shared by the unit tests: paths of the test data and a quiet logger.

#include <unistd.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "color/color_config.h"
#include "core/log.h"

namespace spangle::test {

inline std::string test_dir() {
    return SPANGLE_TEST_DIR;
}
inline std::string asset_dir() {
    return SPANGLE_ASSET_DIR;
}
inline std::string shipped_ocio() {
    return asset_dir() + "/ocio/config.ocio";
}

/** The shipped config, loaded by explicit path so $OCIO in the environment cannot change it. */
inline ColorConfig shipped_config() {
    return ColorConfig::load(shipped_ocio(), {});
}

/** Replaces every occurrence of `from` in `text` by `to` (left to right, not rescanning). */
inline void replace_all(std::string& text, const std::string& from, const std::string& to) {
    std::string out;
    std::size_t start = 0;
    for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, start)) {
        out.append(text, start, at - start);
        out += to;
        start = at + from.size();
    }
    out.append(text, start, std::string::npos);
    text = std::move(out);
}

/** The text of tests/scenes/`name` after `edits` (each from -> to, every occurrence; a `from`
 *  the file lacks throws), with its relative paths ("../../assets/..." and "textures/...")
 *  made absolute, so that the copy can be written anywhere. */
inline std::string scene_text(const std::string& name,
                              const std::vector<std::pair<std::string, std::string>>& edits = {}) {
    std::ifstream in(test_dir() + "/scenes/" + name);
    std::stringstream ss;
    ss << in.rdbuf();
    std::string text = ss.str();
    for (const auto& [from, to] : edits) {
        if (text.find(from) == std::string::npos)
            throw std::runtime_error(name + " has no '" + from + "'");
        replace_all(text, from, to);
    }
    replace_all(text, "\"../../assets/", fmt::format("\"{}/", asset_dir()));
    replace_all(text, "\"textures/", fmt::format("\"{}/scenes/textures/", test_dir()));
    return text;
}

/** A logger that drops info and warnings, so test output stays readable. */
inline const Logger& quiet_log() {
    static const Logger log{LogLevel::Error};
    return log;
}

/** A fresh empty directory under the system temp dir, removed on destruction. Its name carries
 *  the process id: ctest runs tests in parallel processes, and two tests using the same name
 *  (the helpers of one test file) must not share a folder. */
class TempDir {
public:
    explicit TempDir(const std::string& name)
        : path_(std::filesystem::temp_directory_path() /
                ("spangle_test_" + name + "_" + std::to_string(::getpid()))) {
        std::filesystem::remove_all(path_);
        std::filesystem::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    std::string file(const std::string& name) const { return (path_ / name).string(); }
    const std::filesystem::path& path() const { return path_; }

private:
    std::filesystem::path path_;
};

}  // namespace spangle::test
