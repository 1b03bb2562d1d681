#include "cli/watch.h"

#include <poll.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "core/error.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

std::string normal(const std::string& path) {
    std::error_code ec;
    const fs::path abs = fs::absolute(path, ec);
    return (ec ? fs::path(path) : abs).lexically_normal().string();
}

}  // namespace

FileWatcher::FileWatcher() {
    fd_ = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (fd_ < 0) throw_error("cannot watch files: inotify_init1 failed (errno {})", errno);
}

FileWatcher::~FileWatcher() {
    if (fd_ >= 0) ::close(fd_);
}

void FileWatcher::watch(const std::vector<std::string>& files) {
    for (const auto& [wd, dir] : dirs_) inotify_rm_watch(fd_, wd);
    dirs_.clear();
    files_.clear();
    std::set<std::string> dirs;
    for (const auto& f : files) {
        const std::string p = normal(f);
        files_.insert(p);
        dirs.insert(fs::path(p).parent_path().string());
    }
    for (const auto& d : dirs) {
        const int wd = inotify_add_watch(fd_, d.c_str(),
                                         IN_CLOSE_WRITE | IN_MOVED_TO | IN_CREATE | IN_DELETE |
                                             IN_MODIFY | IN_MOVED_FROM | IN_ATTRIB);
        if (wd >= 0) dirs_[wd] = d;
    }
}

void FileWatcher::drain(std::set<std::string>& hit) {
    alignas(inotify_event) char buf[16384];
    for (;;) {
        const ssize_t n = ::read(fd_, buf, sizeof(buf));
        if (n <= 0) return;
        for (ssize_t off = 0; off < n;) {
            inotify_event ev;
            std::memcpy(&ev, buf + off, sizeof(ev));
            const char* name = buf + off + static_cast<ssize_t>(sizeof(inotify_event));
            off += static_cast<ssize_t>(sizeof(inotify_event) + ev.len);
            auto it = dirs_.find(ev.wd);
            if (it == dirs_.end() || ev.len == 0) continue;
            const std::string path = (fs::path(it->second) / name).string();
            if (files_.count(path)) hit.insert(path);
        }
    }
}

std::vector<std::string> FileWatcher::wait(int timeout_ms, int debounce_ms) {
    std::set<std::string> hit;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return {};
    drain(hit);
    if (hit.empty()) return {};
    // Debounce: keep going until the files have been quiet for debounce_ms.
    for (;;) {
        pollfd q{fd_, POLLIN, 0};
        const int r = ::poll(&q, 1, debounce_ms);
        if (r < 0 && errno == EINTR) break;
        if (r <= 0) break;
        drain(hit);
    }
    return {hit.begin(), hit.end()};
}

}  // namespace spangle
