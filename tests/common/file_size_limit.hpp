// A failed write made deterministic: a file-size limit (RLIMIT_FSIZE with SIGXFSZ ignored), past
// which a write fails with EFBIG as it fails with ENOSPC on a full disk, on the same paths.
#pragma once

#include <sys/resource.h>

#include <csignal>
#include <exception>
#include <functional>
#include <string>

namespace rayscan::test {

/// What `write` throws (its what()) while a file may grow to at most `bytes`, or "" when it throws
/// nothing; the limit and SIGXFSZ's action are restored after. A message saying why instead when
/// the limit cannot be set ("getrlimit failed", "hard file size limit too low", "setrlimit failed").
inline std::string error_within_file_size(rlim_t bytes, const std::function<void()>& write) {
  struct rlimit before {};
  if (::getrlimit(RLIMIT_FSIZE, &before) != 0) return "getrlimit failed";
  if (before.rlim_max != RLIM_INFINITY && before.rlim_max < bytes) return "hard file size limit too low";
  struct rlimit r = before;
  r.rlim_cur = bytes;
  void (*old_handler)(int) = std::signal(SIGXFSZ, SIG_IGN);
  if (::setrlimit(RLIMIT_FSIZE, &r) != 0) {
    std::signal(SIGXFSZ, old_handler);
    return "setrlimit failed";
  }
  std::string error;
  try {
    write();
  } catch (const std::exception& e) {
    error = e.what();
  }
  ::setrlimit(RLIMIT_FSIZE, &before);
  std::signal(SIGXFSZ, old_handler);
  return error;
}

}  // namespace rayscan::test
