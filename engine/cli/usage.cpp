// Usage errors and the error line: see usage.h.

#include "cli/usage.h"

#include <cstdio>

namespace spangle {

void print_error(const std::string& msg) {
    // Located messages already read "file:line:col: error: ..."; others get the prefix here.
    if (msg.find(": error: ") != std::string::npos)
        fmt::print(stderr, "{}\n", msg);
    else
        fmt::print(stderr, "spangle: error: {}\n", msg);
}

}  // namespace spangle
