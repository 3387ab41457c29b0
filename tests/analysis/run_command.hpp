// Runs a shell command for the tests that drive the rayscan CLI and third-party programs (GRASS
// r.sun, GDAL's command-line tools) and collects its output.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace rayscan::test {

/// The standard output of `command` (run by /bin/sh; append "2>&1" for its errors too); `status`
/// receives its exit code, or -1 when it could not be started or did not exit normally.
inline std::string run_output(const std::string& command, int& status) {
  std::string out;
  FILE* p = popen(command.c_str(), "r");
  if (!p) {
    status = -1;
    return out;
  }
  std::array<char, 65536> buf{};
  std::size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  const int raw = pclose(p);
  status = (raw != -1 && WIFEXITED(raw)) ? WEXITSTATUS(raw) : -1;
  return out;
}

}  // namespace rayscan::test
