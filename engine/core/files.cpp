#include "core/files.h"

#include <fmt/format.h>
#include <sys/stat.h>
#include <zlib.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include "core/hash.h"
#include "core/memory.h"

namespace spangle {

uint64_t file_content_hash(const std::string& path) {
    std::error_code ec;
    const uintmax_t size = std::filesystem::file_size(path, ec);
    if (ec) return 0;
    uint64_t h = hash2(0x5ce9e5ull, size);
    if (size > kContentHashedBytes) return h;
    std::ifstream in(path, std::ios::binary);
    std::vector<char> bytes(static_cast<std::size_t>(size), 0);
    if (!in.read(bytes.data(), static_cast<std::streamsize>(size))) return h;
    std::size_t i = 0;
    for (; i + 8 <= bytes.size(); i += 8) {
        uint64_t w;
        std::memcpy(&w, bytes.data() + i, 8);
        h = hash2(h, w);
    }
    uint64_t tail = 0;
    // (An empty file has no data pointer: memcpy from null is undefined even for 0 bytes.)
    if (i < bytes.size()) std::memcpy(&tail, bytes.data() + i, bytes.size() - i);
    return hash2(h, tail);
}

std::string file_identity(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return path + "|missing";
    // The inode and the change time besides the modification time: `cp -p`, `rsync -t` and
    // unpacked archives restore an old mtime, and an edit of the same size then looked
    // unchanged (a converted texture's stale copy was used).
    return fmt::format(
        "{}|{}.{:09}|{}|{}|{}.{:09}", path, static_cast<long long>(st.st_mtim.tv_sec),
        static_cast<long long>(st.st_mtim.tv_nsec), static_cast<long long>(st.st_size),
        static_cast<unsigned long long>(st.st_ino), static_cast<long long>(st.st_ctim.tv_sec),
        static_cast<long long>(st.st_ctim.tv_nsec));
}

std::string absolute_path(const std::string& path) {
    std::error_code ec;
    const std::filesystem::path p = std::filesystem::absolute(path, ec);
    return ec ? path : p.lexically_normal().string();
}

namespace {

/** set_executable_dir()'s directory (empty: none). Written once at start-up, read after. */
std::string& executable_dir_override() {
    static std::string dir;
    return dir;
}

}  // namespace

void set_executable_dir(const std::string& dir) {
    executable_dir_override() = dir;
}

std::string executable_dir() {
    if (!executable_dir_override().empty()) return executable_dir_override();
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    return ec ? std::string() : exe.parent_path().string();
}

std::string unreadable(const std::string& path) {
    errno = 0;
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) return std::strerror(errno != 0 ? errno : EACCES);
    std::fclose(f);
    return "";
}

std::string inflate_gzip_file(const std::string& path, const FileLoc& ref) {
    gzFile f = gzopen(path.c_str(), "rb");
    if (!f) throw_error(ref, "cannot open '{}': {}", path, unreadable(path));
    std::string out;
    char buf[1 << 16];
    for (;;) {
        const int n = gzread(f, buf, sizeof buf);
        if (n < 0) {
            int code = 0;
            const std::string why = gzerror(f, &code);
            gzclose(f);
            throw_error(ref, "'{}' is not a valid gzip file: {}", path, why);
        }
        if (n == 0) break;
        // Inflating can multiply the size a thousandfold: stop before memory runs out.
        if (memory_short_for(2.0 * static_cast<double>(out.size() + static_cast<std::size_t>(n))))
            throw_error(ref, "'{}' inflates to more than the memory available ({} so far)", path,
                        format_bytes(static_cast<double>(out.size())));
        out.append(buf, static_cast<std::size_t>(n));
    }
    // A stream cut short or damaged ends the reads without an error from gzread itself.
    int code = Z_OK;
    const std::string why = gzerror(f, &code);
    gzclose(f);
    if (code != Z_OK && code != Z_STREAM_END)
        throw_error(ref, "'{}' is not a valid gzip file: {}", path, why);
    return out;
}

}  // namespace spangle
