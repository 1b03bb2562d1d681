#pragma once
// Internal invariants. SPANGLE_CHECK is always on and cheap; a failure is a bug in Spangle, not a
// user mistake, so it names the source line and aborts via std::logic_error caught in the CLI.
// SPANGLE_DCHECK compiles away in release builds.

#include <fmt/format.h>

#include <stdexcept>

namespace spangle::detail {
[[noreturn]] void check_failed(const char* file, int line, const std::string& what);
}

#define SPANGLE_CHECK(cond, why)                                                          \
    do {                                                                                  \
        if (!(cond)) ::spangle::detail::check_failed(__FILE__, __LINE__, #cond ": " why); \
    } while (0)

#define SPANGLE_CHECK_OP(a, op, b)                                                              \
    do {                                                                                        \
        const auto& spangle_a_ = (a);                                                           \
        const auto& spangle_b_ = (b);                                                           \
        if (!(spangle_a_ op spangle_b_))                                                        \
            ::spangle::detail::check_failed(                                                    \
                __FILE__, __LINE__,                                                             \
                fmt::format("{} " #op " {} failed: {} vs {}", #a, #b, spangle_a_, spangle_b_)); \
    } while (0)

#define SPANGLE_CHECK_EQ(a, b) SPANGLE_CHECK_OP(a, ==, b)
#define SPANGLE_CHECK_NE(a, b) SPANGLE_CHECK_OP(a, !=, b)
#define SPANGLE_CHECK_LT(a, b) SPANGLE_CHECK_OP(a, <, b)
#define SPANGLE_CHECK_LE(a, b) SPANGLE_CHECK_OP(a, <=, b)

#ifdef NDEBUG
#define SPANGLE_DCHECK(cond, why) \
    do {                          \
    } while (0)
#else
#define SPANGLE_DCHECK(cond, why) SPANGLE_CHECK(cond, why)
#endif
