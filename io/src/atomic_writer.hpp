// Internal: binary output files written to rayscan::AtomicFile's temporary and renamed into place
// by commit(); a failed write never leaves a partial file at `path`. AtomicWriter writes forward
// through a large buffer; AtomicStream also seeks (a header filled in after the data).
#pragma once

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/interrupt.hpp"

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
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

/// An output written through a std::ofstream to AtomicFile's temporary, for writers that seek back
/// to fill in a header. Every write and seek is checked where it happens, so that the error's
/// cause is that call's errno (a full disk) rather than whatever errno holds by the close: an
/// OutputFileError "<path>: write failed: <cause>" (output_error names the output, not the
/// temporary). Not copyable.
class AtomicStream {
 public:
  /// Throws OutputFileError as AtomicFile does, or "<path>: cannot create output file: <cause>".
  explicit AtomicStream(const std::filesystem::path& path)
      : file_(path), f_(file_.temp(), std::ios::binary | std::ios::trunc) {
    if (!f_) throw output_error(file_.temp(), "cannot create output file", errno);
  }
  AtomicStream(const AtomicStream&) = delete;
  AtomicStream& operator=(const AtomicStream&) = delete;
  /// Writes `n` bytes from `p` at the current position.
  void write(const void* p, std::uint64_t n) {
    f_.write(static_cast<const char*>(p), static_cast<std::streamsize>(n));
    if (!f_) throw output_error(file_.temp(), "write failed", errno);
  }
  /// Moves the write position to byte `at` of the file.
  void seek(std::uint64_t at) {
    f_.seekp(static_cast<std::streamoff>(at));
    if (!f_) throw output_error(file_.temp(), "write failed", errno);
  }
  /// Closes the file (checked, as a write) and renames it into place (AtomicFile::commit()).
  void commit() {
    f_.close();
    if (!f_) throw output_error(file_.temp(), "write failed", errno);
    file_.commit();
  }

 private:
  AtomicFile file_;
  std::ofstream f_;  // declared last: closed before file_ removes an uncommitted temporary
};

}  // namespace rayscan::io::detail
