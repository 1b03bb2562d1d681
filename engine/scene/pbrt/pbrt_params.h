#pragma once
// A pbrt directive's parameter list: "type name" value pairs as written, each remembering whether
// the reader used it, so that every parameter nobody read becomes one warning (what pbrt calls
// an unused parameter), and the warnings themselves, each said once.

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "scene/pbrt/pbrt_tokenizer.h"

namespace spangle::pbrt {

/** One "type name" [values] pair. */
struct Param {
    std::string type;                  ///< as written, with v3's synonyms: point = point3, ...
    std::string name;                  ///< the parameter's name
    std::vector<double> numbers;       ///< numeric values (and a spectrum's lambda-value pairs)
    std::vector<std::string> strings;  ///< string, texture and named-spectrum values
    std::vector<uint8_t> bools;        ///< bool values, 0 or 1
    FileLoc loc;                       ///< where "type name" is written
    mutable bool used = false;         ///< a reader looked it up
    /** A reader took its first value of several where one belongs (warned about). */
    mutable bool first_of_many = false;
};

/** The parameters of one directive, in the order written. */
class ParamList {
public:
    /** Reads "type name" value pairs from `tokens` for as long as the next token is a string.
     *  Throws SpangleError at the value for a malformed list (a missing ']', a word where a
     *  number belongs, a non-finite number). */
    void parse(Tokenizer& tokens);
    /** The parameter `name` of one of `types` (any when empty), marked used; null when absent. A
     *  parameter of that name but another type is left unused (and warned about). */
    const Param* find(std::string_view name,
                      std::initializer_list<std::string_view> types = {}) const;
    /** A number ("float" or "integer"), or `fallback`; a list takes its first value (and is
     *  warned about by Notes::unused). */
    double number(std::string_view name, double fallback) const;
    /** A string ("string"), or `fallback`. */
    std::string string(std::string_view name, const std::string& fallback) const;
    /** A bool ("bool"; v3's "true"/"false" strings too), or `fallback`. */
    bool boolean(std::string_view name, bool fallback) const;
    /** The numbers of a "type name" of one of `types`; empty when absent. */
    const std::vector<double>& numbers(std::string_view name,
                                       std::initializer_list<std::string_view> types) const;
    /** Adds the parameters of `defaults` (v4's Attribute) that this list does not name. */
    void add_defaults(const ParamList& defaults);
    /** Adds one parameter (a later one of the same name replaces it for lookups). */
    void add(Param p) { params_.push_back(std::move(p)); }
    /** Every parameter, in order. */
    const std::vector<Param>& all() const { return params_; }

private:
    std::vector<Param> params_;
};

/** The reader's warnings: each message said once, at the first place it arose, with a count of
 *  the places it arose again. */
class Notes {
public:
    /** Notes `message` at `at` ("file:line: message"). */
    void add(const FileLoc& at, const std::string& message);
    /** Warns about each parameter of `params` that no one read: "'type name' of `what` is not
     *  supported: dropped", and each of several values where one was read. */
    void unused(const ParamList& params, const std::string& what);
    /** The notes, in the order they first arose. */
    std::vector<std::string> take() const;

private:
    std::vector<std::pair<std::string, int>> notes_;  ///< "file:line: message", repeats
    std::map<std::string, std::size_t> index_;        ///< message -> its entry
};

}  // namespace spangle::pbrt
