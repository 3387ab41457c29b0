#include "rayscan/base/byte_size.hpp"

#include "rayscan/base/ascii_case.hpp"

#include <cmath>
#include <stdexcept>
#include <string_view>

namespace rayscan {

std::uint64_t parse_byte_size(const std::string& text) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = ascii_lower(std::string_view(text).substr(used));
  if (unit.size() >= 2 && unit.substr(unit.size() - 2) == "ib") unit.resize(unit.size() - 2);
  else if (!unit.empty() && unit.back() == 'b') unit.pop_back();
  double mul = 0;
  if (unit.empty()) mul = 1;
  else if (unit == "k") mul = 1024.0;
  else if (unit == "m") mul = 1024.0 * 1024;
  else if (unit == "g") mul = 1024.0 * 1024 * 1024;
  else if (unit == "t") mul = 1024.0 * 1024 * 1024 * 1024;
  if (used == 0 || mul == 0 || !(v > 0) || !std::isfinite(v) || v * mul > 1e18)
    throw std::invalid_argument("size '" + text + "': expected a positive number with an optional K, M, G or T suffix");
  return static_cast<std::uint64_t>(v * mul);
}

}  // namespace rayscan
