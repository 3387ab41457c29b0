// libFuzzer target for the LAZ decoder (LASzip VLR, chunk table, v2 and v3 items): any input must
// either decode or raise rayscan::io::FormatError; anything else is a bug. Built by run.sh.
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)rayscan::io::read_las_records({data, size}, "fuzz-input");
  } catch (const rayscan::io::FormatError&) {
  }
  return 0;
}
