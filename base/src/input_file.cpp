// The input policy of rayscan: see rayscan/base/input_file.hpp.
#include "rayscan/base/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "file_kind.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>

namespace rayscan {

namespace {

/// `error_number`: the errno of a failed open(2) or stat(2), EISDIR for a directory, else 0
/// (InputFileError::error_number).
[[noreturn]] void refuse_input(const std::filesystem::path& path, const std::string& why, int error_number = 0) {
  throw InputFileError(one_line(path.string()) + ": " + why, path, error_number);
}

/// The errno a regular-file-only open gives mode `m`: EISDIR for a directory (what open(2) for
/// writing and Python's open() say), else 0 (refused by rule).
int not_regular_errno(mode_t m) { return S_ISDIR(m) ? EISDIR : 0; }

std::string not_regular(mode_t m) {
  return "is " + detail::file_kind_name(m) + ", not a regular file (rayscan reads regular files only)";
}

}  // namespace

std::string one_line(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\n') out += "\\n";
    else if (c == '\r') out += "\\r";
    else if (c == '\t') out += "\\t";
    else if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out;
}

InputFile::InputFile(const std::filesystem::path& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int e = errno;
    refuse_input(path, std::string("cannot open file: ") + std::strerror(e), e);
  }
  struct stat st {};
  if (::fstat(fd_, &st) != 0) {
    const int e = errno;
    ::close(fd_);
    fd_ = -1;
    refuse_input(path, std::string("cannot stat file: ") + std::strerror(e), e);
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd_);
    fd_ = -1;
    refuse_input(path, not_regular(st.st_mode), not_regular_errno(st.st_mode));
  }
  const int fl = ::fcntl(fd_, F_GETFL);
  if (fl >= 0) ::fcntl(fd_, F_SETFL, fl & ~O_NONBLOCK);
  size_ = static_cast<std::uint64_t>(st.st_size);
}

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

std::vector<std::uint8_t> InputFile::read_all() const {
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(size_));
  std::uint64_t got = 0;
  while (got < size_) {
    const ssize_t r = ::pread(fd_, buf.data() + got, static_cast<std::size_t>(size_ - got),
                              static_cast<off_t>(got));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) refuse_input(path_, "byte " + std::to_string(got) + ": read failed: " + std::strerror(errno));
    if (r == 0)
      refuse_input(path_, "byte " + std::to_string(got) + ": file shrank while being read (expected " +
                        std::to_string(size_) + " bytes)");
    got += static_cast<std::uint64_t>(r);
  }
  return buf;
}

void require_regular_file(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int e = errno;
    refuse_input(path, e == ENOENT ? std::string("no such file") : std::string("cannot stat file: ") + std::strerror(e),
                 e);
  }
  if (!S_ISREG(st.st_mode)) refuse_input(path, not_regular(st.st_mode), not_regular_errno(st.st_mode));
}

std::string read_text_file(const std::filesystem::path& path, std::uint64_t cap) {
  const auto over = [&](const std::string& size) {
    refuse_input(path, "file is " + size + " bytes, over the " + std::to_string(cap) +
                     "-byte limit for text inputs");
  };
  if (path == "-") {
    std::string s;
    char buf[65536];
    while (std::cin.read(buf, sizeof buf) || std::cin.gcount() > 0) {
      s.append(buf, static_cast<std::size_t>(std::cin.gcount()));
      if (s.size() > cap) over("more than " + std::to_string(cap));
    }
    return s;
  }
  const InputFile f(path);
  if (f.size() > cap) over(std::to_string(f.size()));
  const std::vector<std::uint8_t> b = f.read_all();
  return std::string(b.begin(), b.end());
}

}  // namespace rayscan
