#pragma once
// How the spangle command reports what went wrong: a bad command line found after parsing
// (UsageError, exit status 2) and the one error line every failure prints.

#include <fmt/format.h>

#include <string>
#include <utility>
#include <vector>

#include "core/error.h"

namespace spangle {

/** A bad command line (exit status 2), found after parsing (sizes, names, paths that clash). */
class UsageError : public SpangleError {
public:
    using SpangleError::SpangleError;
};

/** Throws UsageError with a fmt-formatted message. */
template <class... Args>
[[noreturn]] void usage_error(fmt::format_string<Args...> f, Args&&... args) {
    throw UsageError(fmt::format(f, std::forward<Args>(args)...));
}

/** Throws UsageError unless every `--plugin-path` folder given is a folder (a typo was searched
 *  silently, the plugins then found elsewhere on the path or not at all). */
void check_plugin_dirs(const std::vector<std::string>& dirs);

/** Prints an error to stderr: a located message ("file:line:col: error: ...") as it is, any
 *  other one after "spangle: error: ". */
void print_error(const std::string& msg);

}  // namespace spangle
