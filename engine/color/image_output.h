#pragma once
// Writing the film: a scene-linear EXR in the working space and an optional display-referred PNG
// preview. Both are written to a temporary file in the destination directory and renamed into
// place, so a reader never sees a half-written image and a failed write leaves nothing behind.

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "color/color_config.h"
#include "core/sample_sum.h"

namespace spangle {

/** EXR options. */
struct ExrOptions {
    bool half = true;                 ///< half floats (default) or 32-bit floats
    std::string compression = "zip";  ///< OpenEXR compression name, validated
    std::vector<std::pair<std::string, std::string>> metadata;  ///< extra string attributes
    std::vector<std::pair<std::string, float>> floats;          ///< extra float attributes
    /** Extra 4x4 matrix attributes (M44f, row-major: worldToCamera, worldToNDC). */
    std::vector<std::pair<std::string, std::array<float, 16>>> matrices;
    /** Extra float-vector attributes (OpenEXR's FloatVector). */
    std::vector<std::pair<std::string, std::vector<float>>> float_vectors;
    /** Render layers written beside R, G, B in the same part: `layer_names.size()` values per
     *  pixel, interleaved, row-major; null for none. */
    const std::vector<float>* layers = nullptr;
    std::vector<std::string> layer_names;
    /** Per layer channel: 1 to write it as 32-bit floats even when `half` (data channels);
     *  shorter than layer_names: the rest follow `half`. */
    std::vector<uint8_t> layer_full_float;
    /** --spp-range parts: the film's exact sums (RGB per pixel), written as 32-bit UINT
     *  channels named by sample_sum_channels() (four words per colour, least significant
     *  first), from which spangle merge adds parts exactly; null for none. */
    const std::vector<SampleSum>* sums = nullptr;
    /** A crop: the image is the data window at (origin_x, origin_y) of a display window of
     *  display_width x display_height (0: the image is the whole frame). */
    int origin_x = 0, origin_y = 0, display_width = 0, display_height = 0;
};

/** The EXR channels holding a part's exact sums: spangle_sum.R.0 .. spangle_sum.B.3 (colour,
 *  then word, least significant first). */
const std::vector<std::string>& sample_sum_channels();

/** Where an output path is written: the file a symbolic link points to (through a chain of
 *  them, even to one that does not exist yet), else the path itself. */
std::string output_target(const std::string& path);

/** Removes the temporary file of an image being written, if any (true: one was). Async-signal-safe:
 * for a signal handler that exits at once (outputs are written to a temporary file and renamed, so
 *  the output itself is never half-written). */
bool remove_image_in_progress() noexcept;

/** While it lives, `tmp` (a temporary file written outside write_file_atomically, as a preview
 *  waiting for its EXR) is one remove_image_in_progress() removes: a second Ctrl-C while the
 *  EXR was written left the finished preview's temporary file behind. */
class TemporaryInProgress {
public:
    explicit TemporaryInProgress(const std::string& tmp);
    ~TemporaryInProgress();
    TemporaryInProgress(const TemporaryInProgress&) = delete;
    TemporaryInProgress& operator=(const TemporaryInProgress&) = delete;

private:
    void* slot_;  ///< its slot in the table the signal handler reads
};

/** Lets write_file write a temporary file beside `path`, then renames it onto `path`: the
 *  output is whole or absent (an empty result counts as a failure). Throws SpangleError. */
void write_file_atomically(const std::string& path,
                           const std::function<void(const std::string&)>& write_file);

/** Valid EXR compression names, for validation and messages. */
const std::vector<std::string>& exr_compressions();

/** Whether an EXR compression is lossy for 32-bit floats (pxr24, dwaa, dwab): data layers (ids,
 *  depth, positions, normals) written with it would be corrupt. */
bool lossy_for_floats(const std::string& compression);

/** Writes width x height RGB (working space) to `path` as EXR. Returns how many finite values
 *  were beyond the half-float range (stored as +-Inf; 0 with options.half false). Throws
 *  SpangleError. */
std::size_t write_exr(const std::string& path, const std::vector<float>& rgb, int width, int height,
                      const ColorConfig& color, const ExrOptions& options);

/** PNG preview options. */
struct PngOptions {
    /** The image is constant over aligned block x block squares, each holding the value of its
     *  pixel (min(x0 + block/2, w-1), min(y0 + block/2, h-1)) (a preview pass): one display
     *  transform per block. */
    uint32_t block = 1;
    int compression_level = 6;  ///< zlib level 0..9 (1 for pass outputs: speed over size)
    /** OCIO display and view of the preview; empty: the config's default display and its
     *  default view (the shipped config's is "Sparkle", a hue-keeping tone map that takes very
     *  bright glints to white). */
    std::string display, view;
};

/** Writes an 8-bit PNG through options.display and options.view. Throws SpangleError.
 *  Memory: 3 bytes per pixel for the display values and the encoded file, plus a few rows of
 *  floats per thread. */
void write_png_preview(const std::string& path, const std::vector<float>& rgb, int width,
                       int height, const ColorConfig& color, const PngOptions& options = {});

/** The same PNG, encoded in memory (for the live preview page). Throws SpangleError. */
std::string encode_png_preview(const std::vector<float>& rgb, int width, int height,
                               const ColorConfig& color, const PngOptions& options = {});

}  // namespace spangle
