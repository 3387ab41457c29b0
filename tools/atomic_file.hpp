// Text output of the tools: a file written through rayscan::AtomicFile (temporary + rename), or
// standard output.
#pragma once

#include "rayscan/base/atomic_file.hpp"

#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>

namespace rayscan::cli {

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
  /// Flush and move the finished file into place.
  void commit() {
    if (!file_) {
      std::cout.flush();
      return;
    }
    out_.flush();
    if (!out_) throw std::runtime_error(file_->path().string() + ": write failed");
    out_.close();  // the last buffer's write error shows here
    if (!out_) throw std::runtime_error(file_->path().string() + ": write failed");
    file_->commit();
  }

 private:
  std::unique_ptr<AtomicFile> file_;
  std::ofstream out_;
};

}  // namespace rayscan::cli
