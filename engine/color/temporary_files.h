#pragma once
// The temporary files images are written to before they are renamed onto their outputs, and
// the ones a killed render left behind. An image at DIR/NAME is written as DIR/.NAME.tmpPID.N
// (PID the writing process, N a counter), locked (flock) while it is written, then renamed onto
// NAME. A stop signal removes it (remove_image_in_progress), but SIGKILL, a crash or a power cut
// cannot: the next render to the same folder removes it (remove_stale_temporaries).

#include <string>
#include <vector>

namespace spangle {

/** A temporary name beside `path`, unique to this process: ".NAME.tmpPID.N". */
std::string temporary_path_for(const std::string& path);

/** Creates `tmp` and holds an exclusive lock on it until destroyed (the file stays: it is
 *  renamed or removed by the writer). A lock that cannot be taken is no error: the lock only
 *  tells remove_stale_temporaries that someone is writing. */
class TemporaryLock {
public:
    explicit TemporaryLock(const std::string& tmp);
    ~TemporaryLock();
    TemporaryLock(const TemporaryLock&) = delete;
    TemporaryLock& operator=(const TemporaryLock&) = delete;

private:
    int fd_ = -1;  ///< an open descriptor of the file, holding the lock; -1: none
};

/** What remove_stale_temporaries found. */
struct StaleTemporaries {
    std::vector<std::string> removed;  ///< paths removed
    std::vector<std::string> failed;   ///< "PATH: why" for those that could not be removed
};

/** Removes the temporary images (".NAME.tmpPID.N" with NAME ending in .exr or .png) in folder
 *  `dir` that nobody is writing: their process PID no longer runs on this machine and no
 *  process holds their lock (a writer on another machine sharing the folder over a network file
 *  system holds it while it writes). Files of processes still running are left alone. */
StaleTemporaries remove_stale_temporaries(const std::string& dir);

}  // namespace spangle
