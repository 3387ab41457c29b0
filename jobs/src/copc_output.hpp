// The COPC output of `translate` and `index` (a .copc.laz name, io::is_copc_output): one call so
// that both commands parse the budget and run the writer the same way. Private to rayscan::jobs.
#pragma once

#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/site/copc_writer.hpp"

#include <tbb/task_arena.h>

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

namespace rayscan::jobs::detail {

/// The memory budget `memory` of a build (byte-size text such as "4G", parse_byte_size), in
/// bytes; an OptionError naming "memory" for a malformed one.
inline std::uint64_t memory_budget(const std::string& memory) {
  try {
    return parse_byte_size(memory);
  } catch (const std::invalid_argument& e) {
    throw OptionError({option("memory"), std::string(": ") + e.what()});
  }
}


/// Writes the cloud file `in` as COPC 1.0 `out` (io::write_copc) within the memory budget
/// `memory` (byte-size text such as "4G", parse_byte_size), temporary records in `temp_dir`
/// (empty: the output's folder), reporting to `progress`, on `threads` threads (0 = all).
/// Throws OptionError naming "memory" (memory_budget) and what io::write_copc throws.
inline io::CopcWriteResult write_copc_output(const std::filesystem::path& in, const std::filesystem::path& out,
                                             const std::string& memory, const std::filesystem::path& temp_dir,
                                             const decltype(io::CopcWriteOptions::progress)& progress,
                                             unsigned threads) {
  io::CopcWriteOptions c;
  c.memory_bytes = memory_budget(memory);
  c.temp_dir = temp_dir;
  c.progress = progress;
  io::CopcWriteResult r;
  tbb::task_arena arena(static_cast<int>(resolve_threads(threads)));
  arena.execute([&] { r = io::write_copc(in, out, c); });
  return r;
}

}  // namespace rayscan::jobs::detail
