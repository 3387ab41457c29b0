// libFuzzer target for the COPC info VLR and hierarchy walk (cycles, offsets, keys) followed by
// decoding every node's chunk: FormatError or success, nothing else. Built by run.sh.
#include "rayscan/site/copc.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"

#include <cstddef>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const rayscan::io::CopcInfo c = rayscan::io::read_copc_info({data, size}, "fuzz-input");
    (void)c;
    (void)rayscan::io::read_las_records({data, size}, "fuzz-input", rayscan::io::las_layers::z);
  } catch (const rayscan::io::FormatError&) {
  }
  return 0;
}
