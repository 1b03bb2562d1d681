#pragma once
// Where things are written in a glTF file's JSON: one pass over the text checks its syntax (an
// error at line:col, which the JSON library behind tinygltf would report without a place) and
// records the line and column of every object member and of every array element that is an
// object or an array, by its JSON path ("materials/2/pbrMetallicRoughness"), so that the reader
// can blame the place a user wrote for what is wrong or dropped.

#include <cstddef>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/error.h"

namespace spangle::gltf {

/** Line and column of the values of one JSON text, by path. */
class JsonLocations {
public:
    JsonLocations() = default;

    /** Scans `text`, the JSON of `file` (a .glb's JSON chunk counts lines from its start). Throws
     *  SpangleError at file:line:col for a syntax error or nesting deeper than 256 levels. */
    JsonLocations(std::string_view text, std::string file);

    /** Where the value at `path` is written: "" is the whole document, "nodes/3/mesh" a member
     *  of an element. A path not recorded (a scalar array element, or a value tinygltf made up)
     *  falls back to its closest recorded ancestor. */
    FileLoc at(std::string_view path) const;

    /** The file's name as messages give it. */
    const std::string& file() const { return file_; }

    /** The names in its top-level extensionsRequired, as written (escapes kept). */
    const std::vector<std::string>& required_extensions() const { return required_; }

    /** Whether the value at `path` is an object or array the file writes (exactly there). */
    bool has(std::string_view path) const { return places_.count(std::string(path)) > 0; }

    /** What the file writes at `path` (an object member, or an array element that is an object
     *  or array): 'o' object, 'a' array, 's' string, 'n' number, 'b' true or false, 'z' null;
     *  0 when nothing is recorded there. */
    char kind(std::string_view path) const {
        const auto it = places_.find(std::string(path));
        return it == places_.end() ? '\0' : it->second.kind;
    }

    /** Calls f(path, kind) for every recorded value (see kind()). */
    template <class F>
    void for_each_kind(F&& f) const {
        for (const auto& [path, place] : places_) f(path, place.kind);
    }

    /** Where a value is written, and what it is (kind()). */
    struct Place {
        int line = 0, column = 0;
        char kind = 0;
    };

    /** The text of a string, number, true or false the file writes at `path` under
     *  "buffers/", as an accessor's count, componentType, type or bufferView, a buffer view's
     *  buffer, byteOffset or byteLength, or an image's bufferView (a string in its quotes, its
     *  escapes kept), or a material's texture index ("materials/N/.../index"), for checking
     *  them before tinygltf reads them; null when none (or an
     *  object, array or null). */
    const std::string* scalar(std::string_view path) const {
        const auto it = scalars_.find(std::string(path));
        return it == scalars_.end() ? nullptr : &it->second;
    }

    /** Every scalar kept (scalar()), by path. */
    const std::unordered_map<std::string, std::string>& scalars() const { return scalars_; }

    /** Where buffer, accessor or skin object `path` ("buffers/N", "accessors/N", "skins/N") or
     *  an animation channel's target ("animations/A/channels/C/target") is written in the text:
     *  its first byte and the byte after it; {0, 0} when it is not an object the file writes. */
    std::pair<std::size_t, std::size_t> span(std::string_view path) const {
        const auto it = spans_.find(std::string(path));
        return it == spans_.end() ? std::pair<std::size_t, std::size_t>{0, 0} : it->second;
    }

private:
    std::string file_;
    std::unordered_map<std::string, Place> places_;         ///< path -> where, and what
    std::vector<std::string> required_;                     ///< extensionsRequired
    std::unordered_map<std::string, std::string> scalars_;  ///< buffers' members
    std::unordered_map<std::string, std::pair<std::size_t, std::size_t>>
        spans_;  ///< buffers, accessors, skins, channel targets
};

}  // namespace spangle::gltf
