#include "scene/toml_reader.h"

#include "core/files.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/text.h"

namespace spangle {

std::string Range::str() const {
    return fmt::format("{}{}, {}{}", min_open ? "(" : "[", min, max, max_open ? ")" : "]");
}

FileLoc loc_of(const toml::node& node, const std::string& file) {
    const auto& s = node.source();
    return {file, static_cast<int>(s.begin.line), static_cast<int>(s.begin.column)};
}

std::string toml_type_name(const toml::node& node) {
    switch (node.type()) {
        case toml::node_type::table:
            return "a table";
        case toml::node_type::array:
            return "an array";
        case toml::node_type::string:
            return "a string";
        case toml::node_type::integer:
            return "an integer";
        case toml::node_type::floating_point:
            return "a float";
        case toml::node_type::boolean:
            return "a boolean";
        case toml::node_type::date:
            return "a date";
        case toml::node_type::time:
            return "a time";
        case toml::node_type::date_time:
            return "a date-time";
        default:
            return "nothing";
    }
}

TableReader::TableReader(const toml::table& table, std::string file, std::string what)
    : table_(table), file_(std::move(file)), what_(std::move(what)) {}

FileLoc TableReader::loc(std::string_view key) const {
    const toml::node* n = table_.get(key);
    return n ? loc_of(*n, file_) : loc();
}

const toml::node* TableReader::node(std::string_view key) {
    known_.insert(std::string(key));
    return table_.get(key);
}

namespace {

/** A key's own location (the key text, not its value). */
FileLoc key_loc(const toml::key& key, const toml::node& value, const std::string& file) {
    const auto& s = key.source();
    FileLoc at{file, static_cast<int>(s.begin.line), static_cast<int>(s.begin.column)};
    return at.line == 0 ? loc_of(value, file) : at;
}

std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    // Unread, a scene or an import was an empty file: a missing camera, or objects silently
    // left out.
    if (!in) {
        const std::string why = unreadable(path);
        throw_error(FileLoc{path, 0, 0}, "cannot read the file: {}",
                    why.empty() ? std::string("it cannot be opened") : why);
    }
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw_error(FileLoc{path, 0, 0}, "cannot read the file: a read error");
    return ss.str();
}

/** The TOML parser recurses once per nesting level and per dotted key part: a hostile file
 *  (50,000 dotted parts, arrays nested 100,000 deep) overflowed the stack. This scan, over the
 *  raw text with strings and comments skipped, refuses such files first. */
void check_nesting(const std::string& text, const std::string& path) {
    constexpr int kMaxDepth = 64, kMaxKeyParts = 128;
    std::vector<char> open;  // '[' or '{' not yet closed
    bool key = true;         // in a key: before '=' on a line or after '{' or ',' in a table
    int parts = 1, line = 1, column = 1;
    const auto fail = [&](const char* what, int limit) {
        throw_error(FileLoc{path, line, column}, "{} (at most {}); the scene cannot be this deep",
                    what, limit);
    };
    for (std::size_t i = 0; i < text.size(); ++i, ++column) {
        const char c = text[i];
        if (c == '\n') {
            ++line;
            column = 0;
            if (open.empty()) key = true, parts = 1;
            continue;
        }
        if (c == '#') {  // a comment, to the end of the line
            while (i + 1 < text.size() && text[i + 1] != '\n') ++i;
            continue;
        }
        if (c == '"' || c == '\'') {  // a string: basic, literal, or either multi-line
            const bool triple = text.compare(i, 3, std::string(3, c)) == 0;
            i += triple ? 3 : 1;
            for (; i < text.size(); ++i) {
                if (text[i] == '\n') ++line, column = 0;
                if (c == '"' && text[i] == '\\') {
                    ++i;
                    continue;
                }
                if (text[i] == c && (!triple || text.compare(i, 3, std::string(3, c)) == 0)) {
                    if (triple) i += 2;
                    break;
                }
            }
            continue;
        }
        if (c == '[' || c == '{') {
            open.push_back(c);
            if (static_cast<int>(open.size()) > kMaxDepth)
                fail("arrays and tables nested too deep", kMaxDepth);
            if (c == '{') key = true, parts = 1;
        } else if ((c == ']' || c == '}') && !open.empty()) {
            open.pop_back();
        } else if (c == '=') {
            key = false;
        } else if (c == ',' && !open.empty() && open.back() == '{') {
            key = true;
            parts = 1;
        } else if (c == '.' && key) {
            if (++parts > kMaxKeyParts) fail("a key of too many dotted parts", kMaxKeyParts);
        }
    }
}

}  // namespace

