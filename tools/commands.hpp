// Subcommands of the `rayscan` program (PDAL-style: `rayscan <command> [options]`). Each command
// lives in its own cmd_<name>.cpp and registers itself on the CLI11 app here.
#pragma once

#include <CLI/CLI.hpp>

#include <charconv>
#include <cstdlib>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

namespace rayscan::cli {

/// An error the user caused (bad option, unreadable or malformed file): printed as one line
/// "rayscan <command>: <message>" and exit code 2.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A CLI11 validator for a finite number in [lo, hi] (open at `lo` when lo_open). Rejects nan,
/// inf and out-of-range values with one short line ("expected a finite number > 0, got 'nan'"),
/// where CLI::PositiveNumber would accept nan and print DBL_MAX with 300 digits.
inline CLI::Validator finite_number(double lo, double hi, bool lo_open = false) {
  std::string want = "a finite number";
  const bool has_hi = hi < std::numeric_limits<double>::max();
  auto g = [](double v) {
    std::ostringstream s;
    s << v;
    return s.str();
  };
  const bool has_lo = lo > -std::numeric_limits<double>::max();
  if (has_hi && has_lo) want += std::string(" in ") + (lo_open ? "(" : "[") + g(lo) + ", " + g(hi) + "]";
  else if (has_lo) want += (lo_open ? " > " : " >= ") + g(lo);
  else if (has_hi) want += " <= " + g(hi);
  return CLI::Validator(
      [=](const std::string& s) {
        double v = 0;
        const char* b = s.data();
        const char* e = b + s.size();
        if (b < e && *b == '+') ++b;
        const auto [p, ec] = std::from_chars(b, e, v);
        const bool ok = ec == std::errc() && p == e && std::isfinite(v) && (lo_open ? v > lo : v >= lo) && v <= hi;
        return ok ? std::string() : "expected " + want + ", got '" + s + "'";
      },
      want, "FINITE");
}
/// A CLI11 validator for a whole number in [lo, hi], checked on the text before CLI11 converts it
/// (whose own line for "1.5" is "Could not convert"): "expected an integer >= 1, got '1.5'" (the
/// range in full when `hi` is below the largest long long).
inline CLI::Validator integer_in(long long lo, long long hi = std::numeric_limits<long long>::max()) {
  const std::string want = "an integer " + (hi == std::numeric_limits<long long>::max()
                                                ? ">= " + std::to_string(lo)
                                                : "in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return CLI::Validator(
      [=](const std::string& s) {
        long long v = 0;
        const char* b = s.data();
        const char* e = b + s.size();
        if (b < e && *b == '+') ++b;
        const auto [p, ec] = std::from_chars(b, e, v);
        const bool ok = ec == std::errc() && p == e && v >= lo && v <= hi;
        return ok ? std::string() : "expected " + want + ", got '" + s + "'";
      },
      want, "INT");
}
/// finite_number(-max, max): any finite number.
inline CLI::Validator any_finite() {
  return finite_number(-std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
}
/// finite_number(0, max): a finite number >= 0 (replaces CLI::NonNegativeNumber).
inline CLI::Validator non_negative() { return finite_number(0.0, std::numeric_limits<double>::max()); }
/// finite_number(0, max, open): a finite number > 0 (replaces CLI::PositiveNumber).
inline CLI::Validator positive() { return finite_number(0.0, std::numeric_limits<double>::max(), true); }

/// The value of --radius: a finite number > 0, or "auto" (nullopt: the job chooses the radius from
/// the point spacing). Throws UsageError naming the flag.
inline std::optional<double> parse_radius(const std::string& text) {
  if (text == "auto") return std::nullopt;
  char* end = nullptr;
  const double r = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end || !(r > 0.0) || !std::isfinite(r))
    throw UsageError("--radius '" + text + "': expected a number > 0 or auto");
  return r;
}

/// Registers a subcommand on `app` and returns the callable that runs it after parsing.
/// The callable returns the process exit code (0 success; 1 "failed a check", e.g. compare).
using Runner = std::function<int()>;

Runner add_query_command(CLI::App& app);
Runner add_render_command(CLI::App& app);
Runner add_info_command(CLI::App& app);
Runner add_compare_command(CLI::App& app);
Runner add_visibility_command(CLI::App& app);
Runner add_solar_command(CLI::App& app);
Runner add_db_command(CLI::App& app);
Runner add_index_command(CLI::App& app);
Runner add_translate_command(CLI::App& app);
Runner add_version_command(CLI::App& app);

}  // namespace rayscan::cli
