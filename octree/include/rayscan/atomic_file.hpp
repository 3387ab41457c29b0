// Output files are never left half-written: data goes to a temporary sibling and is renamed into
// place only when complete (rename(2) is atomic within a file system).
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

#include <fcntl.h>
#include <unistd.h>

namespace rayscan {

/// A temporary path "<dir>/.<name>.tmp.<pid>" next to `path`. Write the whole output to temp(),
/// then call commit() to rename it to `path`. If commit() is not reached (an exception, an early
/// return), the destructor removes the temporary, so `path` is either the old file or the complete
/// new one. Throws std::runtime_error from commit() when the rename fails.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path) : path_(std::move(path)) {
    std::string name = ".";  // built by append: GCC 12 warns falsely (-Wrestrict) on operator+
    name.append(path_.filename().string()).append(".tmp.").append(std::to_string(::getpid()));
    tmp_ = path_.parent_path() / name;
  }
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile() {
    if (!committed_) {
      std::error_code ec;
      std::filesystem::remove(tmp_, ec);
    }
  }
  /// The final path.
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  /// Where to write the data.
  [[nodiscard]] const std::filesystem::path& temp() const { return tmp_; }
  /// Flush the finished temporary to disk (fsync) and move it into place, so that after a crash
  /// or power loss `path` holds the old or the complete new file, never an empty one.
  void commit() {
    const int fd = ::open(tmp_.c_str(), O_RDONLY);
    if (fd >= 0) {
      ::fsync(fd);
      ::close(fd);
    }
    std::error_code ec;
    std::filesystem::rename(tmp_, path_, ec);
    if (ec)
      throw std::runtime_error(path_.string() + ": cannot move the finished file into place: " +
                               ec.message());
    committed_ = true;
  }

 private:
  std::filesystem::path path_;
  std::filesystem::path tmp_;
  bool committed_ = false;
};

}  // namespace rayscan
