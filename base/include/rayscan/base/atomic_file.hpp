// The output policy. Output files are never left half-written: data goes to a
// temporary sibling and is renamed into place only when complete (rename(2) is atomic within a
// file system). Only a regular file or an absent path is ever replaced: a device node, FIFO,
// socket, directory or symbolic link at the output path is refused before anything is written.
// Outputs that belong together (an image and its AOV file, a LAS file and its raster) are written
// inside an OutputTransaction: every temporary is written first, and the renames happen only when
// all of them succeeded. Every temporary is marked for removal should a signal end the program
// (RemoveOnInterrupt, rayscan/base/interrupt.hpp), so an interrupted command leaves none either.
#pragma once

#include "rayscan/base/interrupt.hpp"

#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

namespace rayscan {

/// An output path the output policy refuses, or a failed write or commit. what() is one line
/// "<path>: <reason>". code() is the errno of the system call that failed (ENOENT for a missing
/// output folder, EACCES, ENOSPC for a full disk), so that a binding can raise its own error for
/// it (the Python module's FileNotFoundError); an empty code for a refusal by rule (a FIFO at the
/// path, an output that is also an input).
struct OutputFileError : std::runtime_error {
  /// `what`: the message; `err`: the errno, 0 for none.
  explicit OutputFileError(const std::string& what, int err = 0)
      : std::runtime_error(what), code_(err == 0 ? std::error_code() : std::error_code(err, std::generic_category())) {}
  /// The failed call's errno in the generic category; false when the refusal is a rule's.
  [[nodiscard]] std::error_code code() const noexcept { return code_; }

 private:
  std::error_code code_;
};

/// Registers `temp`, a temporary file or folder written for the output `output`, while this object
/// lives, so that errors about it name the file the user asked for (output_of, output_error): a
/// hidden name such as ".x.laz.las.tmp.512" means nothing to the user. A file inside a registered
/// folder belongs to that folder's output, and `output` may itself be registered (an import's
/// temporary index, whose AtomicFile has a temporary of its own): output_of follows the chain.
/// AtomicFile registers its temporary itself; this is for the intermediate files that are not an
/// AtomicFile's (an uncompressed LAS before compression, COPC records, sort runs; TemporaryFor
/// also marks them for removal on a signal, IntermediateFile also removes them on the way out).
/// Empty paths register nothing. Never throws but std::bad_alloc. Movable, not copyable.
class TemporaryOf {
 public:
  /// Registers nothing.
  TemporaryOf() = default;
  TemporaryOf(const std::filesystem::path& temp, const std::filesystem::path& output);
  TemporaryOf(TemporaryOf&& other) noexcept;
  TemporaryOf& operator=(TemporaryOf&& other) noexcept;
  TemporaryOf(const TemporaryOf&) = delete;
  TemporaryOf& operator=(const TemporaryOf&) = delete;
  ~TemporaryOf();

 private:
  void release() noexcept;
  std::uint64_t id_ = 0;  // 0: nothing registered
};

/// A temporary file or folder `temp` written for the output `output`, while this object lives both
/// registered (TemporaryOf: errors about it name `output`) and marked for removal should a signal
/// end the program (RemoveOnInterrupt, of `kind`). Make it before creating `temp` and destroy it
/// only after removing or renaming `temp`, so that no moment is uncovered; it removes nothing
/// itself. An empty `temp` registers and marks nothing. Never throws but std::bad_alloc. Movable,
/// not copyable.
class TemporaryFor {
 public:
  /// Registers and marks nothing.
  TemporaryFor() = default;
  TemporaryFor(const std::filesystem::path& temp, const std::filesystem::path& output,
               RemoveOnInterrupt::Kind kind = RemoveOnInterrupt::Kind::file)
      : name_(temp, output), mark_(temp, kind) {}
  /// Hands over the mark (to an OutputTransaction, which removes the temporary later); the
  /// registration stays with this object.
  [[nodiscard]] RemoveOnInterrupt take_mark() noexcept { return std::move(mark_); }

 private:
  TemporaryOf name_;
  RemoveOnInterrupt mark_;  // declared last: released before the registration
};

/// An intermediate file `temp` written for the output `output` and never renamed into place (the
/// uncompressed LAS that a LAZ or COPC output is made from, COPC records, an import's index), or
/// with Kind::folder a folder of such files (the sort runs of an index build): registered and
/// marked while this object lives (TemporaryFor: errors about it, or a file in the folder, name
/// `output`; a signal removes it), and removed, a folder with its contents, when this object is
/// destroyed, however the scope is left (an exception, a return). A file is created by its
/// writer after this object; a folder is created by the constructor (its parent must exist; a
/// folder already there is used), which throws OutputFileError naming `output` when it cannot
/// and then removes nothing. Never throws otherwise but std::bad_alloc. Not copyable.
class IntermediateFile {
 public:
  IntermediateFile(std::filesystem::path temp, const std::filesystem::path& output,
                   RemoveOnInterrupt::Kind kind = RemoveOnInterrupt::Kind::file);
  IntermediateFile(const IntermediateFile&) = delete;
  IntermediateFile& operator=(const IntermediateFile&) = delete;
  ~IntermediateFile();
  /// The intermediate file's (or folder's) path.
  [[nodiscard]] const std::filesystem::path& path() const { return temp_; }

