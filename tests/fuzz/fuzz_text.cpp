// libFuzzer target for the text reader: any input must either read into a valid PointCloud or
// raise rayscan::io::FormatError; anything else (crash, ASan report, other exception) is a bug.
// Built and run by tests/fuzz/run.sh.
#include "rayscan/io/point_io.hpp"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rayscan::io::FileInfo info;
  try {
    const rayscan::PointCloud pc =
        rayscan::io::read_point_cloud({data, size}, rayscan::io::Format::text, "fuzz-input", {}, &info);
    pc.validate();  // throws std::invalid_argument (uncaught: reported) on an inconsistent cloud
  } catch (const rayscan::io::FormatError&) {
  }
  return 0;
}
