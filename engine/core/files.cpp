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

std::string executable_dir() {
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    return ec ? std::string() : exe.parent_path().string();
}

}  // namespace spangle
