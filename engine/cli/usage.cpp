// Usage errors and the error line: see usage.h.

#include "cli/usage.h"

#include <cstdio>
#include <filesystem>

namespace spangle {

void check_plugin_dirs(const std::vector<std::string>& dirs) {
    for (const std::string& dir : dirs) {
        std::error_code ec;
        if (!std::filesystem::is_directory(dir, ec))
            usage_error("--plugin-path '{}' is not a folder{}", dir,
                        dir.find(':') != std::string::npos
                            ? " (one folder per --plugin-path: repeat the option, or list "
                              "folders separated by ':' in $SPANGLE_PLUGIN_PATH)"
                            : "");
    }
}

void print_error(const std::string& msg) {
    // Located messages already read "file:line:col: error: ..."; others get the prefix here.
    if (msg.find(": error: ") != std::string::npos)
        fmt::print(stderr, "{}\n", msg);
    else
        fmt::print(stderr, "spangle: error: {}\n", msg);
}

}  // namespace spangle
