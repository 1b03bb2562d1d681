#include "table_cache.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <system_error>
#include <thread>

#include "field.h"

#ifndef SPANGLE_FLAKE_VERSION
#define SPANGLE_FLAKE_VERSION "unversioned"
#endif

namespace spangle::flake {

namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'S', 'P', 'F', 'L', 'T', 'A', 'B', '1'};
constexpr uint64_t kDefaultMegabytes = 256;

uint64_t hash_bytes(const uint8_t* p, std::size_t n, uint64_t seed) {
    uint64_t h = mix(seed, n);
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        uint64_t w;
        std::memcpy(&w, p + i, 8);
        h = mix(h, w);
    }
    uint64_t rest = 0;
    std::memcpy(&rest, p + i, n - i);
    return mix(h, rest ^ 0xa5);
}

void put_u64(std::vector<uint8_t>& out, uint64_t x) {
    const auto* p = reinterpret_cast<const uint8_t*>(&x);
    out.insert(out.end(), p, p + 8);
}

bool get_u64(const std::vector<uint8_t>& in, std::size_t& at, uint64_t& x) {
    if (at + 8 > in.size()) return false;
    std::memcpy(&x, in.data() + at, 8);
    at += 8;
    return true;
}

/** Files of the cache, oldest use first, and their total size. */
struct Entry {
    fs::path path;
    fs::file_time_type used;
    uint64_t size;
};

void trim(const fs::path& dir, uint64_t max_bytes) {
    std::error_code ec;
    std::vector<Entry> entries;
    uint64_t total = 0;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        if (it->path().extension() != ".tab") continue;
        std::error_code e2;
        const uint64_t size = it->file_size(e2);
        const auto used = it->last_write_time(e2);
        if (e2) continue;
        entries.push_back({it->path(), used, size});
        total += size;
    }
    if (total <= max_bytes) return;
    std::sort(entries.begin(), entries.end(),
              [](const Entry& a, const Entry& b) { return a.used < b.used; });
    // Down to three quarters of the bound, so that a full cache is not trimmed at every store.
    for (const Entry& e : entries) {
        if (total <= max_bytes / 4 * 3) break;
        std::error_code e2;
        if (fs::remove(e.path, e2)) total -= e.size;
    }
}

}  // namespace

const char* plugin_version() {
    return SPANGLE_FLAKE_VERSION;
}

namespace {

/** $SPANGLE_FLAKE_THREADS as a number of threads (digits alone, 1 or more: atoi took "4x" for 4
 *  and "-2" silently for the default), or 0 when it is unset, empty or not one. */
int env_table_threads() {
    const char* t = std::getenv("SPANGLE_FLAKE_THREADS");
    if (!t || !*t || std::strspn(t, "0123456789") != std::strlen(t) || std::strlen(t) > 9) return 0;
    return std::atoi(t);
}

}  // namespace

int table_threads() {
    if (const int n = env_table_threads(); n >= 1) return std::min(n, 16);
    return std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 16);
}

TableKey::TableKey(const char* kind) {
    const std::string head = std::string(kind) + '\0' + plugin_version() + '\0';
    bytes_.assign(head.begin(), head.end());
}

void TableKey::add_bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const uint8_t*>(data);
    bytes_.insert(bytes_.end(), p, p + n);
}

uint64_t TableKey::hash() const {
    return hash_bytes(bytes_.data(), bytes_.size(), 0x7ab1e);
}

TableCache::TableCache(std::string dir, uint64_t max_bytes,
                       std::function<void(const std::string&)> warn)
    : dir_(std::move(dir)), max_bytes_(max_bytes), warn_(std::move(warn)) {}

