#include "scene/scene_paths.h"

#include <fmt/format.h>

#include "core/files.h"

namespace fs = std::filesystem;

namespace spangle {

std::string find_scene_file(const std::string& given, const fs::path& dir, std::string_view key,
                            const FileLoc& at) {
    if (given.empty()) throw_error(at, "'{}' must not be empty", key);
    fs::path p(given);
    if (p.is_relative()) p = dir / p;
    std::error_code ec;
    // The key names the file ("mesh", "file"): "file file" reads badly.
    const std::string what = key == "file" ? std::string("file") : fmt::format("{} file", key);
    if (fs::is_directory(p, ec))
        throw_error(at, "{} '{}' is a folder, not a file ({})", what, given,
                    absolute_path(p.string()));
    if (!fs::is_regular_file(p, ec))
        throw_error(at, "{} '{}' not found (looked for {})", what, given,
                    absolute_path(p.string()));
    // A file that is there but cannot be read (its permissions): said here, at the key, not
    // later as an empty or damaged file (an [[import]] read as empty left its objects out of
    // the render without a word).
    if (const std::string why = unreadable(p.string()); !why.empty())
        throw_error(at, "{} '{}' cannot be read: {} ({})", what, given, why,
                    absolute_path(p.string()));
    return p.lexically_normal().string();
}

void check_scene_file(const std::string& path) {
    std::error_code ec;
    if (!fs::exists(path, ec))
        throw_error("scene file '{}' not found (looked for {})", path, absolute_path(path));
    if (!fs::is_regular_file(path, ec))
        throw_error("scene file '{}' is not a regular file (a folder, a device or a pipe)", path);
    if (const std::string why = unreadable(path); !why.empty())
        throw_error("scene file '{}' cannot be read: {}", path, why);
}

}  // namespace spangle
