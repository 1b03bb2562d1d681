#pragma once
// Helpers shared by the unit tests: paths of the test data and a quiet logger.

#include <unistd.h>

#include <filesystem>
#include <string>

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