void TableReader::missing(std::string_view key) const {
    // A required key that is absent is most often a misspelling: point at the typo instead.
    for (auto&& [k, value] : table_) {
        if (known_.count(k.str()) || did_you_mean(k.str(), {std::string(key)}).empty()) continue;
        throw_error(key_loc(k, value, file_), "unknown key '{}' in {}; did you mean '{}'?", k.str(),
                    what_, key);
    }
    throw_error(whole_file_ ? FileLoc{file_, 0, 0} : loc(), "{} is missing required key '{}'",
                what_, key);
}

const toml::node& TableReader::required(std::string_view key) {
    const toml::node* n = node(key);
    if (!n) missing(key);
    return *n;
}

double TableReader::to_number(const toml::node& n, std::string_view key) const {
    if (auto i = n.as_integer()) return static_cast<double>(i->get());
    if (auto f = n.as_floating_point()) {
        const double x = f->get();
        if (!std::isfinite(x))
            throw_error(loc_of(n, file_), "'{}' must be a finite number, got {}", key, x);
        return x;
    }
    throw_error(loc_of(n, file_), "'{}' must be a number, got {}", key, toml_type_name(n));
}

void TableReader::check_range(double x, const toml::node& n, std::string_view key,
                              Range range) const {
    if (!range.contains(x))
        throw_error(loc_of(n, file_), "'{}' must be in {}, got {}", key, range.str(), x);
}

double TableReader::number(std::string_view key, double fallback, Range range) {
    const toml::node* n = node(key);
    if (!n) return fallback;
    const double x = to_number(*n, key);
    check_range(x, *n, key, range);
    return x;
}

double TableReader::number(std::string_view key, Range range) {
    const toml::node& n = required(key);
    const double x = to_number(n, key);
    check_range(x, n, key, range);
    return x;
}

int64_t TableReader::integer(std::string_view key, int64_t fallback, Range range) {
    const toml::node* n = node(key);
    if (!n) return fallback;
    auto i = n->as_integer();
    if (!i)
        throw_error(loc_of(*n, file_), "'{}' must be an integer, got {}", key, toml_type_name(*n));
    check_range(static_cast<double>(i->get()), *n, key, range);
    return i->get();
}

bool TableReader::boolean(std::string_view key, bool fallback) {
    const toml::node* n = node(key);
    if (!n) return fallback;
    auto b = n->as_boolean();
    if (!b)
        throw_error(loc_of(*n, file_), "'{}' must be true or false, got {}", key,
                    toml_type_name(*n));
    return b->get();
}

namespace {

/** A string value; a NUL character in it (TOML's \u0000) is an error: a path or a name with
 *  one stops at it in every system call and message (the reason was cut off). */
std::string string_of(const toml::node& n, std::string_view key, const std::string& file) {
    auto s = n.as_string();
    if (!s) throw_error(loc_of(n, file), "'{}' must be a string, got {}", key, toml_type_name(n));
    if (s->get().find('\0') != std::string::npos)
        throw_error(loc_of(n, file), "'{}' must not contain a NUL character (\\u0000)", key);
    return s->get();
}

}  // namespace

std::string TableReader::string(std::string_view key, std::string fallback) {
    const toml::node* n = node(key);
    return n ? string_of(*n, key, file_) : fallback;
}

