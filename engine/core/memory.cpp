#include "core/memory.h"

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

}  // namespace

uint64_t available_memory() {
    uint64_t have = mem_available();
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
