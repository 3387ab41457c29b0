// A failed write made deterministic: a file-size limit (RLIMIT_FSIZE with SIGXFSZ ignored), past
// which a write fails with EFBIG as it fails with ENOSPC on a full disk, on the same paths.
#pragma once

#include <sys/resource.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <set>
#include <string>

#include "temp_dir.hpp"

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

/// What is wrong with a failed write's outcome, "" when nothing: `error` must be one line that
/// starts with "<out>: <head>" and ends with ": <EFBIG's text>" (the limit's errno, the oracle),
/// naming no temporary (".tmp."); `out` must still hold "OLD" and be the only entry of its folder.
inline std::string failure_names_only_output(const std::string& error, const std::filesystem::path& out,
                                             const std::string& head) {
  const std::string start = out.string() + ": " + head;
  if (error.rfind(start, 0) != 0) return "does not start with '" + start + "': " + error;
  const std::string cause = std::string(": ") + std::strerror(EFBIG);
  if (error.size() <= cause.size() || error.compare(error.size() - cause.size(), cause.size(), cause) != 0)
    return "does not end with '" + cause + "': " + error;
  if (error.find(".tmp.") != std::string::npos) return "names a temporary: " + error;
  if (error.find('\n') != std::string::npos) return "is not one line: " + error;
  std::ifstream f(out);
  if (std::string(std::istreambuf_iterator<char>(f), {}) != "OLD") return out.string() + " lost its old content";
  if (entry_names(out.parent_path()) != std::set<std::string>{out.filename().string()})
    return out.parent_path().string() + " holds more than " + out.filename().string();
  return "";
}

}  // namespace rayscan::test