TableCache TableCache::from_environment(std::function<void(const std::string&)> warn) {
    std::string dir;
    if (const char* d = std::getenv("SPANGLE_FLAKE_CACHE"); d && *d) {
        dir = std::strcmp(d, "off") == 0 ? "" : d;
    } else if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) {
        dir = std::string(x) + "/spangle/flake";
    } else if (const char* h = std::getenv("HOME"); h && *h) {
        dir = std::string(h) + "/.cache/spangle/flake";
    }
    uint64_t mb = kDefaultMegabytes;
    if (const char* m = std::getenv("SPANGLE_FLAKE_CACHE_MB"); m && *m) {
        // Digits alone (strtoull took "-5" for 2^64 - 5); anything else is said, not ignored.
        char* end = nullptr;
        const bool digits = std::strspn(m, "0123456789") == std::strlen(m);
        const unsigned long long v = digits ? std::strtoull(m, &end, 10) : 0;
        if (digits && end && *end == '\0' && v <= (1ull << 40))
            mb = v;
        else if (warn)
            warn(std::string("SPANGLE_FLAKE_CACHE_MB='") + m +
                 "' is not a size in megabytes (0 to 2^40): the default, " +
                 std::to_string(kDefaultMegabytes) + " MB, is used");
    }
    if (const char* t = std::getenv("SPANGLE_FLAKE_THREADS");
        t && *t && env_table_threads() < 1 && warn)
        warn(std::string("SPANGLE_FLAKE_THREADS='") + t +
             "' is not a number of threads (1 or more): tables are built on every core (at most "
             "16)");
    return TableCache(dir, mb << 20, std::move(warn));
}

std::string TableCache::path_of(const TableKey& key) const {
    char name[32];
    std::snprintf(name, sizeof(name), "%016llx.tab", static_cast<unsigned long long>(key.hash()));
    return (fs::path(dir_) / name).string();
}

bool TableCache::load(const TableKey& key, std::vector<uint8_t>& table) const {
    if (!enabled()) return false;
    const std::string path = path_of(key);
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    std::vector<uint8_t> file((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
    // magic | key size | key | table size | table | checksum of everything before it
    if (file.size() < 8 + 8 + 8 + 8 || std::memcmp(file.data(), kMagic, 8) != 0) return false;
    std::size_t at = 8;
    uint64_t key_size = 0, table_size = 0, sum = 0;
    if (!get_u64(file, at, key_size) || key_size != key.bytes().size() ||
        key_size > file.size() - at ||
        !std::equal(key.bytes().begin(), key.bytes().end(),
                    file.begin() + static_cast<std::ptrdiff_t>(at)))
        return false;
    at += key_size;
    if (!get_u64(file, at, table_size) || at + table_size + 8 != file.size()) return false;
    const std::size_t body = at + table_size;
    std::size_t sum_at = body;
    if (!get_u64(file, sum_at, sum) || sum != hash_bytes(file.data(), body, 0xc4ec)) return false;
    table.assign(file.begin() + static_cast<std::ptrdiff_t>(at),
                 file.begin() + static_cast<std::ptrdiff_t>(body));
    // Reading a table counts as using it (the least recently used are trimmed first).
    std::error_code ec;
    fs::last_write_time(path, fs::file_time_type::clock::now(), ec);
    return true;
}

void TableCache::store(const TableKey& key, const std::vector<uint8_t>& table) const {
    if (!enabled() || table.size() + 64 > max_bytes_) return;
    std::vector<uint8_t> file(kMagic, kMagic + 8);
    put_u64(file, key.bytes().size());
    file.insert(file.end(), key.bytes().begin(), key.bytes().end());
    put_u64(file, table.size());
    file.insert(file.end(), table.begin(), table.end());
    put_u64(file, hash_bytes(file.data(), file.size(), 0xc4ec));
    std::error_code ec;
    fs::create_directories(dir_, ec);
    const std::string path = path_of(key);
    // A name no other writer uses: this process and thread.
    const std::string tmp =
        path + ".tmp." + std::to_string(static_cast<long long>(getpid())) + "." +
        std::to_string(std::hash<std::thread::id>{}(std::this_thread::get_id()));
    bool ok = false;
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (out) {
            out.write(reinterpret_cast<const char*>(file.data()),
                      static_cast<std::streamsize>(file.size()));
            ok = static_cast<bool>(out.flush());
        }
    }
    if (ok) {
        fs::rename(tmp, path, ec);
        ok = !ec;
    }
    if (!ok) {
        fs::remove(tmp, ec);
        // Once per process: a cache that cannot be written is a slowdown, never an error.
        static std::atomic<bool> warned{false};
        if (warn_ && !warned.exchange(true))
            warn_("flake table cache: cannot write " + path + "; tables are rebuilt per process");
        return;
    }
    trim(dir_, max_bytes_);
}

}  // namespace spangle::flake
