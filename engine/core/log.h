#pragma once
// A tiny logger: messages go to stderr with a level prefix. Passed around as part of contexts,
// not a singleton; the level threshold is a plain value.

#include <fmt/format.h>

#include <mutex>
#include <set>
#include <string>
#include <string_view>

namespace spangle {

enum class LogLevel { Debug, Info, Warning, Error };

/** The warnings already said, for a logger that says each once (watch mode: a reload that
 *  leaves a warning true does not repeat it). Thread-safe. */
class WarningsSaid {
public:
    /** True the first time `message` is seen. */
    bool first_time(std::string_view message) {
        std::lock_guard<std::mutex> lock(mutex_);
        return said_.emplace(message).second;
    }

private:
    std::mutex mutex_;
    std::set<std::string, std::less<>> said_;
};

/** Where log lines go. Quiet mode drops Info and Debug. */
struct Logger {
    LogLevel threshold = LogLevel::Info;  ///< messages below this level are dropped
    /** When set, a warning said before in the same words is not said again (not owned). */
    WarningsSaid* once = nullptr;

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
