#pragma once
// What identifies a file's content cheaply, for the caches of a watch session; where the running
// program lies; gzip'd files inflated.

#include <cstdint>
#include <string>

#include "core/error.h"

namespace spangle {

/** "path|mtime-ns|size|inode|ctime-ns" of a file, or "path|missing": equal strings mean an
 * unchanged file (an editor's save changes the modification time even when it rewrites the same
 * bytes). */
std::string file_identity(const std::string& path);

/** file_content_hash() covers every byte of files up to this size, and only the size beyond. */
constexpr uintmax_t kContentHashedBytes = uintmax_t{64} << 20;

/** A hash of a file's bytes (of its size alone beyond kContentHashedBytes); 0 when it cannot be
 *  read. What a watch session and a scene hash compare a file by (meshes, textures, LUTs). */
uint64_t file_content_hash(const std::string& path);

/** `path` made absolute (against the working directory) and normalised, for messages that
 *  say where a file was looked for: a relative path says nothing once the working directory is
 *  not the reader's. `path` itself when it cannot be made absolute. */
std::string absolute_path(const std::string& path);

/** Why `path` cannot be opened for reading ("Permission denied", "No such file or directory");
 *  empty when it can. */
std::string unreadable(const std::string& path);

/** The bytes of the gzip'd file `path`, inflated (pbrt's .pbrt.gz and .ply.gz). Throws
 *  SpangleError at `ref` for a file that cannot be opened, is not valid gzip, or inflates to more
 *  than the memory available. */
std::string inflate_gzip_file(const std::string& path, const FileLoc& ref);

/** Whether `bytes` begin with gzip's magic number. */
inline bool is_gzip(const std::string& bytes) {
    return bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f &&
           static_cast<unsigned char>(bytes[1]) == 0x8b;
}

/** Directory of the running executable (via /proc/self/exe), or empty; the directory given to
 *  set_executable_dir() when one was (a library loaded into another program, such as the Python
 *  module, whose plugins and OCIO config lie beside it rather than beside the program). */
std::string executable_dir();

/** Makes executable_dir() return `dir` from now on (empty: /proc/self/exe's again). Call before
 *  any session is made. */
void set_executable_dir(const std::string& dir);

}  // namespace spangle
