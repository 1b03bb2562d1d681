// Temporary image files and their leftovers: see temporary_files.h.

#include "color/temporary_files.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <system_error>

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** The PID of a temporary image's name (".NAME.tmpPID.N", NAME ending in .exr or .png); 0 when
 *  `name` is not one. */
long temporary_pid(const std::string& name) {
    if (name.size() < 2 || name[0] != '.') return 0;
    const std::size_t tmp = name.rfind(".tmp");
    if (tmp == std::string::npos || tmp < 5) return 0;
    const std::string image = name.substr(1, tmp - 1);
    if (!image.ends_with(".exr") && !image.ends_with(".png")) return 0;
    const std::string rest = name.substr(tmp + 4);  // "PID.N"
    const std::size_t dot = rest.find('.');
    if (dot == 0 || dot == std::string::npos || dot + 1 == rest.size()) return 0;
    for (std::size_t i = 0; i < rest.size(); ++i)
        if (i != dot && (rest[i] < '0' || rest[i] > '9')) return 0;
    if (dot > 9) return 0;  // beyond any pid_max
    return std::stol(rest.substr(0, dot));
}

/** Whether process `pid` runs on this machine (EPERM: it runs, as another user). */
bool process_runs(long pid) {
    return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
}

/** Whether some process holds the lock of `path` (a writer still at it). */
bool locked(const fs::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (fd < 0) return false;
    const bool held = ::flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK;
    ::close(fd);  // releases the lock if we took it
    return held;
}

}  // namespace

std::string temporary_path_for(const std::string& path) {
    static std::atomic<unsigned> counter{0};
    const fs::path p(path);
    return (p.parent_path() /
            fmt::format(".{}.tmp{}.{}", p.filename().string(), ::getpid(), counter++))
        .string();
}

TemporaryLock::TemporaryLock(const std::string& tmp) {
    fd_ = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0666);
    // flock (not fcntl) locks belong to this descriptor: the writer's own open and close of
    // the file do not release them.
    if (fd_ >= 0) ::flock(fd_, LOCK_EX | LOCK_NB);
}

TemporaryLock::~TemporaryLock() {
    if (fd_ >= 0) ::close(fd_);
}

StaleTemporaries remove_stale_temporaries(const std::string& dir) {
    StaleTemporaries out;
    std::error_code ec;
    const fs::path folder = dir.empty() ? fs::path(".") : fs::path(dir);
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        const long pid = temporary_pid(name);
        if (pid <= 0 || pid == ::getpid() || process_runs(pid)) continue;
        std::error_code type_ec;
        if (!it->is_regular_file(type_ec) || locked(it->path())) continue;
        // Named as the output was: "NAME" in the working folder, not "./NAME".
        const std::string shown = dir.empty() ? name : it->path().string();
        if (::unlink(it->path().c_str()) == 0)
            out.removed.push_back(shown);
        else if (errno != ENOENT)  // another render removed it first
            out.failed.push_back(fmt::format("{}: {}", shown, std::strerror(errno)));
    }
    return out;
}

}  // namespace spangle
