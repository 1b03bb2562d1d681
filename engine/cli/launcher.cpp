// What an MPI launcher says through the environment: see launcher.h.

#include "cli/launcher.h"

#include <algorithm>
#include <cstdlib>

namespace spangle {
namespace {

/** The environment variable `name` as a number in [0, 2^30); `fallback` when unset or not one. */
int env_int(const char* name, int fallback) {
    const char* v = std::getenv(name);
    if (!v || !*v) return fallback;
    char* end = nullptr;
    const long n = std::strtol(v, &end, 10);
    return end && *end == '\0' && n >= 0 && n < (1L << 30) ? static_cast<int>(n) : fallback;
}

}  // namespace

LauncherInfo launcher_info() {
    LauncherInfo l;
    l.size = env_int("OMPI_COMM_WORLD_SIZE", env_int("PMI_SIZE", 1));
    l.rank = env_int("OMPI_COMM_WORLD_RANK", env_int("PMI_RANK", 0));
    l.local_size = env_int("OMPI_COMM_WORLD_LOCAL_SIZE", env_int("MPI_LOCALNRANKS", 1));
    l.size = std::max(l.size, 1);
    l.local_size = std::max(l.local_size, 1);
    return l;
}

}  // namespace spangle
