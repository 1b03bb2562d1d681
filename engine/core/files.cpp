#include "core/files.h"

#include <fmt/format.h>
#include <sys/stat.h>

#include <filesystem>

namespace spangle {

std::string file_identity(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return path + "|missing";
    return fmt::format("{}|{}.{:09}|{}", path, static_cast<long long>(st.st_mtim.tv_sec),
                       static_cast<long long>(st.st_mtim.tv_nsec),
                       static_cast<long long>(st.st_size));
}

std::string absolute_path(const std::string& path) {
    std::error_code ec;
    const std::filesystem::path p = std::filesystem::absolute(path, ec);
    return ec ? path : p.lexically_normal().string();
}

namespace {

/** set_executable_dir()'s directory (empty: none). Written once at start-up, read after. */
std::string& executable_dir_override() {
    static std::string dir;
    return dir;
}

}  // namespace

void set_executable_dir(const std::string& dir) {
    executable_dir_override() = dir;
}

std::string executable_dir() {
    if (!executable_dir_override().empty()) return executable_dir_override();
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    return ec ? std::string() : exe.parent_path().string();
}

}  // namespace spangle
