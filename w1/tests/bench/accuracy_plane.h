#pragma once
// The accuracy report's experiment on distance blending alone: a receding plane of flakes.

#include <string>

namespace spangle::accuracy {

/** Appends the plane experiment's section to `md`: per flake algorithm, the blending threshold
 *  pairs against the discrete lobe everywhere (time, lobe fractions, mean and structure error).
 *  `quick`: a tiny version for the smoke run. The scene is written to work_dir. */
void plane_section(std::string& md, bool quick, const std::string& work_dir, int threads);

}  // namespace spangle::accuracy
