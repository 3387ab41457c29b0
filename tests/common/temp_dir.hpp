// Test helper shared by every area: a scratch folder per test process.
#pragma once

#include <unistd.h>

#include <filesystem>
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

}  // namespace rayscan::test
