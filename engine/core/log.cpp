#include "core/log.h"

#include <cstdio>
#include <string>

namespace spangle {

void Logger::write(LogLevel level, std::string_view message) const {
    if (level < threshold) return;
    if (level == LogLevel::Warning && once && !once->first_time(message)) return;
    const char* prefix = "";
    switch (level) {
        case LogLevel::Debug:
            prefix = "debug: ";
            break;
        case LogLevel::Info:
            prefix = "";
            break;
        case LogLevel::Warning:
            prefix = "warning: ";
            break;
        case LogLevel::Error:
            prefix = "error: ";
            break;
    }
    // Written without fmt::print, which throws when the write fails: a closed terminal (EIO
    // after a hangup) is no reason to stop a render or lose its image.
    const std::string line = fmt::format("{}{}\n", prefix, message);
    std::fwrite(line.data(), 1, line.size(), stderr);
}

}  // namespace spangle
