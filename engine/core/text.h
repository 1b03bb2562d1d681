#pragma once
// Small text helpers for messages: how far apart two words are, and the "did you mean" hint that
// every unknown-name error offers (scene keys, plugins, models, parameters, commands).

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace spangle {

/** `s` with its ASCII letters in lower case (file extensions, URI schemes, media types). */
std::string ascii_lower(std::string_view s);

/** Levenshtein distance, for "did you mean" suggestions. */
std::size_t edit_distance(std::string_view a, std::string_view b);

/** "; did you mean 'NAME'?" for the candidate within 2 edits of `word` (or the one `word`
 *  starts or is the start of), or "" when none is close. */
std::string did_you_mean(std::string_view word, const std::vector<std::string>& candidates);

}  // namespace spangle
