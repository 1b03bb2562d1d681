// Usage errors and the error line: see usage.h.

#include "cli/usage.h"

#include <cstdio>
#include <filesystem>

#include "shading/plugin_loader.h"

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
    // $SPANGLE_PLUGIN_PATH's folders that are not there: said (a typo in it left the render
    // on the plugins beside the binary, silently), not refused (a shared environment may list
    // folders some machines lack).
    for (const std::string& dir : env_plugin_dirs()) {
        std::error_code ec;
        if (!std::filesystem::is_directory(dir, ec))
            fmt::print(stderr, "warning: $SPANGLE_PLUGIN_PATH names '{}', which is not a folder\n",
                       dir);
    }
}

void print_error(const std::string& msg) {
    // Located messages already read "file:line:col: error: ..."; others get the prefix here.
    // Written without fmt::print, which throws when the write fails (a closed terminal): a
    // throw here, in the handler of an error, ended the process in std::terminate.
    const std::string line = msg.find(": error: ") != std::string::npos
                                 ? msg + "\n"
                                 : fmt::format("spangle: error: {}\n", msg);
    std::fwrite(line.data(), 1, line.size(), stderr);
}

}  // namespace spangle
