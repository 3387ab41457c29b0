// Text output of the tools: a file written through rayscan::AtomicFile (temporary + rename), or
// standard output.
#pragma once

#include "rayscan/base/atomic_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>

namespace rayscan::cli {

/// "<what>: write failed", with the system's reason when errno holds one (a full disk: "No space
/// left on device"; callers clear errno before the call whose failure they report).
[[nodiscard]] inline std::string write_failed(const std::string& what) {
  const int e = errno;
  return what + ": write failed" + (e != 0 ? std::string(" (") + std::strerror(e) + ")" : std::string());
}

/// Flushes standard output (std::cout and the C stream under it) and throws std::runtime_error
/// ("standard output: write failed") when any write to it failed: a full disk, /dev/full, a file
/// size limit. The reason is named when this last flush is the call that failed; an earlier
/// failed write left only the stream's error flag. Called once after every command, so that no
/// command exits 0 with its output lost.
inline void check_standard_output() {
  errno = 0;
  std::cout.flush();
  const bool flushed = std::fflush(stdout) == 0;
  if (!std::cout || !flushed || std::ferror(stdout)) throw std::runtime_error(write_failed("standard output"));
}

/// A text output stream bound to `path` ("" or "-" = standard output). commit() moves the finished
/// file into place; destruction without commit() leaves no file behind. Throws std::runtime_error
/// when the file cannot be created or written.
class AtomicOutput {
 public:
  explicit AtomicOutput(const std::string& path) {
    if (path.empty() || path == "-") return;
    file_ = std::make_unique<AtomicFile>(path);
    out_.open(file_->temp(), std::ios::binary | std::ios::trunc);
    if (!out_) throw std::runtime_error(path + ": cannot create output file");
  }
  /// The stream to write to.
  std::ostream& stream() { return file_ ? out_ : std::cout; }
  /// Flush and move the finished file into place (standard output: flushed; main() checks it
  /// once after every command, check_standard_output).
  void commit() {
    if (!file_) {
      std::cout.flush();
      return;
    }
    errno = 0;
    out_.flush();
    if (!out_) throw std::runtime_error(write_failed(file_->path().string()));
    out_.close();  // the last buffer's write error shows here
    if (!out_) throw std::runtime_error(write_failed(file_->path().string()));
    file_->commit();
  }

 private:
  std::unique_ptr<AtomicFile> file_;
  std::ofstream out_;
};

}  // namespace rayscan::cli
