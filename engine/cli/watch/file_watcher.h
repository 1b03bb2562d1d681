#pragma once
// Watching files for edits with inotify (watch mode's trigger). The parent directory of each file
// is watched, not the file, so that every way editors save is seen: writing in place, truncating
// then writing, writing a temporary file and renaming it over, deleting then creating.

#include <map>
#include <set>
#include <string>
#include <vector>

namespace spangle {

/** How long the files must be quiet before a change is reported. */
struct WatchDebounce {
    int settled_ms = 15;     ///< after every touched file's save has ended
    int unsettled_ms = 250;  ///< while a save is under way or a touched file is missing
    int limit_ms = 2000;     ///< the longest a change waits
};

/** A set of files watched for saves through one inotify descriptor. */
class FileWatcher {
public:
    /** Opens the inotify descriptor; throws SpangleError when the system has none to give. */
    FileWatcher();
    ~FileWatcher();
    FileWatcher(const FileWatcher&) = delete;
    FileWatcher& operator=(const FileWatcher&) = delete;

    /** Replaces the set of watched files. The folders already watched keep their watches (and
     *  the events queued on them: a save made while the caller reloaded is not lost). A file
     *  that is a symbolic link is watched at its target too. With `any_new_file`, any file
     *  written or moved into a watched folder counts (but the names in `ignored`, and hidden
     *  names: a scene that failed on a missing file is retried when it appears). */
    void watch(const std::vector<std::string>& files, bool any_new_file = false,
               const std::vector<std::string>& ignored = {});

    /** Waits up to timeout_ms for an event on a watched file; after the first, keeps reading
     *  until the files have been quiet (an editor's save is several events; see WatchDebounce).
     *  Returns the files touched, empty on timeout or when a signal interrupts the wait. */
    std::vector<std::string> wait(int timeout_ms, const WatchDebounce& debounce = WatchDebounce());

private:
    /** Reads pending events; records watched files they touch in `hit`, with whether their
     *  last event ended a save. */
    void drain(std::map<std::string, bool>& hit);

    int fd_ = -1;
    std::map<int, std::string> dirs_;  ///< watch descriptor -> directory
    std::set<std::string> files_;      ///< absolute, normalised paths
    bool any_new_file_ = false;        ///< report any file written into a watched folder
    std::set<std::string> ignored_;    ///< except these (absolute, normalised)
};

}  // namespace spangle
