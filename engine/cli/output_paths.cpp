// Output paths: see output_paths.h.

#include "cli/output_paths.h"

#include "cli/usage.h"
#include "color/temporary_files.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>
#include <algorithm>
#include <cctype>

#include <cerrno>
#include <climits>
#include <cstring>
#include <filesystem>

#include "core/error.h"

namespace fs = std::filesystem;

namespace spangle {

void check_writable(const std::string& path, const char* what) {
    const fs::path p(path);
    const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
    if (path.size() >= PATH_MAX)
        throw_error("cannot write the {} '{}': the path is longer than {} bytes", what, path,
                    PATH_MAX - 1);
    // The image goes to a temporary name beside it first (".NAME.tmpPID.N"), also a name.
    if (p.filename().string().size() + 24 > NAME_MAX)
        throw_error("cannot write the {} '{}': the file name is longer than {} bytes", what, path,
                    NAME_MAX - 24);
    std::error_code ec;
    // A relative folder is said with where it is (it is the working folder's, which a user
    // reading a scene's relative paths may not expect).
    const auto said = [](const fs::path& d) {
        if (d.is_absolute()) return fmt::format("'{}'", d.string());
        std::error_code aec;
        const fs::path abs = fs::absolute(d, aec);
        return aec ? fmt::format("'{}'", d.string())
                   : fmt::format("'{}' ('{}' in the working folder)",
                                 abs.lexically_normal().string(), d.string());
    };
    const std::string folder = said(dir);
    if (!fs::exists(dir, ec)) {
        // The first folder of the path that is missing: through one ('nosuch/..') the folder
        // at its end may exist, and the message named it.
        fs::path walked;
        for (const fs::path& part : dir) {
            walked /= part;
            std::error_code wec;
            if (!fs::exists(walked, wec)) break;
            // A file on the way ('model.obj/../out.exr'): that is what is wrong.
            if (!fs::is_directory(walked, wec) && walked != dir)
                throw_error("cannot write the {} '{}': {} is not a folder", what, path,
                            said(walked));
        }
        throw_error("cannot write the {} '{}': folder {} does not exist", what, path,
                    said(walked.empty() ? dir : walked));
    }
    if (!fs::is_directory(dir, ec))
        throw_error("cannot write the {} '{}': {} is not a folder", what, path, folder);
    if (fs::is_directory(p, ec))
        throw_error("cannot write the {} '{}': it is a folder", what, path);
    // Creating a file there is the only test that holds for every case (permissions, root,
    // read-only or special file systems): the image's own temporary file is made the same way.
    const fs::path probe = dir / fmt::format(".spangle-probe-{}", ::getpid());
    const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0)
        throw_error("cannot write the {} '{}': cannot create files in folder {} ({})", what, path,
                    folder, std::strerror(errno));
    ::close(fd);
    ::unlink(probe.c_str());
}

bool same_file(const std::string& a, const std::string& b) {
    std::error_code ec1, ec2;
    const fs::path pa = fs::weakly_canonical(fs::absolute(a), ec1),
                   pb = fs::weakly_canonical(fs::absolute(b), ec2);
    if (ec1 || ec2) return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
    return pa == pb;
}

std::string frame_path(const std::string& pattern, int64_t f) {
    const std::string name = fs::path(pattern).filename().string();
    const std::size_t at = name.find('#');
    std::string out;
    if (at != std::string::npos) {
        std::size_t run = at;
        while (run < name.size() && name[run] == '#') ++run;
        const std::string num = fmt::format("{:0{}d}", f, run - at);
        out = name.substr(0, at) + num + name.substr(run);
    } else {
        const fs::path p(name);
        out = fmt::format("{}.{:04d}{}", p.stem().string(), f, p.extension().string());
    }
    return (fs::path(pattern).parent_path() / out).string();
}

bool has_extension(const std::string& path, const std::string& ext) {
    std::string e = std::filesystem::path(path).extension().string();
    std::transform(e.begin(), e.end(), e.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return e == ext;
}

void prepare_exr_output(const std::string& path) {
    if (!has_extension(path, ".exr")) usage_error("output '{}' must end in .exr", path);
    check_writable(path, "EXR");
    const StaleTemporaries found =
        remove_stale_temporaries(std::filesystem::path(path).parent_path().string());
    for (const std::string& p : found.removed)
        fmt::print(stderr,
                   "removed '{}', left by a spangle process that was killed while writing it\n", p);
    for (const std::string& why : found.failed)
        fmt::print(stderr, "warning: cannot remove a temporary image a killed process left: {}\n",
                   why);
}

}  // namespace spangle
