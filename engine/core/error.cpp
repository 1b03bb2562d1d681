#include "core/error.h"

namespace spangle {

std::string FileLoc::str() const {
    if (line <= 0) return file;
    if (column <= 0) return fmt::format("{}:{}", file, line);
    return fmt::format("{}:{}:{}", file, line, column);
}

SpangleError with_context(const SpangleError& e, std::string_view context) {
    const std::string msg = e.what();
    const std::string prefix = fmt::format("{}: ", context);
    constexpr std::string_view kMark = ": error: ";
    const std::size_t at = msg.find(kMark);
    const std::size_t start = at == std::string::npos ? 0 : at + kMark.size();
    if (msg.compare(start, prefix.size(), prefix) == 0) return e;  // said already
    return SpangleError(msg.substr(0, start) + prefix + msg.substr(start));
}

}  // namespace spangle
