// libFuzzer's entry point for one target (SPANGLE_FUZZ_TARGET, set by CMake).
#include <cstddef>
#include <cstdint>

#include "fuzz_targets.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    spangle::fuzz::run_one(SPANGLE_FUZZ_TARGET, data, size);
    return 0;
}
