#pragma once
// Progress on long renders: a redrawn bar with samples per second and time left on a terminal,
// a plain line every 10% otherwise (logs, CI). The same for the long work before a render
// (reading, subdivision, BVH builds), shown once a piece of it has run a second.

#include <chrono>
#include <cstdint>
#include <cstdio>

#include "core/progress.h"

namespace spangle {

/** Reports samples done out of a total; call update() from one thread at a time. */
class Progress {
public:
    /** interactive: redraw one line in place (stderr is a terminal). */
    explicit Progress(bool interactive, std::FILE* out = stderr);
    /** `traced`: the samples actually traced, when adaptive sampling counts the samples of
     *  stopped pixels as done (0: done are all traced). The rate is the traced one, and the
     *  time left the remaining samples at that rate (with adaptive sampling, at most that). */
    void update(uint64_t done, uint64_t total, uint64_t traced = 0);
    /** Ends the line on a terminal. */
    void finish();

private:
    bool interactive_;
    std::FILE* out_;
    std::chrono::steady_clock::time_point start_, last_draw_;
    int last_decile_ = -1;
    bool drawn_ = false;
};

/** A WorkProgress that shows each piece of work taking over a second: on a terminal a line
 *  redrawn in place ("subdividing body.obj at level 8  45%  12s"), otherwise a line per 10%;
 *  each shown piece ends with the seconds it took. Quick pieces print nothing. */
WorkProgress work_meter(bool interactive, std::FILE* out = stderr);

}  // namespace spangle
