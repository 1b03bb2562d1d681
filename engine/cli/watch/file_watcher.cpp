// Watching files with inotify: see file_watcher.h.

#include "cli/watch/file_watcher.h"

#include <poll.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>

#include "core/error.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** `path` made absolute and lexically normal, as the watched set holds it. */
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

void FileWatcher::watch(const std::vector<std::string>& files, bool any_new_file,
                        const std::vector<std::string>& ignored) {
    files_.clear();
    std::set<std::string> dirs;
    const auto add = [&](const std::string& p) {
        files_.insert(p);
        dirs.insert(fs::path(p).parent_path().string());
    };
    for (const auto& f : files) {
        const std::string p = normal(f);
        add(p);
        // A link (a "current" scene pointing at a version file): its target's folder is where
        // an editor's save of the target shows up.
        std::error_code ec;
        if (fs::is_symlink(p, ec)) {
            const fs::path target = fs::weakly_canonical(p, ec);
            if (!ec) add(target.lexically_normal().string());
        }
    }
    any_new_file_ = any_new_file;
    ignored_.clear();
    for (const auto& f : ignored) ignored_.insert(normal(f));
    // Folders no longer needed lose their watch; those kept keep theirs (re-adding every watch
    // gave new descriptors, and the events queued under the old ones were dropped).
    for (auto it = dirs_.begin(); it != dirs_.end();) {
        if (dirs.count(it->second) == 0) {
            inotify_rm_watch(fd_, it->first);
            it = dirs_.erase(it);
        } else {
            dirs.erase(it->second);
            ++it;
        }
    }
    for (const auto& d : dirs) {
        const int wd =
            inotify_add_watch(fd_, d.c_str(),
                              IN_CLOSE_WRITE | IN_MOVED_TO | IN_CREATE | IN_DELETE | IN_MODIFY |
                                  IN_MOVED_FROM | IN_ATTRIB | IN_DELETE_SELF | IN_MOVE_SELF);
        if (wd >= 0) dirs_[wd] = d;
    }
}

void FileWatcher::drain(std::map<std::string, bool>& hit) {
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
            if (it == dirs_.end()) continue;
            if ((ev.mask & (IN_IGNORED | IN_DELETE_SELF | IN_MOVE_SELF)) != 0) {
                // The folder itself went (deleted, or moved: its watch would follow it away):
                // the next watch() adds one at the path again.
                if ((ev.mask & IN_IGNORED) == 0) inotify_rm_watch(fd_, ev.wd);
                dirs_.erase(it);
                continue;
            }
            if (ev.len == 0) continue;
            const std::string path = (fs::path(it->second) / name).string();
            if (!files_.count(path)) {
                // Waiting on a scene that failed: a new file (written or moved in) may be the
                // one it lacked. Not an output, not a hidden temporary.
                const bool arrived = (ev.mask & (IN_CLOSE_WRITE | IN_MOVED_TO)) != 0;
                if (!any_new_file_ || !arrived || name[0] == '.' || ignored_.count(path)) continue;
            }
            // Settled: the last event ends a save (closed after writing, renamed into place, or
            // only its times or mode changed). Anything else means a save still under way.
            auto [entry, fresh] = hit.emplace(path, false);
            if ((ev.mask & (IN_CLOSE_WRITE | IN_MOVED_TO)) != 0)
                entry->second = true;
            else if ((ev.mask & IN_ATTRIB) != 0)
                entry->second = fresh || entry->second;
            else
                entry->second = false;
        }
    }
}

std::vector<std::string> FileWatcher::wait(int timeout_ms, const WatchDebounce& debounce) {
    std::map<std::string, bool> hit;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return {};
    drain(hit);
    if (hit.empty()) return {};
    // Debounce: keep reading until the files have been quiet for a while: briefly when every
    // save looks finished, longer while one is under way or a file is missing (deleted, to be
    // created again), but never past debounce.limit_ms in all.
    const auto start = std::chrono::steady_clock::now();
    for (;;) {
        bool settled = true;
        for (const auto& [path, done] : hit) {
            std::error_code ec;
            settled = settled && done && fs::exists(path, ec);
        }
        const int elapsed = static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                                 std::chrono::steady_clock::now() - start)
                                                 .count());
        const int left = debounce.limit_ms - elapsed;
        if (left <= 0) break;
        pollfd q{fd_, POLLIN, 0};
        const int r =
            ::poll(&q, 1, std::min(left, settled ? debounce.settled_ms : debounce.unsettled_ms));
        if (r <= 0) break;  // quiet long enough, or a signal
        drain(hit);
    }
    std::vector<std::string> out;
    for (const auto& [path, done] : hit) out.push_back(path);
    return out;
}

}  // namespace spangle
