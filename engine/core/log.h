#pragma once
// A tiny logger: messages go to stderr with a level prefix. Passed around as part of contexts,
// not a singleton; the level threshold is a plain value.

#include <fmt/format.h>

#include <string_view>

namespace spangle {

enum class LogLevel { Debug, Info, Warning, Error };

/** Where log lines go. Quiet mode drops Info and Debug. */
struct Logger {
    LogLevel threshold = LogLevel::Info;  ///< messages below this level are dropped

    void write(LogLevel level, std::string_view message) const;

    template <class... Args>
    void info(fmt::format_string<Args...> f, Args&&... args) const {
        write(LogLevel::Info, fmt::format(f, std::forward<Args>(args)...));
    }
    template <class... Args>
    void warn(fmt::format_string<Args...> f, Args&&... args) const {
        write(LogLevel::Warning, fmt::format(f, std::forward<Args>(args)...));
    }
};

}  // namespace spangle
