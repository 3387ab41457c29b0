// Output files are written to a temporary sibling and renamed into place on success, so a failed
// or interrupted run never leaves a half-written file.
#pragma once

#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <unistd.h>

namespace rayscan::cli {

/// A text output stream bound to `path` ("" or "-" = standard output). Data goes to
/// "<path>.tmp.<pid>" and commit() renames it to `path`; destruction without commit() removes the
/// temporary. Throws std::runtime_error when the file cannot be created or written.
class AtomicOutput {
 public:
  explicit AtomicOutput(const std::string& path) : path_(path) {
    if (path.empty() || path == "-") return;
    tmp_ = path + ".tmp." + std::to_string(::getpid());
    file_.open(tmp_, std::ios::binary | std::ios::trunc);
    if (!file_) throw std::runtime_error(path + ": cannot create output file");
  }
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;
  ~AtomicOutput() {
    if (!tmp_.empty() && !committed_) {
      file_.close();
      std::error_code ec;
      std::filesystem::remove(tmp_, ec);
    }
  }
  /// The stream to write to.
  std::ostream& stream() { return tmp_.empty() ? std::cout : file_; }
  /// Flush and move the temporary into place.
  void commit() {
    if (tmp_.empty()) {
      std::cout.flush();
      return;
    }
    file_.flush();
    if (!file_) throw std::runtime_error(path_ + ": write failed");
    file_.close();
    std::filesystem::rename(tmp_, path_);
    committed_ = true;
  }

 private:
  std::string path_, tmp_;
  std::ofstream file_;
  bool committed_ = false;
};

}  // namespace rayscan::cli
