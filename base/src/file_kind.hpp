// Private helper of the input and output file policies (input_file.cpp, atomic_file.cpp).
#pragma once

#include <sys/stat.h>

#include <string>

namespace rayscan::detail {

/// Words for a file type that is not a regular file, for one-line errors ("a FIFO", ...); the
/// st_mode of lstat()/fstat() (POSIX.1-2017 <sys/stat.h> S_IS* macros).
inline std::string file_kind_name(mode_t m) {
  if (S_ISLNK(m)) return "a symbolic link";
  if (S_ISDIR(m)) return "a directory";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  return "not a regular file";
}

}  // namespace rayscan::detail
