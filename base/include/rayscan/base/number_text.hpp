// Numbers as text for reports and messages: the shortest decimal that reads back as the same
// double (std::to_chars), so a value printed and parsed again is bit-identical, and a value that
// came from decimal text (636500.92) prints as it was written, not as 636500.92000000004.
#pragma once

#include <charconv>
#include <string>

namespace rayscan {

/// `v` as the shortest decimal text that round-trips to `v` (std::to_chars without a precision:
/// "636500.92", "0.00025", "1e+300", "-inf", "nan").
[[nodiscard]] inline std::string shortest_text(double v) {
  char buf[32];  // the longest shortest form of a double is 24 characters ("-2.2250738585072014e-308")
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, end) : std::string();
}

}  // namespace rayscan
