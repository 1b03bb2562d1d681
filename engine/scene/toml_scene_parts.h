#pragma once

#include <vector>
// What the two files of the TOML scene reader share (toml_scene_reader.cpp reads the scene's
// tables, toml_material_reader.cpp its materials, colours and textures). Internal to the reader.

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "scene/scene_description.h"
#include "scene/toml_reader.h"

namespace spangle::toml_scene {

/** The file being read. */
struct ReadContext {
    std::string file;           ///< scene path as given (FileLoc::file of every location)
    std::filesystem::path dir;  ///< its folder, for relative paths
};

/** Values that must not be negative (intensities, colours). */
constexpr Range kNonNegative{0.0, 1e30, false, false};

/** `[r, g, b]` (bare) or `{ rgb = [r, g, b], space = "name" }`, as written. */
ColorDesc read_raw_color(const ReadContext& ctx, const toml::node& n, std::string_view name);

/** The colour under `key`, checked non-negative; none when absent. */
std::optional<ColorDesc> read_color(const ReadContext& ctx, TableReader& r, std::string_view key);

/** `[a, b]`: an array of exactly two numbers, into a and b; false for anything else. */
bool two_numbers(const toml::node& n, float& a, float& b);

/** An array of finite numbers whose length is `size` or `other_size` (0: only `size`), into
 *  `out`; false for anything else (not an array, another length, a non-number, inf or nan). */
bool finite_numbers(const toml::node& n, std::size_t size, std::vector<double>& out,
                    std::size_t other_size = 0);

/** A [[material]] table (finished: no unknown key left). */
MaterialDesc read_material(const ReadContext& ctx, TableReader& r);

/** A colour texture table `{ texture = "file", space, scale, uv_transform, wrap, filter }` (as a
 *  material parameter takes it, without `vertex_color`: an object's emission), named `name` in
 *  messages. */
TextureDesc read_color_texture(const ReadContext& ctx, const toml::table& t, std::string_view name);

}  // namespace spangle::toml_scene
