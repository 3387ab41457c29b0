// The index job (rayscan/jobs/index.hpp): options checked, then the out-of-core build.
#include "rayscan/jobs/index.hpp"
#include "copc_output.hpp"

#include "rayscan/base/ascii_case.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/byte_size.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/base/threads.hpp"
#include "rayscan/io/point_io.hpp"

#include <tbb/task_arena.h>

#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <utility>

namespace rayscan::jobs {

namespace {

/// The memory budget of either output, parsed (detail::memory_budget).
std::uint64_t memory_bytes(const IndexJobOptions& o) { return detail::memory_budget(o.memory); }

/// The attribute list parsed. A name that is not one an index stores (io::kIndexAttributes), nor
/// all or none, written as listed (lower case, as every name from a list of the command line), is
/// an OptionError naming "attributes" that lists only those; "all" inside a list is
/// AttributeSet::parse's (every attribute a reader knows), which the build refuses.
io::AttributeSet index_attributes(const std::string& list) {
  // "all" alone means every attribute an index stores.
  if (list == "all") return io::kIndexAttributes;
  std::string names;  // "id, rgb, ..." from the one set
  const std::string stored = io::kIndexAttributes.to_string();
  for (const char c : stored) names += c == ',' ? std::string(", ") : std::string(1, c);
  std::size_t at = 0;
  while (at <= list.size()) {
    const std::size_t end = std::min(list.find(',', at), list.size());
    const std::string word = list.substr(at, end - at);
    at = end + 1;
    bool ok = true;
    try {
      const io::AttributeSet one = io::AttributeSet::parse(word);
      ok = word == ascii_lower(word) && (word == "all" || (one & io::kIndexAttributes) == one);
    } catch (const std::invalid_argument&) {
      ok = false;
    }
    if (!ok)
      throw OptionError({option("attributes"), " '" + one_line(word) + "': expected " + names + ", all or none"});
  }
  return io::AttributeSet::parse(list);
}

/// The build's options from the job's: the memory budget and attribute list parsed, the output
/// name checked. Throws as run_index() for these options.
io::IndexBuildOptions index_build_options(const IndexJobOptions& o) {
  io::IndexBuildOptions b;
  b.config = o.config;
  b.memory_bytes = memory_bytes(o);
  b.attributes = index_attributes(o.attributes);
  b.compact_positions = o.compact_positions;
  if (!io::is_index_file(o.output))
    throw OptionError({o.output.string() + ": the index file name must end in .rsi (or .copc.laz for a COPC file)"});
  b.temp_dir = o.temp_dir;
  b.progress = o.progress;
  return b;
}

/// Throws OptionError when two inputs are the same file (same device and inode, as
/// require_outputs compares: "a.las" and "./a.las", a symbolic or hard link to it): its points
/// would be indexed twice, each copy with its own ids. An input that cannot be stat'ed is left to
/// its reader's error.
void require_distinct_inputs(const std::vector<std::filesystem::path>& inputs) {
  std::map<std::pair<dev_t, ino_t>, std::size_t> seen;
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    struct stat st {};
    if (::stat(inputs[i].c_str(), &st) != 0) continue;
    const auto [it, fresh] = seen.emplace(std::pair{st.st_dev, st.st_ino}, i);
    if (!fresh)
      throw OptionError({one_line(inputs[i].string()) + ": the same file as input " + std::to_string(it->second + 1) +
                         " ('" + one_line(inputs[it->second].string()) + "'): give each input file once"});
  }
}

}  // namespace

IndexJobResult run_index(const IndexJobOptions& options) {
  if (io::is_copc_output(options.output)) {
    if (options.inputs.size() != 1)
      throw OptionError({options.output.string() + ": a COPC output is written from one input file (got " +
                         std::to_string(options.inputs.size()) + ")"});
    memory_bytes(options);
    require_temp_dir(options.temp_dir);
    const std::filesystem::path out[] = {options.output};
    require_outputs(out, options.inputs);
    IndexJobResult result;
    result.output = options.output;
    result.copc = detail::write_copc_output(options.inputs[0], options.output, options.memory, options.temp_dir,
                                            options.progress, options.control.threads);
    return result;
  }
  require_distinct_inputs(options.inputs);
  const io::IndexBuildOptions build = index_build_options(options);
  const std::filesystem::path out[] = {options.output};
  require_outputs(out, options.inputs);
  IndexJobResult result;
  result.output = options.output;
  tbb::task_arena arena(static_cast<int>(resolve_threads(options.control.threads)));
  arena.execute([&] { result.stats = io::build_index_file(options.inputs, options.output, build); });
  return result;
}

}  // namespace rayscan::jobs
