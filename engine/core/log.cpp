#include "core/log.h"

#include <cstdio>

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
    fmt::print(stderr, "{}{}\n", prefix, message);
}

}  // namespace spangle
