#pragma once
// User-facing errors. Every mistake a user can make becomes a SpangleError carrying where it
// happened (FileLoc) and what was expected; only engine/cli/ turns one into an exit code.

#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

namespace spangle {

/** A position in a user's file: 1-based line and column, or 0 when unknown. */
struct FileLoc {
    std::string file;  ///< path as the user gave it (or as resolved)
    int line = 0;      ///< 1-based; 0 = whole file
    int column = 0;    ///< 1-based; 0 = whole line

    /** "file:line:col", "file:line" or "file", depending on what is known. */
    [[nodiscard]] std::string str() const;
};

/** An error caused by input (scene file, mesh, plugin, command line). what() is the full
 *  message, "file:line:col: error: ..." when a location is known. */
class SpangleError : public std::runtime_error {
public:
    explicit SpangleError(const std::string& message) : std::runtime_error(message) {}
    SpangleError(const FileLoc& loc, const std::string& message)
        : std::runtime_error(loc.file.empty() ? message : loc.str() + ": error: " + message) {}
};

/** The same error with `context` ("material 'paint'") said before its message, after the
 *  location: "file:3:5: error: material 'paint': ...". */
SpangleError with_context(const SpangleError& e, std::string_view context);

/** Throws SpangleError at loc with a fmt-formatted message. */
template <class... Args>
[[noreturn]] void throw_error(const FileLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
    throw SpangleError(loc, fmt::format(f, std::forward<Args>(args)...));
}

/** Throws SpangleError without a location. */
template <class... Args>
[[noreturn]] void throw_error(fmt::format_string<Args...> f, Args&&... args) {
    throw SpangleError(fmt::format(f, std::forward<Args>(args)...));
}

}  // namespace spangle
