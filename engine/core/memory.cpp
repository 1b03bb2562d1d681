#include "core/memory.h"

#include <sys/resource.h>
#include <unistd.h>

#include <charconv>
#include <cstdlib>
#include <fstream>
#include <string>
#include <string_view>

#include "core/error.h"

namespace spangle {

namespace {

uint64_t mem_available() {
    std::ifstream in("/proc/meminfo");
    std::string key;
    uint64_t kb = 0;
    while (in >> key >> kb) {
        if (key == "MemAvailable:") return kb * 1024;
        in.ignore(256, '\n');
    }
    return 0;
}

/** "8G", "512M", "64K", "1000000": bytes; throws for anything else. */
uint64_t parse_size(std::string_view text) {
    double value = 0.0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    std::string_view unit(end, static_cast<std::size_t>(text.data() + text.size() - end));
    double scale = 1.0;
    if (unit == "K" || unit == "KiB")
        scale = 1024.0;
    else if (unit == "M" || unit == "MiB")
        scale = 1048576.0;
    else if (unit == "G" || unit == "GiB")
        scale = 1073741824.0;
    else if (unit == "T" || unit == "TiB")
        scale = 1099511627776.0;
    else if (!unit.empty())
        value = -1.0;
    if (ec != std::errc() || !(value > 0.0) || value * scale > 1.8e19)
        throw_error("SPANGLE_MEMORY_LIMIT='{}' is not a size such as 8G, 512M or 1000000", text);
    return static_cast<uint64_t>(value * scale);
}

/** What this process may still map under its address-space limit (ulimit -v, RLIMIT_AS, which
 *  schedulers set); 0 when there is no limit. */
uint64_t address_space_left() {
    rlimit r{};
    if (::getrlimit(RLIMIT_AS, &r) != 0 || r.rlim_cur == RLIM_INFINITY) return 0;
    std::ifstream statm("/proc/self/statm");
    uint64_t pages = 0;
    statm >> pages;
    const uint64_t used = pages * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
    return r.rlim_cur > used ? r.rlim_cur - used : 1;
}

/** A number read from a cgroup file; false when the file is missing or says "max". */
bool read_count(const std::string& file, uint64_t& out) {
    std::ifstream in(file);
    std::string text;
    if (!(in >> text) || text == "max") return false;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc();
}

/** What this process's cgroup may still use under its memory limit (a container's or a batch
 *  job's, which MemAvailable does not see): v2's memory.max, v1's memory.limit_in_bytes (where
 *  the namespace hides the path, the mount's root is this cgroup). 0 when there is none. */
uint64_t cgroup_memory_left() {
    std::ifstream self("/proc/self/cgroup");
    std::string line, v2, v1;
    bool has_v1 = false;
    while (std::getline(self, line)) {
        if (line.rfind("0::", 0) == 0) v2 = line.substr(3);
        const std::size_t at = line.find(":memory:");
        if (at != std::string::npos) {
            v1 = line.substr(at + 8);
            has_v1 = true;
        }
    }
    const auto left = [](uint64_t limit, uint64_t used) {
        // v1 writes "no limit" as a number near 2^63.
        if (limit >= (uint64_t{1} << 60)) return uint64_t{0};
        return limit > used ? limit - used : uint64_t{1};
    };
    uint64_t limit = 0, used = 0;
    if (has_v1) {
        for (const std::string& dir : {"/sys/fs/cgroup/memory" + (v1 == "/" ? std::string() : v1),
                                       std::string("/sys/fs/cgroup/memory")})
            if (read_count(dir + "/memory.limit_in_bytes", limit) &&
                read_count(dir + "/memory.usage_in_bytes", used))
                return left(limit, used);
        return 0;
    }
    const std::string dir = "/sys/fs/cgroup" + (v2 == "/" || v2.empty() ? std::string() : v2);
    if (read_count(dir + "/memory.max", limit) && read_count(dir + "/memory.current", used))
        return left(limit, used);
    return 0;
}

}  // namespace

uint64_t available_memory() {
    uint64_t have = mem_available();
    // The least of the machine's free memory and the process's limits.
    for (const uint64_t cap : {address_space_left(), cgroup_memory_left()})
        if (cap > 0) have = have == 0 ? cap : std::min(have, cap);
    if (const char* limit = std::getenv("SPANGLE_MEMORY_LIMIT"); limit && *limit) {
        const uint64_t cap = parse_size(limit);
        have = have == 0 ? cap : std::min(have, cap);
    }
    return have;
}

uint64_t memory_short_for(double need) {
    const uint64_t have = available_memory();
    return have > 0 && need > 0.9 * static_cast<double>(have) ? have : 0;
}

std::string format_bytes(double bytes) {
    if (bytes >= 1073741824.0) return fmt::format("{:.1f} GiB", bytes / 1073741824.0);
    if (bytes >= 10485760.0) return fmt::format("{:.0f} MiB", bytes / 1048576.0);
    if (bytes >= 1048576.0) return fmt::format("{:.1f} MiB", bytes / 1048576.0);
    return fmt::format("{:.0f} KiB", bytes / 1024.0);
}

}  // namespace spangle
