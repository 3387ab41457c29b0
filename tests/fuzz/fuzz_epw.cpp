// libFuzzer target for the EnergyPlus weather (EPW) reader: any input must either read into an
// EpwFile or raise std::runtime_error (the reader's one-line error); anything else (crash, ASan
// report, other exception) is a bug. Built and run by tests/fuzz/run.sh.
#include "rayscan/analysis/epw.hpp"

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const rayscan::analysis::EpwFile f = rayscan::analysis::parse_epw(in, "fuzz-input");
    if (f.records.empty()) __builtin_trap();  // the reader promises at least one record
  } catch (const std::runtime_error&) {
  }
  return 0;
}
