#include "core/text.h"

#include <cctype>

#include <fmt/format.h>

#include <algorithm>

namespace spangle {

std::size_t edit_distance(std::string_view a, std::string_view b) {
    std::vector<std::size_t> row(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
        std::size_t diag = row[0];
        row[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const std::size_t up = row[j];
            row[j] =
                std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0u : 1u)});
            diag = up;
        }
    }
    return row[b.size()];
}

namespace {

/** The closest of `candidates` to `word`, when it is within 2 edits; empty otherwise. */
std::string nearest(std::string_view word, const std::vector<std::string>& candidates) {
    std::string best;
    std::size_t best_d = 3;
    for (const auto& c : candidates) {
        const std::size_t d = edit_distance(word, c);
        if (d < best_d) {
            best_d = d;
            best = c;
        }
    }
    return best;
}

}  // namespace

std::string did_you_mean(std::string_view word, const std::vector<std::string>& candidates) {
    std::string guess = nearest(word, candidates);
    for (const auto& c : candidates)
        if (guess.empty() && word.size() >= 3 && c.size() >= 3 &&
            (c.rfind(word, 0) == 0 || word.rfind(c, 0) == 0))
            guess = c;
    return guess.empty() ? std::string() : fmt::format("; did you mean '{}'?", guess);
}

std::string ascii_lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

}  // namespace spangle