 private:
  std::filesystem::path temp_;
  RemoveOnInterrupt::Kind kind_;
  TemporaryFor temp_for_;  // released after the destructor removed temp_
};

/// `message` (an error's what()) with the path `temp` at its start replaced by `named`: a writer's
/// refusal of the data, raised about an intermediate file it was given, told of the file the user
/// gave (the output, or the input the data came from). Returned as it is when it does not start
/// with `temp`.
[[nodiscard]] std::string temporary_named_as(std::string message, const std::filesystem::path& temp,
                                             const std::filesystem::path& named);

/// The output `file` is written for: the output of the registered temporary `file` (or of the
/// registered folder `file` lies in), followed through the chain; `file` itself when it is no
/// registered temporary. Paths are compared as spelled (the writers use the registered path).
[[nodiscard]] std::filesystem::path output_of(const std::filesystem::path& file);

/// The error of an operation on `file` (a write, fsync, truncate): OutputFileError
/// "<output_of(file)>: <what>: <strerror(err)>" (no cause when `err` is 0). When `file` is written
/// in another folder than its output (a temporary folder given by the user), the message says so:
/// "<output>: <what> (temporary file in '<folder>'): <cause>", as that folder is the one that is full.
/// Its code() is `err`.
[[nodiscard]] OutputFileError output_error(const std::filesystem::path& file, const std::string& what, int err);

/// Throws OutputFileError unless `path` is absent or a regular file (checked with lstat(2), so a
/// symbolic link is refused rather than followed or replaced), or when its directory does not
/// exist. Called by AtomicFile's constructor; call it directly to check every output of a
/// command before starting long work.
void require_replaceable_output(const std::filesystem::path& path);

/// Throws OptionError naming "temp_dir" ("temp_dir '<dir>': not an existing folder") unless `dir`
/// is empty (beside the output) or an existing folder: a build's temporary files (an index
/// file's sort runs, a COPC output's records file) go there, and a mistyped folder is refused
/// before any long work, named as the option rather than by the hidden file it would have held.
/// The folder is never created.
void require_temp_dir(const std::filesystem::path& dir);

/// The checks a job runs on its outputs before any long work, so that a bad output path fails
/// in a second, not after the computation: each output replaceable (require_replaceable_output),
/// its directory writable by this process (a probe file created with O_EXCL and removed: a
/// read-only directory or mount, and a file system that takes no new files such as procfs even
/// for root, are refused), and none the same file as an input (same device and inode, so another
/// spelling, a hard link or a symbolic link to the input is caught: writing there would replace
/// the input it is read from), and no two outputs at one path (another spelling or a link included).
/// Empty paths are skipped. Throws OutputFileError "<output>: <reason>".
void require_outputs(std::span<const std::filesystem::path> outputs, std::span<const std::filesystem::path> inputs = {});

class AtomicFile;

/// A group of outputs committed all or nothing. While an OutputTransaction is alive on a thread,
/// AtomicFile::commit() on that thread only flushes its temporary and hands it to the
/// transaction; commit() of the transaction renames all of them (in creation order). Destroying
/// the transaction without commit() removes every temporary, leaving all old outputs intact.
/// A transaction constructed while another is active on the thread joins the outer one (its
/// commit() does nothing; the outer commit() renames everything), so library functions that
/// write several files can open one and still compose. Not copyable.
class OutputTransaction {
 public:
  OutputTransaction();
  OutputTransaction(const OutputTransaction&) = delete;
  OutputTransaction& operator=(const OutputTransaction&) = delete;
  ~OutputTransaction();
  /// Renames every finished temporary into place. Throws OutputFileError when a rename fails
  /// (outputs renamed before it stay in place; the rest are removed).
  void commit();
  /// The transaction active on this thread, or nullptr.
  static OutputTransaction* current();

 private:
  friend class AtomicFile;
  struct Pending {
    std::filesystem::path temp, path;
    RemoveOnInterrupt mark;  // the temporary's, handed over by its AtomicFile
  };
  void adopt(std::filesystem::path temp, std::filesystem::path path, RemoveOnInterrupt mark);
  std::vector<Pending> pending_;
  OutputTransaction* outer_ = nullptr;  // non-null: this one joined an outer transaction
};

/// A temporary path "<dir>/.<name>.tmp.<pid>" next to `path`. Write the whole output to temp(),
/// then call commit() to rename it to `path`. If commit() is not reached (an exception, an early
/// return), the destructor removes the temporary, so `path` is either the old file or the complete
/// new one. The constructor applies require_replaceable_output() and creates the temporary
/// exclusively (O_EXCL | O_NOFOLLOW, after removing a stale one of the same name), so writing
/// never follows a planted link. The temporary is marked for removal by the interrupt handler
/// (RemoveOnInterrupt) until it is renamed or removed, or handed to an OutputTransaction, which
/// keeps the mark. Throws OutputFileError.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();
  /// The final path.
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  /// Where to write the data.
  [[nodiscard]] const std::filesystem::path& temp() const { return tmp_; }
  /// Writes `bytes` as the whole content of temp() with checked writes (a short write, ENOSPC or
  /// EIO is an OutputFileError naming path() and the reason) and a checked close. For writers
  /// that encode into memory (images); streaming writers write temp() themselves.
  void write_all(std::span<const unsigned char> bytes);
  /// Flush the finished temporary to disk (fsync, checked: a failure is an OutputFileError and
  /// the old file stays) and move it into place, so that after a crash or power loss `path` holds
  /// the old or the complete new file, never an empty one. A replaced file's permission bits are
  /// kept (a read-only output stays read-only, as `cp` onto an existing file keeps its mode).
  /// Inside an OutputTransaction the rename is deferred to the transaction's commit().
  void commit();

 private:
  std::filesystem::path path_;
  std::filesystem::path tmp_;
  TemporaryFor temp_for_;  // errors about tmp_ name path_; destroyed after the destructor removed tmp_
  bool committed_ = false;
};

}  // namespace rayscan
