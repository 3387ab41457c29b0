// Test helpers shared by every area: scratch folders per test process, and a folder's listing.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <set>
#include <string>
#include <string_view>

namespace rayscan::test {

/// The folder <system temp>/<name>_<pid>, created when missing (std::filesystem errors throw).
/// One per test process and name, so that tests running in parallel processes never share one.
inline std::filesystem::path process_temp_dir(std::string_view name) {
  const std::filesystem::path d =
      std::filesystem::temp_directory_path() / (std::string(name) + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

/// The empty folder <system temp>/<name>_<pid>: whatever a previous process of the same id left
/// there is removed first (std::filesystem errors throw).
inline std::filesystem::path fresh_temp_dir(std::string_view name) {
  const std::filesystem::path d =
      std::filesystem::temp_directory_path() / (std::string(name) + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

/// The names of the entries of folder `d` (not recursive), sorted.
inline std::set<std::string> entry_names(const std::filesystem::path& d) {
  std::set<std::string> s;
  for (const auto& e : std::filesystem::directory_iterator(d)) s.insert(e.path().filename().string());
  return s;
}

}  // namespace rayscan::test
