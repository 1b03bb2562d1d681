#include "scene/pbrt/pbrt_params.h"

#include <charconv>
#include <cmath>

namespace spangle::pbrt {

namespace {

/** Which values a parameter type takes. */
enum class ValueKind { Numbers, Strings, Bools, Spectrum };

/** The canonical type of a spelling (v3's synonyms), or "" when it is no pbrt type. */
std::string_view canonical_type(std::string_view t) {
    if (t == "point") return "point3";
    if (t == "vector") return "vector3";
    if (t == "normal") return "normal3";
    if (t == "color") return "rgb";
    static constexpr std::string_view kTypes[] = {
        "integer", "float", "point2",   "vector2",   "point3", "vector3", "normal3",
        "rgb",     "xyz",   "spectrum", "blackbody", "string", "texture", "bool"};
    for (std::string_view k : kTypes)
        if (t == k) return k;
    return {};
}

ValueKind kind_of(std::string_view type) {
    if (type == "string" || type == "texture") return ValueKind::Strings;
    if (type == "bool") return ValueKind::Bools;
    if (type == "spectrum") return ValueKind::Spectrum;
    return ValueKind::Numbers;
}

/** A number as pbrt writes one ("+1", "1.", ".5", "1e-3"); false for anything else. Plain
 *  integers (mesh indices, most of a large file) take a short path. */
bool parse_number(std::string_view s, double& out) {
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    if (!s.empty() && s.size() <= 15) {
        std::size_t i = s.front() == '-' ? 1 : 0;
        int64_t v = 0;
        bool digits = i < s.size();
        for (std::size_t k = i; k < s.size() && digits; ++k) {
            const char c = s[k];
            digits = c >= '0' && c <= '9';
            v = v * 10 + (c - '0');
        }
        if (digits) {
            out = static_cast<double>(i ? -v : v);
            return true;
        }
    }
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return ec == std::errc() && end == s.data() + s.size();
}

/** One value token into `p`. */
void take_value(Tokenizer& tokens, const Token& t, ValueKind kind, Param& p) {
    const std::string_view v = t.text;
    const bool quoted = t.kind == Token::Kind::String;
    if (kind == ValueKind::Bools) {
        if (v == "true" || v == "false") {
            p.bools.push_back(v == "true" ? 1 : 0);
            return;
        }
        throw_error(tokens.loc(t), "'{} {}' takes true or false, got '{}'", p.type, p.name, v);
    }
    if (kind == ValueKind::Strings || (kind == ValueKind::Spectrum && quoted)) {
        if (!quoted)
            throw_error(tokens.loc(t), "'{} {}' takes quoted strings, got '{}'", p.type, p.name, v);
        p.strings.emplace_back(v);
        return;
    }
    double x = 0.0;
    if (quoted || !parse_number(v, x)) {
        // A number beyond a double's range: too small (1e-400) is 0, as pbrt reads it; too
        // large (1e400) is said so, not "not a number".
        const std::string_view w = !v.empty() && v.front() == '+' ? v.substr(1) : v;
        double y = 0.0;
        const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), y);
        if (!quoted && ec == std::errc::result_out_of_range && end == w.data() + w.size()) {
            const std::size_t e = w.find_first_of("eE");
            if (e != std::string_view::npos && e + 1 < w.size() && w[e + 1] == '-') {
                p.numbers.push_back(0.0);
                return;
            }
            throw_error(tokens.loc(t), "'{} {}': {} is out of range (beyond about 1e308)", p.type,
                        p.name, v);
        }
        throw_error(tokens.loc(t), "'{} {}' takes numbers, got '{}'", p.type, p.name, v);
    }
    if (!std::isfinite(x))
        throw_error(tokens.loc(t), "'{} {}': {} is not a finite number", p.type, p.name, v);
    p.numbers.push_back(x);
}

}  // namespace

