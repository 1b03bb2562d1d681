#include "scene/gltf/json_locations.h"

#include <cctype>

namespace spangle::gltf {
namespace {

constexpr int kMaxDepth = 256;  ///< deeper nesting is refused (no glTF needs more than ~10)

/** A recursive-descent scanner of RFC 8259 JSON that records the places of values. */
class Scanner {
public:
    Scanner(std::string_view text, const std::string& file,
            std::unordered_map<std::string, JsonLocations::Place>& places,
            std::vector<std::string>& required,
            std::unordered_map<std::string, std::string>& scalars,
            std::unordered_map<std::string, std::pair<std::size_t, std::size_t>>& spans)
        : text_(text),
          file_(file),
          places_(places),
          required_(required),
          scalars_(scalars),
          spans_(spans) {}

    void document() {
        skip_space();
        record();
        value(0);
        skip_space();
        if (pos_ < text_.size()) fail("unexpected text after the JSON document");
    }

private:
    [[noreturn]] void fail(const std::string& what) const {
        throw_error(FileLoc{file_, line_, column_}, "invalid JSON: {}", what);
    }

    char peek() const { return pos_ < text_.size() ? text_[pos_] : '\0'; }
    bool at_end() const { return pos_ >= text_.size(); }

    void advance() {
        if (text_[pos_] == '\n') {
            ++line_;
            column_ = 1;
        } else {
            ++column_;
        }
        ++pos_;
    }

    void skip_space() {
        while (!at_end() && (peek() == ' ' || peek() == '\t' || peek() == '\n' || peek() == '\r'))
            advance();
    }

    void expect(char c, const char* what) {
        if (at_end() || peek() != c) fail(fmt::format("expected {}", what));
        advance();
    }

    void record() {
        const char c = peek();
        const char kind = c == '{'               ? 'o'
                          : c == '['             ? 'a'
                          : c == '"'             ? 's'
                          : c == 't' || c == 'f' ? 'b'
                          : c == 'n'             ? 'z'
                                                 : 'n';
        places_.emplace(path_, JsonLocations::Place{line_, column_, kind});
    }

    /** A value at path_, `depth` levels down. */
    void value(int depth) {
        if (depth > kMaxDepth) fail(fmt::format("nested deeper than {} levels", kMaxDepth));
        if (at_end()) fail("unexpected end of the text, expected a value");
        const char c = peek();
        if (c == '{') return object(depth);
        if (c == '[') return array(depth);
        if (c == '"') {
            // The required extensions' names are kept: a file that needs one Spangle does not
            // read is refused by that, before tinygltf trips over what it compresses.
            if (path_ == "extensionsRequired") {
                std::string name;
                string(&name, true);
                required_.push_back(std::move(name));
                return;
            }
            // The buffers' members (their uri), checked before tinygltf reads the data.
            if (kept_scalar()) {
                std::string text;
                string(&text);
                scalars_[path_] = '"' + text + '"';
                return;
            }
            return string(nullptr);
        }
        if (c == '-' || (c >= '0' && c <= '9')) {
            const std::size_t start = pos_;
            number();
            if (kept_scalar()) scalars_[path_] = std::string(text_.substr(start, pos_ - start));
            return;
        }
        for (const char* word : {"true", "false", "null"}) {
            const std::string_view w(word);
            if (text_.substr(pos_, w.size()) == w) {
                for (std::size_t i = 0; i < w.size(); ++i) advance();
                if (w != "null" && kept_scalar()) scalars_[path_] = std::string(w);
                return;
            }
        }
        fail(fmt::format("unexpected character '{}', expected a value", c));
    }

    void object(int depth) {
        advance();
        skip_space();
        if (peek() == '}') return advance();
        for (;;) {
            skip_space();
            if (peek() != '"') fail("expected a member name in double quotes");
            std::string key;
            string(&key, true);
            skip_space();
            expect(':', "':' after a member name");
            skip_space();
            const std::size_t size = path_.size();
            if (!path_.empty()) path_ += '/';
            path_ += key;
            record();
            // An animation channel's target (one without a node is rewritten for tinygltf).
            const bool target = key == "target" && peek() == '{' && depth == 4 &&
                                path_.rfind("animations/", 0) == 0 &&
                                path_.find("/channels/") != std::string::npos;
            const std::size_t start = pos_;
            value(depth + 1);
            if (target) spans_[path_] = {start, pos_};
            path_.resize(size);
            skip_space();
            if (peek() == ',') {
                advance();
                continue;
            }
            expect('}', "',' or '}' in an object");
            return;
        }
    }

    void array(int depth) {
        advance();
        skip_space();
        if (peek() == ']') return advance();
        for (std::size_t i = 0;; ++i) {
            skip_space();
            const std::size_t size = path_.size();
            // The buffers' and accessors' objects: where each is written, byte for byte (a buffer
            // that only stands in for compressed data, and an accessor without a view, are
            // rewritten in the text tinygltf reads).
            const bool buffer =
                (path_ == "buffers" || path_ == "accessors" || path_ == "skins") && peek() == '{';
            const std::size_t start = pos_;
            if (peek() == '{' || peek() == '[') {
                if (!path_.empty()) path_ += '/';
                path_ += std::to_string(i);
                record();
            }
            value(depth + 1);
            if (buffer) spans_[path_] = {start, pos_};
            path_.resize(size);
            skip_space();
            if (peek() == ',') {
                advance();
                continue;
            }
            expect(']', "',' or ']' in an array");
            return;
        }
    }

