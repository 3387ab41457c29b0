// Direct and buffered file I/O of the index build and the read-only maps of its own output:
// descriptors that throw on failure, the background writer of page-aligned buffers (O_DIRECT),
// the sequential section writer with its running CRC-32C, and a map that drops its pages behind a
// sequential pass. docs/index-format.md, "Build (external memory)" 3 and 4.
#pragma once

#include "bytes.hpp"
#include "format.hpp"
#include "rayscan/base/atomic_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace rayscan::io::rsi {

using detail::HugeArray;
using detail::kDirectAlign;
using detail::round_up_direct;

/// Throws OutputFileError "<output>: <what>: <errno text>", the output being the file the user
/// asked for that `p` is written for (output_of: the build's temporary output and sort runs are
/// hidden files that mean nothing to the user), else `p` itself.
[[noreturn]] inline void io_fail(const fs::path& p, const std::string& what) { throw output_error(p, what, errno); }

/// An owned file descriptor with full-length pwrite/pread that throw on failure (ENOSPC etc.).
class Fd {
 public:
  Fd(const fs::path& p, int flags, mode_t mode = 0644) : path_(p) {
    fd_ = ::open(p.c_str(), flags | O_CLOEXEC, mode);
    if (fd_ < 0) io_fail(p, "cannot open");
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  void pwrite_all(const void* data, std::size_t n, std::uint64_t off) {
    const auto* p = static_cast<const char*>(data);
    while (n > 0) {
      const ssize_t w = ::pwrite(fd_, p, n, static_cast<off_t>(off));
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        if (w == 0) errno = ENOSPC;
        io_fail(path_, "write failed at byte " + std::to_string(off));
      }
      p += w;
      n -= static_cast<std::size_t>(w);
      off += static_cast<std::uint64_t>(w);
    }
  }
  /// Reads up to n bytes at off; returns bytes read (less only at end of file). On an O_DIRECT
  /// descriptor a read that ends off a block boundary is the end of the file: the loop stops
  /// there rather than read again at an unaligned offset.
  std::size_t pread_some(void* data, std::size_t n, std::uint64_t off) {
    auto* p = static_cast<char*>(data);
    std::size_t got = 0;
    while (got < n) {
      const ssize_t r = ::pread(fd_, p + got, n - got, static_cast<off_t>(off + got));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) io_fail(path_, "read failed at byte " + std::to_string(off + got));
      if (r == 0) break;
      got += static_cast<std::size_t>(r);
      if (direct_ && got % 4096 != 0) break;
    }
    return got;
  }
  [[nodiscard]] int get() const { return fd_; }
  /// Opens with O_DIRECT where the file system takes it (not tmpfs, say), else as a plain open.
  static Fd direct(const fs::path& p, int flags) {
    const int d = ::open(p.c_str(), flags | O_DIRECT | O_CLOEXEC, 0644);
    if (d >= 0) return Fd(d, p, true);
    return Fd(p, flags);
  }
  /// True when opened with O_DIRECT: offsets, lengths and buffers of reads and writes must be
  /// multiples of kDirectAlign (the page cache is bypassed).
  [[nodiscard]] bool is_direct() const { return direct_; }
  Fd(Fd&& o) noexcept : fd_(std::exchange(o.fd_, -1)), path_(std::move(o.path_)), direct_(o.direct_) {}

 private:
  Fd(int d, fs::path p, bool direct) : fd_(d), path_(std::move(p)), direct_(direct) {}
  int fd_ = -1;
  fs::path path_;
  bool direct_ = false;
};


