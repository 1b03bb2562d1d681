#include "scene/pbrt/pbrt_tokenizer.h"

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/files.h"
#include "core/memory.h"

namespace spangle::pbrt {

namespace {

/** The bytes of `path`, inflated when they are gzip'd. */
std::string read_whole(const std::string& path, const FileLoc& ref) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw_error(ref, "pbrt file '{}' not found (or not a regular file; looked for {})", path,
                    absolute_path(path));
    std::ifstream in(path, std::ios::binary);
    if (!in) throw_error(ref, "cannot open '{}': {}", path, unreadable(path));
    unsigned char magic[2] = {0, 0};
    in.read(reinterpret_cast<char*>(magic), 2);
    if (in.gcount() == 2 && magic[0] == 0x1f && magic[1] == 0x8b)
        return inflate_gzip_file(path, ref);
    const auto size = std::filesystem::file_size(path, ec);
    if (ec) throw_error(ref, "cannot read '{}': {}", path, ec.message());
    if (memory_short_for(static_cast<double>(size)))
        throw_error(ref, "'{}' ({}) does not fit the memory available", path,
                    format_bytes(static_cast<double>(size)));
    std::string out(size, '\0');
    in.seekg(0);
    in.read(out.data(), static_cast<std::streamsize>(size));
    out.resize(static_cast<std::size_t>(in.gcount()));
    return out;
}

bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}

/** The text without a UTF-8 byte order mark, a lone carriage return (old Mac line ends) made a
 *  line feed, so that lines count and the first directive reads. */
std::string plain(std::string text) {
    if (text.starts_with("\xEF\xBB\xBF")) text.erase(0, 3);
    for (std::size_t i = 0; i < text.size(); ++i)
        if (text[i] == '\r' && (i + 1 == text.size() || text[i + 1] != '\n')) text[i] = '\n';
    return text;
}

}  // namespace

Tokenizer::Tokenizer(const std::string& path, const FileLoc& ref)
    : path_(path), text_(plain(read_whole(path, ref))) {}

Tokenizer::Tokenizer(std::string name, std::string text)
    : path_(std::move(name)), text_(plain(std::move(text))) {}

const Token& Tokenizer::peek() {
    if (!peeked_) {
        peek_ = scan();
        peeked_ = true;
    }
    return peek_;
}

Token Tokenizer::next() {
    if (peeked_) {
        peeked_ = false;
        return peek_;
    }
    return scan();
}

std::size_t Tokenizer::bytes_to_close() const {
    const std::size_t close = text_.find(']', at_);
    return (close == std::string::npos ? text_.size() : close) - at_;
}

Token Tokenizer::scan() {
    const std::size_t n = text_.size();
    while (at_ < n) {
        const char c = text_[at_];
        if (c == '\n') {
            ++line_;
            line_start_ = ++at_;
        } else if (is_space(c)) {
            ++at_;
        } else if (c == '#') {
            while (at_ < n && text_[at_] != '\n') ++at_;
        } else {
            break;
        }
    }
    Token t;
    t.line = line_;
    t.column = static_cast<int>(at_ - line_start_) + 1;
    if (at_ >= n) return t;
    const char c = text_[at_];
    if (c == '[' || c == ']') {
        t.kind = c == '[' ? Token::Kind::Open : Token::Kind::Close;
        t.text = std::string_view(text_).substr(at_++, 1);
        return t;
    }
    if (c == '"') return scan_string(t.line, t.column);
    const std::size_t start = at_;
    while (at_ < n && !is_space(text_[at_]) && text_[at_] != '"' && text_[at_] != '[' &&
           text_[at_] != ']' && text_[at_] != '#')
        ++at_;
    t.kind = Token::Kind::Word;
    t.text = std::string_view(text_).substr(start, at_ - start);
    return t;
}

Token Tokenizer::scan_string(int line, int column) {
    const std::size_t n = text_.size();
    const std::size_t start = ++at_;
    bool escaped = false;
    while (at_ < n && text_[at_] != '"') {
        if (text_[at_] == '\n')
            throw_error(FileLoc{path_, line, column}, "a string must end on the line it starts");
        if (text_[at_] == '\\') {
            escaped = true;
            ++at_;
        }
        ++at_;
    }
    if (at_ >= n) throw_error(FileLoc{path_, line, column}, "unterminated string");
    Token t;
    t.kind = Token::Kind::String;
    t.line = line;
    t.column = column;
    t.text = std::string_view(text_).substr(start, at_ - start);
    ++at_;
    if (!escaped) return t;
    unescaped_.clear();
    for (std::size_t i = 0; i < t.text.size(); ++i) {
        char c = t.text[i];
        if (c == '\\' && i + 1 < t.text.size()) {
            switch (t.text[++i]) {
                case 'n':
                    c = '\n';
                    break;
                case 't':
                    c = '\t';
                    break;
                case 'b':
                    c = '\b';
                    break;
                case 'f':
                    c = '\f';
                    break;
                case 'r':
                    c = '\r';
                    break;
                default:
                    c = t.text[i];  // \\, \", \' and any other: the character itself
            }
        }
        unescaped_.push_back(c);
    }
    t.text = unescaped_;
    return t;
}

}  // namespace spangle::pbrt
