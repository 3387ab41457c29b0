// The output policy of rayscan: see rayscan/base/atomic_file.hpp.
#include "rayscan/base/atomic_file.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/interrupt.hpp"
#include "rayscan/base/option_error.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "file_kind.hpp"

#include <cerrno>
#include <cstring>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace rayscan {

namespace {

thread_local OutputTransaction* g_current = nullptr;

/// Throws OutputFileError "<path>: <why>" with the errno `err` of the failed call (0: a rule's).
[[noreturn]] void refuse_output(const std::filesystem::path& path, const std::string& why, int err = 0) {
  throw OutputFileError(one_line(path.string()) + ": " + why, err);
}

/// Gives `tmp` the permission bits of the regular file at `path`, if there is one, so that
/// replacing an output keeps its mode.
void keep_mode(const std::filesystem::path& tmp, const std::filesystem::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::chmod(tmp.c_str(), st.st_mode & 07777) != 0)
    throw output_error(path, "cannot give the new file the old one's mode", errno);
}

/// The registered temporaries (TemporaryOf): few at a time (a command's outputs and their
/// intermediate files), so a vector searched under a mutex; writer threads may look up at once.
struct Registered {
  std::uint64_t id;
  std::filesystem::path temp, output;
};
struct Registry {
  std::mutex m;
  std::vector<Registered> entries;
  std::uint64_t next_id = 1;
};
Registry& registry() {
  static Registry* r = new Registry;  // never destroyed: registrations may outlive static destructors
  return *r;
}

/// The entry whose temporary is `file` or the folder `file` lies in, or nullptr (registry locked).
const Registered* registered(const Registry& r, const std::filesystem::path& file) {
  for (const Registered& e : r.entries)
    if (e.temp == file) return &e;
  const std::filesystem::path folder = file.parent_path();
  if (folder.empty() || folder == file) return nullptr;
  for (const Registered& e : r.entries)
    if (e.temp == folder) return &e;
  return nullptr;
}

/// `p`'s folder, absolute and normalised, for comparing where two files lie.
std::filesystem::path folder_of(const std::filesystem::path& p) {
  std::error_code ec;
  const std::filesystem::path a = std::filesystem::absolute(p, ec);
  return (ec ? p : a).lexically_normal().parent_path();
}

}  // namespace

TemporaryOf::TemporaryOf(const std::filesystem::path& temp, const std::filesystem::path& output) {
  if (temp.empty() || output.empty()) return;
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.m);
  id_ = r.next_id++;
  r.entries.push_back({id_, temp, output});
}

TemporaryOf::TemporaryOf(TemporaryOf&& other) noexcept : id_(std::exchange(other.id_, 0)) {}

TemporaryOf& TemporaryOf::operator=(TemporaryOf&& other) noexcept {
  if (this != &other) {
    release();
    id_ = std::exchange(other.id_, 0);
  }
  return *this;
}

TemporaryOf::~TemporaryOf() { release(); }

void TemporaryOf::release() noexcept {
  if (id_ == 0) return;
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.m);
  std::erase_if(r.entries, [&](const Registered& e) { return e.id == id_; });
  id_ = 0;
}

IntermediateFile::IntermediateFile(std::filesystem::path temp, const std::filesystem::path& output,
                                   RemoveOnInterrupt::Kind kind)
    : temp_(std::move(temp)), kind_(kind), temp_for_(temp_, output, kind) {
  if (kind_ != RemoveOnInterrupt::Kind::folder) return;
  std::error_code ec;
  std::filesystem::create_directory(temp_, ec);
  if (ec) throw output_error(temp_, "cannot create the temporary folder", ec.value());
}

IntermediateFile::~IntermediateFile() {
  std::error_code ec;
  if (kind_ == RemoveOnInterrupt::Kind::folder) std::filesystem::remove_all(temp_, ec);
  else std::filesystem::remove(temp_, ec);
}

std::string temporary_named_as(std::string message, const std::filesystem::path& temp,
                               const std::filesystem::path& named) {
  const std::string t = temp.string();
  if (!t.empty() && message.rfind(t, 0) == 0) message = named.string() + message.substr(t.size());
  return message;
}

