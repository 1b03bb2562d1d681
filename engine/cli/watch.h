#pragma once
// Watching files for edits with inotify. The parent directory of each file is watched, not the
// file, so that every way editors save is seen: writing in place, truncating then writing,
// writing a temporary file and renaming it over, deleting then creating.

#include <map>
#include <set>
#include <string>
#include <vector>

namespace spangle {

class FileWatcher {
public:
    FileWatcher();
    ~FileWatcher();
    FileWatcher(const FileWatcher&) = delete;
    FileWatcher& operator=(const FileWatcher&) = delete;

    /** Replaces the set of watched files. */
    void watch(const std::vector<std::string>& files);

    /** Waits up to timeout_ms for an event on a watched file; after the first, keeps reading
     *  until debounce_ms pass without one (an editor's save is several events). Returns the
     *  files touched, empty on timeout or when a signal interrupts the wait. */
    std::vector<std::string> wait(int timeout_ms, int debounce_ms = 200);

private:
    /** Reads pending events; adds watched files they touch to `hit`. */
    void drain(std::set<std::string>& hit);

    int fd_ = -1;
    std::map<int, std::string> dirs_;  ///< watch descriptor -> directory
    std::set<std::string> files_;      ///< absolute, normalised paths
};

}  // namespace spangle
