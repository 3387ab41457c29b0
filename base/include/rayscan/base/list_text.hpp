// Lists of words as a message's sentence writes them ("a, b or c"): the one join of the
// "expected ..." and "applies to ... only" lists that the libraries and the program print.
#pragma once

#include <cstddef>
#include <iterator>
#include <string>
#include <string_view>

namespace rayscan {

/// `words` (a container of std::string, std::string_view or const char*) in order as a sentence's
/// list: the last two joined by " <conjunction> " ("or", "and"), the others by ", " (no comma
/// before the conjunction): "" for none, "a" for one, "a or b", "a, b or c". Each word is written
/// as given (no quoting or escaping).
template <class Words>
[[nodiscard]] std::string join_words(const Words& words, std::string_view conjunction) {
  const std::size_t n = std::size(words);
  std::string s;
  std::size_t i = 0;
  for (const auto& w : words) {
    if (i > 0 && i + 1 < n) {
      s += ", ";
    } else if (i > 0) {
      s += ' ';
      s += conjunction;
      s += ' ';
    }
    s += w;
    ++i;
  }
  return s;
}

/// `words` as alternatives, join_words(words, "or"): "a, b or c", as a message lists the values
/// it accepts ("expected a, b or c").
template <class Words>
[[nodiscard]] std::string join_alternatives(const Words& words) {
  return join_words(words, "or");
}

}  // namespace rayscan
