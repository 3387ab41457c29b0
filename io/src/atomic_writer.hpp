// Internal: a binary output file written through a large buffer to rayscan::AtomicFile's temporary
// and renamed into place by commit(); a failed write never leaves a partial file at `path`.
#pragma once

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/interrupt.hpp"

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <fcntl.h>
#include <unistd.h>
#include <vector>

namespace rayscan::io::detail {

class AtomicWriter {
 public:
  /// `direct`: write straight to `path` (no temporary, no rename; for an intermediate file the
  /// caller removes itself, e.g. the plain LAS that write_las compresses into a .laz output). A
  /// direct file is marked for removal by the interrupt handler (RemoveOnInterrupt) while this
  /// writer lives; a caller that keeps the file longer marks it itself. Errors name the output a
  /// direct file is registered for (TemporaryOf, by the caller), else the file itself.
  explicit AtomicWriter(const std::filesystem::path& path, bool direct = false) : path_(path) {
    if (!direct) {
      file_.emplace(path);
      f_ = std::fopen(file_->temp().c_str(), "wb");
    } else {  // created exclusively, never through a planted link (as AtomicFile's temporary)
      mark_ = RemoveOnInterrupt(path);
      std::error_code ec;
      std::filesystem::remove(path, ec);
      const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
      if (fd >= 0 && (f_ = ::fdopen(fd, "wb")) == nullptr) ::close(fd);
    }
    if (f_ == nullptr) {
      const int e = errno;
      if (direct) require_replaceable_output(path);  // a missing folder is named as for every output
      throw output_error(direct ? path : file_->temp(), "cannot create output file", e);
    }
    buf_.reserve(kBuffer);
  }
  AtomicWriter(const AtomicWriter&) = delete;
  AtomicWriter& operator=(const AtomicWriter&) = delete;
  ~AtomicWriter() {
    if (f_ != nullptr) std::fclose(f_);
  }
  void write(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    buf_.insert(buf_.end(), b, b + n);
    if (buf_.size() >= kBuffer) flush();
  }
  template <class T>
  void put(T v) {
    write(&v, sizeof(T));
  }
  /// Writes `s` into a fixed-width NUL-padded field of `n` bytes (truncating).
  void put_fixed(const std::string& s, std::size_t n) {
    std::vector<char> f(n, '\0');
    std::memcpy(f.data(), s.data(), std::min(n, s.size()));
    write(f.data(), n);
  }
  /// Writes what is buffered and closes the file (then, unless direct, renames it into place).
  /// A failed write is an OutputFileError naming the output the user asked for (output_error:
  /// the temporary's output, or the output a direct intermediate file is registered for).
  void commit() {
    flush();
    if (std::fflush(f_) != 0 || std::ferror(f_)) throw output_error(where(), "write failed", errno);
    const int closed = std::fclose(f_);
    f_ = nullptr;
    if (closed != 0) throw output_error(where(), "write failed", errno);
    if (file_) file_->commit();
  }

 private:
  static constexpr std::size_t kBuffer = 4u << 20;
  void flush() {
    if (buf_.empty()) return;
    const std::size_t w = std::fwrite(buf_.data(), 1, buf_.size(), f_);
    if (w != buf_.size()) throw output_error(where(), "write failed at byte " + std::to_string(flushed_ + w), errno);
    flushed_ += w;
    buf_.clear();
  }
  /// The file written: the temporary of `path_`, or `path_` itself when direct.
  [[nodiscard]] const std::filesystem::path& where() const { return file_ ? file_->temp() : path_; }
  std::filesystem::path path_;
  std::uint64_t flushed_ = 0;  // bytes handed to the stream before the buffer
  std::optional<AtomicFile> file_;
  RemoveOnInterrupt mark_;  // a direct file's
  std::FILE* f_ = nullptr;
  std::vector<std::uint8_t> buf_;
};

}  // namespace rayscan::io::detail
