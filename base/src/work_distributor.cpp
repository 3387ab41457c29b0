// Byte helpers of the work-distribution hook (rayscan/base/work_distributor.hpp).
#include "rayscan/base/work_distributor.hpp"

#include <cstring>
#include <stdexcept>
#include <string>

namespace rayscan {

void read_bytes(std::span<const std::byte> bytes, std::size_t& offset, std::span<std::byte> values) {
  if (offset > bytes.size() || bytes.size() - offset < values.size())
    throw std::runtime_error("work result message: " + std::to_string(bytes.size()) + " bytes, expected at least " +
                             std::to_string(offset + values.size()));
  if (!values.empty()) std::memcpy(values.data(), bytes.data() + offset, values.size());
  offset += values.size();
}

}  // namespace rayscan
