#pragma once
// What identifies a file's content cheaply, for the caches of a watch session; where the running
// program lies.

#include <string>

namespace spangle {

/** "path|mtime-ns|size" of a file, or "path|missing": equal strings mean an unchanged file (an
 *  editor's save changes the modification time even when it rewrites the same bytes). */
std::string file_identity(const std::string& path);

/** Directory of the running executable (via /proc/self/exe), or empty. */
std::string executable_dir();

}  // namespace spangle
