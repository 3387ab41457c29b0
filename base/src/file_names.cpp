#include "rayscan/base/file_names.hpp"

#include "rayscan/base/ascii_case.hpp"

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
  std::string s = "expected a file name ending in ";
  for (std::size_t i = 0; i < extensions.size(); ++i)
    s += (i == 0 ? "" : i + 1 == extensions.size() ? " or " : ", ") + extensions[i];
  return s;
}

}  // namespace rayscan