    /** A string into out: its text as written (escapes kept), or with `decode` as the JSON
     *  parser reads it (member names and extension names: "buffer\\u0056iew" is the member
     *  bufferView to tinygltf, and kept as written it hid an image's view from the checks). */
    void string(std::string* out, bool decode = false) {
        advance();
        uint32_t high = 0;  // a UTF-16 high surrogate waiting for its low half
        for (;;) {
            if (at_end()) fail("unterminated string");
            const char c = peek();
            if (c == '"') return advance();
            if (static_cast<unsigned char>(c) < 0x20) fail("control character in a string");
            if (c != '\\') {
                if (out) *out += c;
                advance();
                continue;
            }
            if (out && !decode) *out += c;
            advance();
            if (at_end()) fail("unterminated string");
            const char e = peek();
            if (e == 'u') {
                uint32_t unit = 0;
                for (int k = 0; k < 4; ++k) {
                    if (out && !decode) *out += peek();
                    advance();
                    if (at_end() || !std::isxdigit(static_cast<unsigned char>(peek())))
                        fail("'\\u' must be followed by four hexadecimal digits");
                    const char h = peek();
                    unit = unit * 16 +
                           static_cast<uint32_t>(std::isdigit(static_cast<unsigned char>(h))
                                                     ? h - '0'
                                                     : std::tolower(h) - 'a' + 10);
                }
                if (out && !decode) *out += peek();
                advance();
                if (out && decode) {
                    if (unit >= 0xd800 && unit < 0xdc00) {
                        high = unit;
                        continue;
                    }
                    uint32_t cp = unit;
                    if (unit >= 0xdc00 && unit < 0xe000 && high != 0)
                        cp = 0x10000 + ((high - 0xd800) << 10) + (unit - 0xdc00);
                    high = 0;
                    append_utf8(*out, cp);
                }
                continue;
            }
            const std::string_view escapes("\"\\/bfnrt"), meant("\"\\/\b\f\n\r\t");
            const std::size_t k = escapes.find(e);
            if (k == std::string_view::npos)
                fail(fmt::format("unknown escape '\\{}' in a string", e));
            if (out) *out += decode ? meant[k] : e;
            advance();
        }
    }

    /** Code point cp as UTF-8. */
    static void append_utf8(std::string& out, uint32_t cp) {
        if (cp < 0x80) {
            out += static_cast<char>(cp);
        } else if (cp < 0x800) {
            out += static_cast<char>(0xc0 | (cp >> 6));
            out += static_cast<char>(0x80 | (cp & 0x3f));
        } else if (cp < 0x10000) {
            out += static_cast<char>(0xe0 | (cp >> 12));
            out += static_cast<char>(0x80 | ((cp >> 6) & 0x3f));
            out += static_cast<char>(0x80 | (cp & 0x3f));
        } else {
            out += static_cast<char>(0xf0 | (cp >> 18));
            out += static_cast<char>(0x80 | ((cp >> 12) & 0x3f));
            out += static_cast<char>(0x80 | ((cp >> 6) & 0x3f));
            out += static_cast<char>(0x80 | (cp & 0x3f));
        }
    }

    void digits() {
        if (!std::isdigit(static_cast<unsigned char>(peek()))) fail("expected a digit");
        while (std::isdigit(static_cast<unsigned char>(peek()))) advance();
    }

    void number() {
        if (peek() == '-') advance();
        if (peek() == '0')
            advance();
        else
            digits();
        if (peek() == '.') {
            advance();
            digits();
        }
        if (peek() == 'e' || peek() == 'E') {
            advance();
            if (peek() == '+' || peek() == '-') advance();
            digits();
        }
    }

    std::string_view text_;
    const std::string& file_;
    std::unordered_map<std::string, JsonLocations::Place>& places_;
    std::vector<std::string>& required_;
    std::unordered_map<std::string, std::string>& scalars_;
    std::unordered_map<std::string, std::pair<std::size_t, std::size_t>>& spans_;

    /** Whether the scalar at path_ is kept (scalars_): a buffer's members, an accessor's count,
     *  componentType, type and bufferView, a buffer view's buffer, byteOffset and byteLength, an
     *  image's bufferView, and a material's texture indices, checked before tinygltf reads
     *  them. */
    bool kept_scalar() const {
        if (path_.starts_with("buffers/")) return true;
        // A material's texture references (tinygltf reads -1 as none written).
        if (path_.starts_with("materials/") && path_.ends_with("/index")) return true;
        // The member of element N of a top-level array ("accessors/N/key").
        const auto key_of = [&](std::string_view array) -> std::string_view {
            if (!path_.starts_with(array) || path_.size() <= array.size() ||
                path_[array.size()] != '/')
                return {};
            const std::size_t slash = path_.find('/', array.size() + 1);
            if (slash == std::string::npos) return {};
            return std::string_view(path_).substr(slash + 1);
        };
        if (const std::string_view key = key_of("accessors"); !key.empty())
            return key == "count" || key == "componentType" || key == "type" || key == "bufferView";
        if (const std::string_view key = key_of("bufferViews"); !key.empty())
            return key == "buffer" || key == "byteOffset" || key == "byteLength";
        return key_of("images") == "bufferView";
    }
    std::size_t pos_ = 0;
    int line_ = 1;
    int column_ = 1;
    std::string path_;
};

}  // namespace

JsonLocations::JsonLocations(std::string_view text, std::string file) : file_(std::move(file)) {
    Scanner(text, file_, places_, required_, scalars_, spans_).document();
}

FileLoc JsonLocations::at(std::string_view path) const {
    std::string p(path);
    for (;;) {
        if (auto it = places_.find(p); it != places_.end())
            return FileLoc{file_, it->second.line, it->second.column};
        const std::size_t slash = p.rfind('/');
        if (p.empty()) return FileLoc{file_, 1, 1};
        p.resize(slash == std::string::npos ? 0 : slash);
    }
}

}  // namespace spangle::gltf
