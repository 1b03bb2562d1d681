#include "scene/frame_sequence.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>

#include "core/files.h"
#include "core/text.h"
#include "geometry/obj_reader.h"
#include "geometry/ply_reader.h"

namespace spangle {

FrameRun find_frame_run(const std::string& pattern) {
    const std::size_t slash = pattern.find_last_of('/');
    const std::size_t name = slash == std::string::npos ? 0 : slash + 1;
    FrameRun run;
    for (std::size_t i = pattern.find('#', name); i != std::string::npos;
         i = pattern.find('#', i)) {
        if (run.count > 0) {
            run.several = true;
            break;
        }
        run.first = i;
        while (i < pattern.size() && pattern[i] == '#') ++i;
        run.count = i - run.first;
    }
    return run;
}

std::string expand_frame_pattern(const std::string& pattern, int64_t frame) {
    const FrameRun run = find_frame_run(pattern);
    if (run.count == 0) return pattern;
    const auto width = static_cast<int>(run.count);
    return pattern.substr(0, run.first) + fmt::format("{:0{}d}", frame, width) +
           pattern.substr(run.first + run.count);
}

int64_t frame_at(int64_t frame_start, double fps, double time) {
    return frame_start + static_cast<int64_t>(std::llround(time * fps));
}

/** The file of a sequence `pattern` (named at `at`) for `frame`, checked to exist; `what`
 *  words it for the message ("mesh", "cage"). */
std::string sequence_file(const std::string& pattern, int64_t frame, const FileLoc& at,
                          const char* what) {
    const std::string path = expand_frame_pattern(pattern, frame);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw_error(at, "{} file of frame {} not found (looked for {}, from the sequence {})", what,
                    frame, absolute_path(path), pattern);
    return path;
}

void check_sequence_files(const SceneDescription& scene, int64_t first, int64_t last) {
    for (const ObjectDesc& d : scene.objects) {
        if (const auto* m = std::get_if<MeshFileShape>(&d.shape); m && m->sequence) {
            // PLY frames declare their counts in their headers, OBJ frames are counted by a scan
            // of their lines: a frame of another topology is found now, not after the frames
            // before it have rendered.
            const bool obj = ascii_lower(m->path).ends_with(".obj");
            uint64_t v0 = 0, f0 = 0, c0 = 0;
            std::string file0;
            for (int64_t f = first; f <= last; ++f) {
                const std::string file = sequence_file(m->path, f, m->loc, "mesh");
                uint64_t v = 0, faces = 0, corners = 0;
                if (obj ? !obj_counts(file, v, faces, corners) : !ply_header_counts(file, v, faces))
                    continue;
                if (file0.empty()) {
                    file0 = file;
                    v0 = v;
                    f0 = faces;
                    c0 = corners;
                } else if (v != v0 || faces != f0) {
                    throw_error(m->loc,
                                "mesh sequence '{}': frame {} ({}) has {} vertices and {} faces, "
                                "{} has {} and {}: every frame of a deforming mesh has one "
                                "topology",
                                m->path, f, file, v, faces, file0, v0, f0);
                } else if (corners != c0) {
                    throw_error(m->loc,
                                "mesh sequence '{}': frame {} ({}) has faces of {} corners in all, "
                                "{} of {}: every frame of a deforming mesh has one topology",
                                m->path, f, file, corners, file0, c0);
                }
            }
        }
        if (const auto* c = std::get_if<SubdivShape>(&d.shape); c && c->sequence)
            for (int64_t f = first; f <= last; ++f) sequence_file(c->path, f, c->loc, "cage");
    }
}

}  // namespace spangle