std::filesystem::path output_of(const std::filesystem::path& file) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.m);
  std::filesystem::path p = file;
  // Bounded: a chain is two or three links long; a cycle (never registered) cannot hang.
  for (std::size_t hop = 0; hop <= r.entries.size(); ++hop) {
    const Registered* e = registered(r, p);
    if (e == nullptr) break;
    p = e->output;
  }
  return p;
}

OutputFileError output_error(const std::filesystem::path& file, const std::string& what, int err) {
  const std::filesystem::path out = output_of(file);
  std::string message = one_line(out.string()) + ": " + what;
  if (out != file) {
    // Where the bytes went: the file's folder, or for a file in a registered temporary folder
    // (sort runs) the folder that one lies in.
    std::filesystem::path written = file;
    {
      Registry& r = registry();
      const std::lock_guard<std::mutex> lock(r.m);
      const Registered* e = registered(r, file);
      if (e != nullptr && e->temp != file) written = e->temp;
    }
    const std::filesystem::path where = folder_of(written);
    if (where != folder_of(out)) message += " (temporary file in '" + one_line(where.string()) + "')";
  }
  if (err != 0) message += std::string(": ") + std::strerror(err);
  return OutputFileError(message, err);
}

void require_temp_dir(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!dir.empty() && !std::filesystem::is_directory(dir, ec))
    throw OptionError({option("temp_dir"), " '" + one_line(dir.string()) + "': not an existing folder"});
}

void require_replaceable_output(const std::filesystem::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISREG(st.st_mode))
      refuse_output(path,
                    "is " + detail::file_kind_name(st.st_mode) +
                        "; refusing to replace it (outputs go to a new path or over a regular file)",
                    S_ISDIR(st.st_mode) ? EISDIR : 0);
    return;
  }
  if (errno != ENOENT) throw output_error(path, "cannot stat output path", errno);
  const std::filesystem::path dir = path.parent_path().empty() ? "." : path.parent_path();
  struct stat ds {};
  const int dir_err = ::stat(dir.c_str(), &ds) != 0 ? errno : S_ISDIR(ds.st_mode) ? 0 : ENOTDIR;
  if (dir_err != 0) refuse_output(path, "output directory '" + one_line(dir.string()) + "' does not exist", dir_err);
}

void require_outputs(std::span<const std::filesystem::path> outputs, std::span<const std::filesystem::path> inputs) {
  // Two outputs of one command at one path would share a temporary file, and the second would
  // replace the first: refused, by their paths with every link and `..` resolved.
  std::vector<std::filesystem::path> resolved;
  for (const std::filesystem::path& p : outputs) {
    std::error_code ec;
    const std::filesystem::path a = std::filesystem::absolute(p, ec).lexically_normal();
    const std::filesystem::path r = std::filesystem::weakly_canonical(a, ec);
    resolved.push_back(ec ? a : r);
  }
  for (std::size_t j = 0; j < outputs.size(); ++j)
    for (std::size_t i = 0; i < j; ++i)
      if (!outputs[i].empty() && !outputs[j].empty() && resolved[i] == resolved[j])
        refuse_output(outputs[j], "is also the command's output '" + one_line(outputs[i].string()) +
                                      "' (give each output its own path)");
  for (const std::filesystem::path& out : outputs) {
    if (out.empty()) continue;
    require_replaceable_output(out);
    const std::filesystem::path dir = out.parent_path().empty() ? "." : out.parent_path();
    // A file created there and removed: permission bits (access(2)) pass root everywhere, while a
    // file system that takes no new files (procfs, sysfs, a read-only mount) only says so when one
    // is created. A short fixed name, so that a long output name cannot make it too long.
    const std::filesystem::path probe = dir / (".rayscan-probe." + std::to_string(::getpid()));
    {
      const RemoveOnInterrupt on_signal(probe);  // a signal between open and unlink removes it too
      ::unlink(probe.c_str());  // a stale probe of this pid (or a planted link): removed, not followed
      const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
      if (fd < 0) {
        const int err = errno;  // read before the message is built
        throw output_error(out, "cannot write in directory '" + one_line(dir.string()) + "'", err);
      }
      ::close(fd);
      ::unlink(probe.c_str());
    }
    struct stat os {};
    if (::stat(out.c_str(), &os) != 0) continue;  // a new file cannot be an input
    for (const std::filesystem::path& in : inputs) {
      struct stat is {};
      if (!in.empty() && ::stat(in.c_str(), &is) == 0 && is.st_dev == os.st_dev && is.st_ino == os.st_ino)
        refuse_output(out, "is the same file as the input '" + one_line(in.string()) +
                               "' (write the output to another path)");
    }
  }
}

