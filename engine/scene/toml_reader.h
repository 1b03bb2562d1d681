#pragma once
// Typed, located access to one TOML table. Every getter records the key as known; finish()
// rejects any key nobody asked for, listing the valid ones, so a misspelled parameter is an error
// rather than a silent default. Used by the TOML scene reader (scene/toml_scene_reader.h).

#include <toml++/toml.h>

#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "core/math.h"

namespace spangle {

/** An interval for range checks; open ends exclude the bound. */
struct Range {
    double min = -1e300, max = 1e300;
    bool min_open = false, max_open = false;

    bool contains(double x) const {
        return (min_open ? x > min : x >= min) && (max_open ? x < max : x <= max);
    }
    std::string str() const;
};

/** Location of a TOML node in `file`. */
FileLoc loc_of(const toml::node& node, const std::string& file);

/** Readable TOML type name of a node ("string", "array", ...). */
std::string toml_type_name(const toml::node& node);

/** Reads keys of one table; see the file comment. */
class TableReader {
public:
    /** `what` names the table in messages, e.g. "[camera]" or "[[object]] #2". */
    TableReader(const toml::table& table, std::string file, std::string what);

    const std::string& what() const { return what_; }
    const std::string& file() const { return file_; }
    FileLoc loc() const { return loc_of(table_, file_); }
    /** Location of key's value, or the table's when absent. */
    FileLoc loc(std::string_view key) const;
    bool has(std::string_view key) {
        known_.insert(std::string(key));
        return table_.contains(key);
    }
    /** The raw node, marking the key known; nullptr when absent. */
    const toml::node* node(std::string_view key);

    double number(std::string_view key, double fallback, Range range);
    double number(std::string_view key, Range range);  ///< required
    int64_t integer(std::string_view key, int64_t fallback, Range range);
    bool boolean(std::string_view key, bool fallback);
    std::string string(std::string_view key, std::string fallback);
    std::string string(std::string_view key);  ///< required
    /** A 3-vector written as [x, y, z]; all finite. */
    Vec3 vec3(std::string_view key);  ///< required
    Vec3 vec3(std::string_view key, Vec3 fallback);
    /** A sub-table, or nullptr when absent (wrong type is an error). */
    const toml::table* table(std::string_view key);
    /** An array of tables (`[[key]]`), or nullptr when absent. */
    const toml::array* table_array(std::string_view key);

    /** Throws for the first key in the table that no getter asked about. */
    void finish() const;

    /** Marks this reader as the file's root table: its errors name the file, not line 1. */
    void set_whole_file() { whole_file_ = true; }

    /** Throws "`what` is missing required key 'key'" at the table. */
    [[noreturn]] void missing(std::string_view key) const;

private:
    const toml::node& required(std::string_view key);
    double to_number(const toml::node& n, std::string_view key) const;
    void check_range(double x, const toml::node& n, std::string_view key, Range range) const;

    const toml::table& table_;
    std::string file_;
    std::string what_;
    std::set<std::string, std::less<>> known_;
    bool whole_file_ = false;
};

/** Location of a key's text (falls back to its value's). */
FileLoc key_location(const toml::key& key, const toml::node& value, const std::string& file);

/** Parses a 3-vector from a node; `name` is used in messages. */
Vec3 parse_vec3(const toml::node& n, const std::string& file, std::string_view name);

/** Reads and parses the TOML file at `path` (which exists). Throws SpangleError at the place
 *  of a syntax error ("invalid TOML: ..."), and refuses a file nested deeper than the parser
 *  can take (see check_nesting in the .cpp). A file that cannot be read parses as empty. */
toml::table parse_toml_file(const std::string& path);

}  // namespace spangle
