// The input policy: every file rayscan reads is opened here. Only regular files are
// read (FIFOs, devices, directories and sockets are refused before any read, and the open itself
// never blocks); text inputs (scene / camera JSON, observer files, rays CSV) are capped in size;
// every read loop is bounded by the size fstat(2) reports, never by a count in a header.
#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan {

/// A file that the input policy refuses (not a regular file, missing, unreadable, over the
/// size cap). what() is one line: "<path>: <reason>"; path() is the file. Where the refusal is
/// a failed open(2) or stat(2), or a directory, error_number() is the errno (EISDIR for a
/// directory), so that a front end can raise its own error for it (Python's FileNotFoundError);
/// 0 for a refusal by rule (a FIFO, a size over the cap) or a failed read.
class InputFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
  InputFileError(const std::string& what, std::filesystem::path path, int error_number)
      : std::runtime_error(what), path_(std::move(path)), error_number_(error_number) {}
  /// The errno of the failed call (see above), 0 when none.
  [[nodiscard]] int error_number() const noexcept { return error_number_; }
  /// The file refused (empty for an error built from a message alone).
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }

 private:
  std::filesystem::path path_;
  int error_number_ = 0;
};

/// Size cap of text inputs (JSON, CSV, observer and rays files): 256 MiB. A scene, camera or
/// observer file is a few KiB; a rays CSV of 256 MiB holds about 3 million rays (use the binary
/// .f64 rays format, which is not capped, for more).
inline constexpr std::uint64_t kTextInputCap = 256ull << 20;

/// A read-only file descriptor on a regular file (RAII). Opened with O_RDONLY | O_NONBLOCK |
/// O_CLOEXEC (so that opening a FIFO does not wait for a writer), checked with fstat(2) to be a
/// regular file, then switched back to blocking reads. Throws InputFileError otherwise.
class InputFile {
 public:
  explicit InputFile(const std::filesystem::path& path);
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  InputFile(InputFile&& o) noexcept : path_(std::move(o.path_)), fd_(o.fd_), size_(o.size_) { o.fd_ = -1; }
  ~InputFile();
  /// The open descriptor (owned by this object).
  [[nodiscard]] int fd() const { return fd_; }
  /// File size in bytes at open time (fstat st_size).
  [[nodiscard]] std::uint64_t size() const { return size_; }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  /// Reads exactly size() bytes (a loop bounded by size(); a file that shrinks while being read
  /// throws InputFileError naming the byte offset).
  [[nodiscard]] std::vector<std::uint8_t> read_all() const;

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

/// Throws InputFileError unless `path` names an existing regular file (symlinks followed). For
/// inputs opened by a third-party library (OpenImageIO), called before the library sees the path.
void require_regular_file(const std::filesystem::path& path);

/// Reads a whole text input under the input policy: `path` must be a regular file of at most
/// `cap` bytes ("-" reads standard input, up to `cap` bytes). Throws InputFileError
/// ("<path>: file is N bytes, over the M-byte limit for text inputs").
std::string read_text_file(const std::filesystem::path& path, std::uint64_t cap = kTextInputCap);

/// A one-line rendering of `s` for messages: newlines, tabs and other control characters
/// become C escapes ("\n", "\t", "\x1b"), so a path holding a newline keeps a message on one line.
std::string one_line(const std::string& s);

}  // namespace rayscan
