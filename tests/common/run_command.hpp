// Test helper shared by the CLI tests of every area: run a command line and capture its output.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>

namespace rayscan::test {

/// `p` in single quotes, for the shell. (Appended piecewise: `"'" + s + "'"` sets off GCC 12's
/// -Wrestrict false positive at -O3, an error under RAYSCAN_WERROR.)
inline std::string quoted(const std::filesystem::path& p) {
  std::string q = "'";
  q += p.string();
  q += '\'';
  return q;
}

/// Exit code (-1 when the process did not exit normally) and captured output of a command.
struct CommandResult {
  int code = -1;
  std::string out;
};

/// Runs `cmd` through /bin/sh and captures its standard output; standard error is captured too
/// when `merge_stderr`, otherwise discarded.
inline CommandResult run_command(const std::string& cmd, bool merge_stderr = true) {
  CommandResult r;
  FILE* p = ::popen((cmd + (merge_stderr ? " 2>&1" : " 2>/dev/null")).c_str(), "r");
  if (!p) return r;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int st = ::pclose(p);
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

}  // namespace rayscan::test
