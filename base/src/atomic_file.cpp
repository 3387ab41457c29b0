// The output policy of rayscan: see rayscan/base/atomic_file.hpp.
#include "rayscan/base/atomic_file.hpp"

#include "rayscan/base/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "file_kind.hpp"

#include <cerrno>
#include <cstring>

namespace rayscan {

namespace {

thread_local OutputTransaction* g_current = nullptr;

[[noreturn]] void refuse_output(const std::filesystem::path& path, const std::string& why) {
  throw OutputFileError(one_line(path.string()) + ": " + why);
}

}  // namespace

void require_replaceable_output(const std::filesystem::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISREG(st.st_mode))
      refuse_output(path, "is " + detail::file_kind_name(st.st_mode) +
                       "; refusing to replace it (outputs go to a new path or over a regular file)");
    return;
  }
  if (errno != ENOENT) refuse_output(path, std::string("cannot stat output path: ") + std::strerror(errno));
  const std::filesystem::path dir = path.parent_path().empty() ? "." : path.parent_path();
  struct stat ds {};
  if (::stat(dir.c_str(), &ds) != 0 || !S_ISDIR(ds.st_mode))
    refuse_output(path, "output directory '" + one_line(dir.string()) + "' does not exist");
}

OutputTransaction::OutputTransaction() : outer_(g_current) {
  if (outer_ == nullptr) g_current = this;
}

OutputTransaction::~OutputTransaction() {
  if (g_current == this) g_current = nullptr;
  for (const auto& [tmp, path] : pending_) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
  }
}

OutputTransaction* OutputTransaction::current() { return g_current; }

void OutputTransaction::adopt(std::filesystem::path temp, std::filesystem::path path) {
  pending_.emplace_back(std::move(temp), std::move(path));
}

void OutputTransaction::commit() {
  if (outer_ != nullptr) return;  // joined: the outer transaction renames
  if (g_current == this) g_current = nullptr;
  for (const auto& [tmp, path] : pending_) require_replaceable_output(path);  // re-checked: may have changed
  while (!pending_.empty()) {
    auto [tmp, path] = pending_.front();
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) refuse_output(path, "cannot move the finished file into place: " + ec.message());
    pending_.erase(pending_.begin());
  }
}

AtomicFile::AtomicFile(std::filesystem::path path) : path_(std::move(path)) {
  require_replaceable_output(path_);
  std::string name = ".";  // built by append: GCC 12 warns falsely (-Wrestrict) on operator+
  name.append(path_.filename().string()).append(".tmp.").append(std::to_string(::getpid()));
  tmp_ = path_.parent_path() / name;
  ::unlink(tmp_.c_str());  // a stale temporary of this pid (or a planted link): removed, not followed
  const int fd = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
  if (fd < 0) refuse_output(path_, std::string("cannot create output file: ") + std::strerror(errno));
  ::close(fd);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
  }
}

void AtomicFile::commit() {
  const int fd = ::open(tmp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
  if (OutputTransaction* tx = OutputTransaction::current()) {
    tx->adopt(tmp_, path_);
    committed_ = true;  // the transaction owns the temporary now
    return;
  }
  require_replaceable_output(path_);  // re-checked: the path may have changed while writing
  std::error_code ec;
  std::filesystem::rename(tmp_, path_, ec);
  if (ec) refuse_output(path_, "cannot move the finished file into place: " + ec.message());
  committed_ = true;
}

}  // namespace rayscan
