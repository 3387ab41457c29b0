// Numbers as text for reports and messages: the shortest decimal that reads back as the same
// double (std::to_chars), so a value printed and parsed again is bit-identical, and a value that
// came from decimal text (636500.92) prints as it was written, not as 636500.92000000004. Counts
// with their noun, singular for one ("1 ray", "2 rays").
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>

namespace rayscan {

/// `v` as the shortest decimal text that round-trips to `v` (std::to_chars without a precision:
/// "636500.92", "0.00025", "1e+300", "-inf", "nan").
[[nodiscard]] inline std::string shortest_text(double v) {
  char buf[32];  // the longest shortest form of a double is 24 characters ("-2.2250738585072014e-308")
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, end) : std::string();
}

/// Decimals of the grid step `step` written shortest in fixed notation (0.00025 -> 5, 0.01 -> 2,
/// 1 -> 0, 0.5 -> 1): the digits that show every multiple of the step exactly, as lasinfo prints a
/// LAS file's coordinates to its scale. -1 for a step that is not a short decimal (1/3: more than
/// 12 decimals), not finite or not > 0.
[[nodiscard]] inline int step_decimals(double step) {
  if (!(step > 0) || !std::isfinite(step)) return -1;
  char buf[400];  // fixed notation of the largest double is 309 digits
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, step, std::chars_format::fixed);
  if (ec != std::errc()) return -1;
  const std::string_view t(buf, static_cast<std::size_t>(end - buf));
  const std::size_t dot = t.find('.');
  const int dec = dot == std::string_view::npos ? 0 : static_cast<int>(t.size() - dot - 1);
  return dec <= 12 ? dec : -1;
}

/// `n` and the noun `one`, in the plural unless `n` is 1: count_text(1, "ray") is "1 ray",
/// count_text(0, "ray") "0 rays". The plural appends "s": for nouns that form it so (ray, point,
/// result, thread, node), not for others (a "process" would read "processs").
[[nodiscard]] inline std::string count_text(std::uint64_t n, std::string_view one) {
  std::string s = std::to_string(n);
  s += ' ';
  s += one;
  if (n != 1) s += 's';
  return s;
}

}  // namespace rayscan