std::string TableReader::string(std::string_view key) {
    return string_of(required(key), key, file_);
}

Vec3 parse_vec3(const toml::node& n, const std::string& file, std::string_view name) {
    auto arr = n.as_array();
    if (!arr || arr->size() != 3)
        throw_error(loc_of(n, file), "'{}' must be an array of 3 numbers, got {}", name,
                    arr ? fmt::format("an array of {}", arr->size()) : toml_type_name(n));
    float v[3];
    for (std::size_t i = 0; i < 3; ++i) {
        const toml::node& e = (*arr)[i];
        double x;
        if (auto k = e.as_integer())
            x = static_cast<double>(k->get());
        else if (auto f = e.as_floating_point())
            x = f->get();
        else
            throw_error(loc_of(e, file), "'{}' element {} must be a number, got {}", name, i,
                        toml_type_name(e));
        if (!std::isfinite(x) || std::fabs(x) > 1e30)
            throw_error(loc_of(e, file), "'{}' element {} must be finite and within +-1e30, got {}",
                        name, i, x);
        v[i] = static_cast<float>(x);
    }
    return {v[0], v[1], v[2]};
}

Vec3 TableReader::vec3(std::string_view key) {
    return parse_vec3(required(key), file_, key);
}

Vec3 TableReader::vec3(std::string_view key, Vec3 fallback) {
    const toml::node* n = node(key);
    return n ? parse_vec3(*n, file_, key) : fallback;
}

const toml::table* TableReader::table(std::string_view key) {
    const toml::node* n = node(key);
    if (!n) return nullptr;
    auto t = n->as_table();
    if (!t) throw_error(loc_of(*n, file_), "'{}' must be a table, got {}", key, toml_type_name(*n));
    return t;
}

const toml::array* TableReader::table_array(std::string_view key) {
    const toml::node* n = node(key);
    if (!n) return nullptr;
    auto a = n->as_array();
    if (!a || !a->is_array_of_tables())
        throw_error(loc_of(*n, file_), "'{}' must be written as [[{}]] tables, got {}", key, key,
                    toml_type_name(*n));
    return a;
}

namespace {

/** Where a well-known key belongs, for one written in another table (spp in [camera] was
 *  "did you mean 'up'?"): "; 'spp' belongs in [render]", or "". */
std::string belongs_elsewhere(const std::string& key, const std::string& table) {
    static const std::pair<const char*, std::vector<const char*>> kPlaces[] = {
        {"[render]",
         {"width", "height", "spp", "max_depth", "rr_depth", "seed", "working_space", "color_space",
          "filter", "filter_radius", "filter_samples", "frame_start", "frame_end", "fps", "shutter",
          "noise_threshold", "min_spp", "max_spp", "transparent_background"}},
        {"[camera]", {"position", "look_at", "up", "fov", "projection", "ortho_height"}},
        {"the material's params = { ... }",
         {"albedo", "base_color", "roughness", "roughness_v", "ior", "preset", "density",
          "flake_weight", "flake_roughness", "gamma", "coat", "metallic"}},
    };
    const bool in_material = table.find("[[material]]") != std::string::npos;
    // A texture's table: its own keys are near the material's, not the render's ('height' in a
    // normal map was sent to [render]).
    if (table.starts_with("texture '")) {
        if (key == "height" && table != "texture 'bump_map'")
            return "; 'height' is a bump map's (bump_map = { texture = ..., height = ... })";
        return "";
    }
    for (const auto& [place, keys] : kPlaces) {
        const std::string_view p(place);
        if (table.find(place) != std::string::npos) continue;
        // Lights and objects have positions of their own: camera keys are hinted only from
        // [render] and [environment]; parameters only from a material.
        if (p == "[camera]" && table != "[render]" && table != "[environment]") continue;
        if (p.starts_with("the material") && !in_material) continue;
        for (const char* k : keys)
            if (key == k) return fmt::format("; '{}' belongs in {}", key, place);
    }
    return "";
}

}  // namespace

