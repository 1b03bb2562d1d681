#pragma once
// The loaders a user's files reach, as fuzz targets: each takes the bytes of one file, writes
// them where the loader expects a file of that kind, and runs the loader. A SpangleError is the
// expected answer to bad input; anything else that escapes (another exception, a crash, a
// sanitizer report, a hang, memory beyond the fuzzer's limit) is a bug.

#include <cstddef>
#include <cstdint>
#include <string>

namespace spangle::fuzz {

/** Runs `target` ("scene", "pbrt", "gltf", "ply", "obj" or "cage") on one input. Returns true when
 * the loader accepted it, false when it threw a SpangleError; any other outcome propagates. Throws
 * std::invalid_argument for an unknown target. */
bool run_one(const std::string& target, const std::uint8_t* data, std::size_t size);

}  // namespace spangle::fuzz
