#pragma once
// Progress on long renders: a redrawn bar with samples per second and time left on a terminal,
// a plain line every 10% otherwise (logs, CI).

#include <chrono>
#include <cstdint>
#include <cstdio>

namespace spangle {

/** Reports samples done out of a total; call update() from one thread at a time. */
class Progress {
public:
    /** interactive: redraw one line in place (stderr is a terminal). */
    explicit Progress(bool interactive, std::FILE* out = stderr);
    void update(uint64_t done, uint64_t total);
    /** Ends the line on a terminal. */
    void finish();

private:
    bool interactive_;
    std::FILE* out_;
    std::chrono::steady_clock::time_point start_, last_draw_;
    int last_decile_ = -1;
    bool drawn_ = false;
};

}  // namespace spangle
