#include "core/check.h"

namespace spangle::detail {

void check_failed(const char* file, int line, const std::string& what) {
    throw std::logic_error(fmt::format("internal error at {}:{}: {}", file, line, what));
}

}  // namespace spangle::detail
