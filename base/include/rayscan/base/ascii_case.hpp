// ASCII case folding: the one lower-casing of names that are ASCII by definition (file
// extensions, point field names, format keywords, SQL identifiers). Header only: a loop the
// compiler inlines at each use.
#pragma once

#include <string>
#include <string_view>

namespace rayscan {

/// `s` with ASCII A-Z lowered and every other byte kept (UTF-8 sequences untouched);
/// locale-independent, unlike std::tolower.
[[nodiscard]] inline std::string ascii_lower(std::string_view s) {
  std::string out(s);
  for (char& c : out)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return out;
}

}  // namespace rayscan
