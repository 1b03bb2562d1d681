#include "scene/frame_sequence.h"

#include <fmt/format.h>

#include <cmath>

namespace spangle {

FrameRun find_frame_run(const std::string& pattern) {
    const std::size_t slash = pattern.find_last_of('/');
    const std::size_t name = slash == std::string::npos ? 0 : slash + 1;
    FrameRun run;
    for (std::size_t i = pattern.find('#', name); i != std::string::npos;
         i = pattern.find('#', i)) {
        if (run.count > 0) {
            run.several = true;
            break;
        }
        run.first = i;
        while (i < pattern.size() && pattern[i] == '#') ++i;
        run.count = i - run.first;
    }
    return run;
}

std::string expand_frame_pattern(const std::string& pattern, int64_t frame) {
    const FrameRun run = find_frame_run(pattern);
    if (run.count == 0) return pattern;
    const auto width = static_cast<int>(run.count);
    return pattern.substr(0, run.first) + fmt::format("{:0{}d}", frame, width) +
           pattern.substr(run.first + run.count);
}

int64_t frame_at(int64_t frame_start, double fps, double time) {
    return frame_start + static_cast<int64_t>(std::llround(time * fps));
}

}  // namespace spangle