OutputTransaction::OutputTransaction() : outer_(g_current) {
  if (outer_ == nullptr) g_current = this;
}

OutputTransaction::~OutputTransaction() {
  if (g_current == this) g_current = nullptr;
  for (const Pending& p : pending_) {
    std::error_code ec;
    std::filesystem::remove(p.temp, ec);
  }
}

OutputTransaction* OutputTransaction::current() { return g_current; }

void OutputTransaction::adopt(std::filesystem::path temp, std::filesystem::path path, RemoveOnInterrupt mark) {
  pending_.push_back({std::move(temp), std::move(path), std::move(mark)});
}

void OutputTransaction::commit() {
  if (outer_ != nullptr) return;  // joined: the outer transaction renames
  if (g_current == this) g_current = nullptr;
  for (const Pending& p : pending_) require_replaceable_output(p.path);  // re-checked: may have changed
  while (!pending_.empty()) {
    const Pending& p = pending_.front();
    keep_mode(p.temp, p.path);
    std::error_code ec;
    std::filesystem::rename(p.temp, p.path, ec);
    if (ec) refuse_output(p.path, "cannot move the finished file into place: " + ec.message(), ec.value());
    pending_.erase(pending_.begin());  // (its mark with it: the temporary is gone)
  }
}

AtomicFile::AtomicFile(std::filesystem::path path) : path_(std::move(path)) {
  require_replaceable_output(path_);
  std::string name = ".";  // built by append: GCC 12 warns falsely (-Wrestrict) on operator+
  name.append(path_.filename().string()).append(".tmp.").append(std::to_string(::getpid()));
  tmp_ = path_.parent_path() / name;
  temp_for_ = TemporaryFor(tmp_, path_);  // before the file exists: no moment uncovered
  ::unlink(tmp_.c_str());  // a stale temporary of this pid (or a planted link): removed, not followed
  const int fd = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
  if (fd < 0) throw output_error(path_, "cannot create output file", errno);
  ::close(fd);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
  }
}

void AtomicFile::write_all(std::span<const unsigned char> bytes) {
  const int fd = ::open(tmp_.c_str(), O_WRONLY | O_TRUNC | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) throw output_error(path_, "cannot open the temporary file", errno);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t w = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      const int e = w < 0 ? errno : ENOSPC;  // a zero-byte write makes no progress: treat as full
      ::close(fd);
      throw output_error(path_,
                         "cannot write " + std::to_string(bytes.size()) + " bytes (wrote " + std::to_string(done) + ")", e);
    }
    done += static_cast<std::size_t>(w);
  }
  if (::close(fd) != 0) throw output_error(path_, "cannot write", errno);
}

void AtomicFile::commit() {
  // fsync reports the delayed write errors (ENOSPC, EIO) of file systems that allocate late.
  const int fd = ::open(tmp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw output_error(path_, "cannot reopen the temporary file", errno);
  const bool synced = ::fsync(fd) == 0 || errno == EINVAL || errno == EROFS;  // EINVAL: no sync support
  const int sync_errno = errno;
  ::close(fd);
  if (!synced) throw output_error(path_, "cannot write", sync_errno);
  if (OutputTransaction* tx = OutputTransaction::current()) {
    tx->adopt(tmp_, path_, temp_for_.take_mark());
    committed_ = true;  // the transaction owns the temporary now
    return;
  }
  require_replaceable_output(path_);  // re-checked: the path may have changed while writing
  keep_mode(tmp_, path_);
  std::error_code ec;
  std::filesystem::rename(tmp_, path_, ec);
  if (ec) refuse_output(path_, "cannot move the finished file into place: " + ec.message(), ec.value());
  committed_ = true;
}

}  // namespace rayscan
