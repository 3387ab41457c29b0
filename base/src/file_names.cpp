#include "rayscan/base/file_names.hpp"

#include "rayscan/base/ascii_case.hpp"
#include "rayscan/base/list_text.hpp"

#include <algorithm>

namespace rayscan {

std::string lower_extension(const std::filesystem::path& path) {
  return ascii_lower(path.extension().string());
}

bool has_extension(const std::filesystem::path& path, const std::vector<std::string>& extensions) {
  const std::string e = lower_extension(path);
  return !e.empty() && std::find(extensions.begin(), extensions.end(), e) != extensions.end();
}

std::string extensions_expected(const std::vector<std::string>& extensions) {
  return "expected a file name ending in " + join_alternatives(extensions);
}

}  // namespace rayscan
