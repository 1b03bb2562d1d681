#pragma once
// A persistent cache of the flake plugin's tables (the smooth lobe's blur table, the rough coat's
// albedo, the sparse flakes' scale), shared by every process of a user: one-shot renders, MPI
// ranks, crop parts, tests and turntable frames build a material's tables once and read them
// afterwards.
//
// Where: $SPANGLE_FLAKE_CACHE (a directory; "off" disables the cache), else
// $XDG_CACHE_HOME/spangle/flake, else $HOME/.cache/spangle/flake. Size: at most
// $SPANGLE_FLAKE_CACHE_MB megabytes (default 256); storing beyond it deletes the least recently
// used tables (reading a table marks it used). A table of the default material is about 0.4 MB.
//
// Each file holds its whole key (every input the table depends on, the plugin's version and
// build included), the table and a checksum: a file is used only when its key equals the one
// asked for and its checksum holds, so a stale, foreign or damaged file is rebuilt, never read.
// Writers write a temporary file and rename it over the final name (atomic on POSIX): a reader in
// another process sees the old table, the new one or none, never a partial one; two processes
// building the same table at once both write the same bytes.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace spangle::flake {

/** Everything a table depends on, as bytes, starting with its kind and the plugin's version. */
class TableKey {
public:
    explicit TableKey(const char* kind);
    void add_bytes(const void* data, std::size_t n);
    template <class T>
    void add(const T& x) {
        add_bytes(&x, sizeof(T));
    }
    const std::vector<uint8_t>& bytes() const { return bytes_; }
    /** A 64-bit hash of the bytes (the file name). */
    uint64_t hash() const;

private:
    std::vector<uint8_t> bytes_;
};

/** The plugin's version string keys every table: the project version and a hash of the flake
 *  plugin's sources at build time. */
const char* plugin_version();

/** Threads a table is built on: $SPANGLE_FLAKE_THREADS when set (1 for the one-core figures),
 *  else every core (at most 16). A table does not depend on it. */
int table_threads();

/** A directory of cached tables. Copyable; thread-safe (every call works on files only). */
class TableCache {
public:
    /** A cache in `dir` (empty: disabled) of at most max_bytes; `warn` receives a message the
     *  first time the directory cannot be written. */
    TableCache(std::string dir, uint64_t max_bytes,
               std::function<void(const std::string&)> warn = {});
    /** The cache the environment asks for (see the header comment). */
    static TableCache from_environment(std::function<void(const std::string&)> warn = {});

    bool enabled() const { return !dir_.empty(); }
    const std::string& dir() const { return dir_; }
    uint64_t max_bytes() const { return max_bytes_; }

    /** The table stored under `key`; false when there is none (or it is unusable). */
    bool load(const TableKey& key, std::vector<uint8_t>& table) const;
    /** Stores a table under `key`, then trims the directory to its size bound. */
    void store(const TableKey& key, const std::vector<uint8_t>& table) const;
    /** The file a key's table lives in. */
    std::string path_of(const TableKey& key) const;

private:
    std::string dir_;
    uint64_t max_bytes_ = 0;
    std::function<void(const std::string&)> warn_;
};

}  // namespace spangle::flake
