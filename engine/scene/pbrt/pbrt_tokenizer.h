#pragma once
// pbrt's scene syntax as tokens: quoted strings, [ and ], and bare words (directives, numbers,
// v4's bare true/false), with '#' comments to the end of the line. A file is read whole (gzip'd
// files are inflated through zlib); tokens point into it, so a mesh of millions of numbers is
// read without a string per number.

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "core/error.h"

namespace spangle::pbrt {

/** One token of a pbrt file. */
struct Token {
    /** What the token is. */
    enum class Kind { End, Word, String, Open, Close };
    Kind kind = Kind::End;  ///< End: the file has no more tokens
    std::string_view text;  ///< a word as written; a string without its quotes, unescaped
    int line = 0;           ///< 1-based line of its first character
    int column = 0;         ///< 1-based column of its first character
};

/** The tokens of one file, in order. */
class Tokenizer {
public:
    /** Reads `path` (inflating it when it starts with gzip's magic bytes). Throws SpangleError
     *  at `ref` when it cannot be read or is larger than memory allows. */
    Tokenizer(const std::string& path, const FileLoc& ref);
    /** Tokens of text held in memory (tests, the fuzz target); `name` is used in messages. */
    Tokenizer(std::string name, std::string text);

    /** The next token (Kind::End at the end, again and again). Throws SpangleError at its place
     *  for an unterminated string or a control character. */
    Token next();
    /** The token next() would return, without taking it. */
    const Token& peek();
    /** Bytes from the read position to the next ']' (or the end): a bound on the values of a
     *  list, for reserving (each value takes at least two bytes). */
    std::size_t bytes_to_close() const;
    /** The file's path as messages show it. */
    const std::string& path() const { return path_; }
    /** A token's place in this file. */
    FileLoc loc(const Token& t) const { return {path_, t.line, t.column}; }

private:
    Token scan();
    Token scan_string(int line, int column);

    std::string path_;
    std::string text_;
    std::size_t at_ = 0;
    int line_ = 1;
    std::size_t line_start_ = 0;
    bool peeked_ = false;
    Token peek_;
    std::string unescaped_;  ///< the last string with escapes, unescaped (one at a time)
};

}  // namespace spangle::pbrt