/// Writes page-aligned buffers to O_DIRECT descriptors on a thread of its own, so that the
/// builder's in-order sink never waits for the disk: a fixed pool of buffers (page-aligned,
/// kDirectAlign multiples) is acquired, filled, submitted and recycled after its write. Errors
/// (a full disk) are kept and rethrown by the next acquire/submit/drain.
class DirectWriter {
 public:
  DirectWriter(std::size_t buffers, std::size_t bytes) : bytes_(bytes) {
    for (std::size_t i = 0; i < buffers; ++i) {
      pool_.emplace_back(bytes);
      free_.push_back(pool_.back().data());
    }
    thread_ = std::thread([this] { run(); });
  }
  DirectWriter(const DirectWriter&) = delete;
  DirectWriter& operator=(const DirectWriter&) = delete;
  ~DirectWriter() {
    {
      std::lock_guard<std::mutex> lk(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  [[nodiscard]] std::size_t buffer_bytes() const { return bytes_; }
  /// A free buffer of buffer_bytes() (waits for a write to end when all are in use).
  std::uint8_t* acquire() {
    std::unique_lock<std::mutex> lk(m_);
    cv_.wait(lk, [&] { return !free_.empty() || error_; });
    rethrow();
    std::uint8_t* b = free_.back();
    free_.pop_back();
    return b;
  }
  /// Queues the write of buf[0, len) at byte `off` of `fd` (len and off multiples of
  /// kDirectAlign); buf returns to the pool after it.
  void submit(Fd& fd, std::uint8_t* buf, std::size_t len, std::uint64_t off) {
    {
      std::lock_guard<std::mutex> lk(m_);
      rethrow();
      jobs_.push_back({&fd, buf, len, off});
    }
    cv_.notify_all();
  }
  /// Waits until every submitted write has ended; rethrows the first error.
  void drain() {
    std::unique_lock<std::mutex> lk(m_);
    cv_.wait(lk, [&] { return (jobs_.empty() && busy_ == 0) || error_; });
    rethrow();
  }

 private:
  struct Job {
    Fd* fd;
    std::uint8_t* buf;
    std::size_t len;
    std::uint64_t off;
  };
  void rethrow() {
    if (error_) std::rethrow_exception(error_);
  }
  void run() {
    std::unique_lock<std::mutex> lk(m_);
    for (;;) {
      cv_.wait(lk, [&] { return stop_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // (stop_)
      const Job j = jobs_.front();
      jobs_.pop_front();
      ++busy_;
      lk.unlock();
      std::exception_ptr e;
      try {
        j.fd->pwrite_all(j.buf, j.len, j.off);
      } catch (...) {
        e = std::current_exception();
      }
      lk.lock();
      --busy_;
      if (e && !error_) error_ = e;
      free_.push_back(j.buf);
      cv_.notify_all();
    }
  }
  std::size_t bytes_;
  std::deque<HugeArray<std::uint8_t>> pool_;
  std::vector<std::uint8_t*> free_;
  std::deque<Job> jobs_;
  std::size_t busy_ = 0;
  bool stop_ = false;
  std::exception_ptr error_;
  std::mutex m_;
  std::condition_variable cv_;
  std::thread thread_;
};

/// Sequential writer into one region of a file, with a running CRC-32C of the bytes written.
/// With a DirectWriter (and an O_DIRECT descriptor; the region's offset a multiple of
/// kDirectAlign) the bytes go through its page-aligned buffers past the page cache, written in
/// the background; the last page is padded with zeros past the region's end (flush), which must
/// be free file space (sections are kAlign-aligned). Why: on a VM whose balloon reports free
/// memory to the host, each fresh page-cache page is a host fault on first touch, and buffered
/// writes of the output cost ~1.5 s of CPU per GB against ~0.1 s direct (bench/notes/).
class SectionWriter {
 public:
  SectionWriter(Fd& fd, std::uint64_t offset, std::size_t buffer_bytes, DirectWriter* direct = nullptr)
      : fd_(&fd), off_(offset) {
    if (direct != nullptr && fd.is_direct()) {
      if (offset % kDirectAlign != 0) throw std::logic_error("index build: a direct section off its alignment");
      dw_ = direct;
    } else {
      buf_.reserve(buffer_bytes);
    }
  }
  void write(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    if (dw_ != nullptr) {
      crc_ = crc32_of(b, n, crc_);
      while (n > 0) {
        if (cur_ == nullptr) cur_ = dw_->acquire(), fill_ = 0;
        const std::size_t take = std::min(n, dw_->buffer_bytes() - fill_);
        std::memcpy(cur_ + fill_, b, take);
        fill_ += take, b += take, n -= take;
        if (fill_ == dw_->buffer_bytes()) submit(fill_);
      }
      return;
    }
    if (buf_.size() + n > buf_.capacity()) flush();
    if (n >= buf_.capacity()) {
      emit(b, n);
      return;
    }
    buf_.insert(buf_.end(), b, b + n);
  }
  /// Writes what is buffered. Direct: only at the end of the section (the last page padded;
  /// the write may still run: DirectWriter::drain).
  void flush() {
    if (dw_ != nullptr) {
      if (cur_ != nullptr && fill_ > 0) {
        const std::size_t len = round_up_direct(fill_), real = fill_;
        std::memset(cur_ + fill_, 0, len - fill_);
        submit(len);
        written_ -= len - real;
      }
      return;
    }
    if (!buf_.empty()) emit(buf_.data(), buf_.size());
    buf_.clear();
  }
  [[nodiscard]] std::uint32_t crc() const { return crc_; }
  [[nodiscard]] std::uint64_t written() const { return written_; }

 private:
  void emit(const std::uint8_t* p, std::size_t n) {
    fd_->pwrite_all(p, n, off_ + written_);
    crc_ = crc32_of(p, n, crc_);
    written_ += n;
  }
  void submit(std::size_t len) {
    dw_->submit(*fd_, cur_, len, off_ + written_);
    written_ += len;
    cur_ = nullptr;
    fill_ = 0;
  }
  Fd* fd_;
  std::uint64_t off_;
  std::uint64_t written_ = 0;
  std::uint32_t crc_ = 0;
  std::vector<std::uint8_t> buf_;
  DirectWriter* dw_ = nullptr;   // direct mode: the background writer
  std::uint8_t* cur_ = nullptr;  // ... its buffer being filled, to fill_
  std::size_t fill_ = 0;
};

/// Page size of the maps below (madvise ranges are page-aligned).
inline std::size_t page_bytes() {
  static const std::size_t p = [] {
    const long v = ::sysconf(_SC_PAGESIZE);
    return v > 0 ? static_cast<std::size_t>(v) : std::size_t{4096};
  }();
  return p;
}

/// Read-only map of a file region (for the codes temp file and the output's positions).
/// release_below() drops the pages of [0, byte) from the process (MADV_DONTNEED: on a shared
/// read-only map the data stays in the page cache and is faulted in again if touched), so a
/// sequential pass holds a bounded number of resident pages whatever the file size.
struct ReadMap {
  void* p = nullptr;
  std::size_t n = 0;
  std::size_t released = 0;  ///< bytes [0, released) have been dropped
  ReadMap(int fd, std::size_t bytes, const fs::path& name) : n(bytes) {
    if (n == 0) return;
    p = ::mmap(nullptr, n, PROT_READ, MAP_SHARED, fd, 0);
    if (p == MAP_FAILED) {
      p = nullptr;
      io_fail(name, "cannot memory-map");
    }
  }
  ReadMap(const ReadMap&) = delete;
  ReadMap& operator=(const ReadMap&) = delete;
  ~ReadMap() {
    if (p != nullptr) ::munmap(p, n);
  }
  void release_below(std::size_t byte) {
    const std::size_t end = std::min(byte, n) / page_bytes() * page_bytes();
    if (p == nullptr || end <= released) return;
    (void)::madvise(static_cast<std::uint8_t*>(p) + released, end - released, MADV_DONTNEED);
    released = end;
  }
  /// Drops every resident page of the map (release_below's bookkeeping is kept: it only ever
  /// drops pages again).
  void drop() const {
    if (p != nullptr) (void)::madvise(p, n, MADV_DONTNEED);
  }
  /// Maps the pages of [byte, byte + len) in one call (MADV_POPULATE_READ, best effort) instead
  /// of a page fault per few pages as a sequential pass reaches them.
  void populate(std::size_t byte, std::size_t len) const {
    const std::size_t b = std::min(byte, n) / page_bytes() * page_bytes(), e = std::min(n, byte + len);
    if (p != nullptr && e > b) (void)::madvise(static_cast<std::uint8_t*>(p) + b, e - b, MADV_POPULATE_READ);
  }
};

}  // namespace rayscan::io::rsi
