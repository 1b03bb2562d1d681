#pragma once
// How much memory Spangle may still take, for the estimates made before big allocations (the
// film, subdivision levels): refusing up front with the setting to lower beats being killed by
// the kernel half way through.

#include <cstdint>
#include <string>

namespace spangle {

/** Bytes this process may still take: /proc/meminfo's MemAvailable, lowered to what its
 *  address-space limit (ulimit -v) and its cgroup's memory limit (a container's, a batch job's)
 *  leave, and to $SPANGLE_MEMORY_LIMIT when that is set (a size such as 8G, 512M or 1000000
 *  bytes; for shared machines and for tests). 0 when nothing can be read. Throws SpangleError
 *  for a malformed $SPANGLE_MEMORY_LIMIT. */
uint64_t available_memory();

/** The one rule every estimate follows: when `need` bytes would take more than 90% of
 *  available_memory(), the bytes available (for the caller's message, which names the setting
 *  to lower); 0 when it fits or nothing is known. */
uint64_t memory_short_for(double need);

/** Bytes for messages: "412 MiB", "1.6 GiB". */
std::string format_bytes(double bytes);

}  // namespace spangle