void ParamList::parse(Tokenizer& tokens) {
    while (tokens.peek().kind == Token::Kind::String) {
        const Token decl = tokens.next();
        Param p;
        p.loc = tokens.loc(decl);
        const std::string_view d = decl.text;
        const std::size_t a = d.find_first_not_of(" \t");
        const std::size_t b = a == std::string_view::npos ? a : d.find_first_of(" \t", a);
        const std::size_t c = b == std::string_view::npos ? b : d.find_first_not_of(" \t", b);
        const std::size_t e = c == std::string_view::npos ? c : d.find_first_of(" \t", c);
        if (c == std::string_view::npos ||
            (e != std::string_view::npos &&
             d.find_first_not_of(" \t", e) != std::string_view::npos))
            throw_error(p.loc, "expected a parameter \"type name\", got \"{}\"", d);
        const std::string_view type = canonical_type(d.substr(a, b - a));
        if (type.empty())
            throw_error(p.loc,
                        "unknown parameter type '{}' in \"{}\" (valid: integer, float, point2, "
                        "vector2, point3, vector3, normal3, rgb, spectrum, blackbody, string, "
                        "texture, bool)",
                        d.substr(a, b - a), d);
        p.type = type;
        p.name = d.substr(c, e == std::string_view::npos ? e : e - c);
        const ValueKind kind = kind_of(type);
        const Token first = tokens.next();
        if (first.kind == Token::Kind::Open) {
            // Reserved, not touched: the pages a list does not fill cost nothing.
            if (kind == ValueKind::Numbers) p.numbers.reserve(tokens.bytes_to_close() / 2 + 1);
            for (;;) {
                const Token t = tokens.next();
                if (t.kind == Token::Kind::Close) break;
                if (t.kind == Token::Kind::End)
                    throw_error(tokens.loc(first), "'[' of '{} {}' is never closed", p.type,
                                p.name);
                if (t.kind == Token::Kind::Open)
                    throw_error(tokens.loc(t), "'{} {}': a list cannot hold a list", p.type,
                                p.name);
                // A directive's name inside a list: the list's ']' is missing.
                if (t.kind == Token::Kind::Word && !t.text.empty() && t.text[0] >= 'A' &&
                    t.text[0] <= 'Z')
                    throw_error(tokens.loc(first),
                                "'[' of '{} {}' is never closed (before {} at "
                                "line {})",
                                p.type, p.name, t.text, t.line);
                take_value(tokens, t, kind, p);
            }
        } else if (first.kind == Token::Kind::Word || first.kind == Token::Kind::String) {
            take_value(tokens, first, kind, p);
        } else {
            throw_error(tokens.loc(first), "'{} {}' has no value", p.type, p.name);
        }
        params_.push_back(std::move(p));
    }
}

const Param* ParamList::find(std::string_view name,
                             std::initializer_list<std::string_view> types) const {
    for (auto it = params_.rbegin(); it != params_.rend(); ++it) {
        if (it->name != name) continue;
        bool ok = types.size() == 0;
        for (std::string_view t : types) ok = ok || it->type == t;
        if (!ok) continue;
        it->used = true;
        return &*it;
    }
    return nullptr;
}

double ParamList::number(std::string_view name, double fallback) const {
    const Param* p = find(name, {"float", "integer"});
    if (p && p->numbers.size() > 1) p->first_of_many = true;
    return p && !p->numbers.empty() ? p->numbers.front() : fallback;
}

std::string ParamList::string(std::string_view name, const std::string& fallback) const {
    const Param* p = find(name, {"string"});
    return p && !p->strings.empty() ? p->strings.front() : fallback;
}

bool ParamList::boolean(std::string_view name, bool fallback) const {
    if (const Param* p = find(name, {"bool"}); p && !p->bools.empty()) return p->bools.front();
    // pbrt-v3 wrote bools as strings: "bool twosided" "true" reads as a bool above; "string"
    // spellings of a bool are not bools in pbrt either.
    return fallback;
}

const std::vector<double>& ParamList::numbers(std::string_view name,
                                              std::initializer_list<std::string_view> types) const {
    static const std::vector<double> kNone;
    const Param* p = find(name, types);
    return p ? p->numbers : kNone;
}

void ParamList::add_defaults(const ParamList& defaults) {
    for (const Param& d : defaults.params_) {
        bool named = false;
        for (const Param& p : params_) named = named || p.name == d.name;
        if (named) continue;
        // pbrt ignores an Attribute's parameters a directive does not take: no warning for them
        // (Attribute "shape" "float radius" warned at every trianglemesh).
        params_.push_back(d);
        params_.back().used = true;
    }
}

void Notes::add(const FileLoc& at, const std::string& message) {
    auto [it, added] = index_.emplace(message, notes_.size());
    if (added) {
        const std::string where = at.line > 0 ? fmt::format("{}:{}", at.file, at.line) : at.file;
        notes_.emplace_back(fmt::format("{}: {}", where, message), 0);
    } else {
        ++notes_[it->second].second;
    }
}

void Notes::unused(const ParamList& params, const std::string& what) {
    for (const Param& p : params.all()) {
        if (p.first_of_many)
            add(p.loc, fmt::format("'{} {}' of {} takes one value, got {}: the first stands",
                                   p.type, p.name, what, p.numbers.size()));
        if (p.used) continue;
        // Given twice: the later one was taken (it was said to be "not supported").
        bool again = false;
        for (const Param& q : params.all())
            again = again || (&q != &p && q.used && q.name == p.name);
        if (again)
            add(p.loc, fmt::format("'{} {}' of {} is given more than once: the last one stands",
                                   p.type, p.name, what));
        else
            add(p.loc,
                fmt::format("'{} {}' of {} is not supported: dropped", p.type, p.name, what));
    }
}

std::vector<std::string> Notes::take() const {
    std::vector<std::string> out;
    for (const auto& [text, more] : notes_)
        out.push_back(
            more == 0 ? text
                      : fmt::format("{} (and {} more time{})", text, more, more == 1 ? "" : "s"));
    return out;
}

}  // namespace spangle::pbrt