void TableReader::finish() const {
    for (auto&& [key, value] : table_) {
        if (known_.count(key.str())) continue;
        std::string hint = belongs_elsewhere(std::string(key.str()), what_);
        if (hint.empty())
            hint = did_you_mean(key.str(), std::vector<std::string>(known_.begin(), known_.end()));
        throw_error(key_loc(key, value, file_), "unknown key '{}' in {}{} (valid keys: {})",
                    key.str(), what_, hint, fmt::join(known_, ", "));
    }
}

FileLoc key_location(const toml::key& key, const toml::node& value, const std::string& file) {
    return key_loc(key, value, file);
}

namespace {

/** The key set just before `column` of `line` (toml++ reports a key set twice at its value):
 *  "key = " read backwards, quoted or bare (dotted parts kept); "" when the text there is not
 *  one. Finds the duplicate inside an inline table, where the line's first key is another. */
std::string key_before(const std::string& text, std::size_t line, std::size_t column) {
    std::size_t at = 0;
    for (std::size_t l = 1; l < line && at != std::string::npos; ++l) {
        at = text.find('\n', at);
        if (at != std::string::npos) ++at;
    }
    if (at == std::string::npos || column < 1) return "";
    std::size_t p = at + column - 1;  // the value's first character
    if (p > text.size()) return "";
    const auto blank = [&](std::size_t i) { return text[i] == ' ' || text[i] == '\t'; };
    while (p > at && blank(p - 1)) --p;
    if (p == at || text[p - 1] != '=') return "";
    --p;
    while (p > at && blank(p - 1)) --p;
    const std::size_t end = p;
    if (p > at && (text[p - 1] == '"' || text[p - 1] == '\'')) {
        const char q = text[p - 1];
        const std::size_t open = text.rfind(q, p - 2);
        if (open == std::string::npos || open < at) return "";
        return text.substr(open + 1, p - 2 - open);
    }
    const auto bare = [&](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
    };
    while (p > at && bare(text[p - 1])) --p;
    return text.substr(p, end - p);
}

/** The key a "key = value" line sets, unquoted ("" when the line is not one). */
std::string key_of_line(const std::string& text, std::size_t line) {
    std::size_t at = 0;
    for (std::size_t l = 1; l < line && at != std::string::npos; ++l) {
        at = text.find('\n', at);
        if (at != std::string::npos) ++at;
    }
    if (at == std::string::npos) return "";
    const std::size_t end = text.find('\n', at);
    const std::string row = text.substr(at, end == std::string::npos ? end : end - at);
    const std::size_t eq = row.find('=');
    if (eq == std::string::npos) return "";
    std::string key = row.substr(0, eq);
    const std::size_t b = key.find_first_not_of(" \t"), e = key.find_last_not_of(" \t");
    if (b == std::string::npos) return "";
    key = key.substr(b, e - b + 1);
    if (key.size() >= 2 && (key.front() == '"' || key.front() == '\'') && key.back() == key.front())
        key = key.substr(1, key.size() - 2);
    return key;
}

}  // namespace

toml::table parse_toml_file(const std::string& path) {
    std::string text;
    try {
        text = read_text(path);
        check_nesting(text, path);
        return toml::parse(text, path);
    } catch (const toml::parse_error& e) {
        const auto& s = e.source().begin;
        const FileLoc at{path, static_cast<int>(s.line), static_cast<int>(s.column)};
        // toml++ garbles a quoted key's name in this message ('"spspp" ' for "spp"): the key is
        // taken from the line itself.
        const std::string why(e.description());
        if (why.find("cannot redefine existing") != std::string::npos) {
            std::string key = key_before(text, s.line, s.column);
            if (key.empty()) key = key_of_line(text, s.line);
            if (!key.empty()) throw_error(at, "invalid TOML: '{}' is set twice in its table", key);
        }
        throw_error(at, "invalid TOML: {}", why);
    }
}

}  // namespace spangle
