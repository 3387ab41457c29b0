// Subcommands of the `rayscan` program (PDAL-style: `rayscan <command> [options]`). Each command
// lives in its own cmd_<name>.cpp and registers itself on the CLI11 app here.
#pragma once

#include "rayscan/base/list_text.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"
#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/spacing.hpp"

#include <CLI/CLI.hpp>

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <initializer_list>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

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
namespace detail {

/// The validator of integer_in and random_seed: a whole number of type T in [lo, hi], written in
/// decimal with an optional '+', rewritten as std::to_string of its value ("010" -> "10") so that
/// CLI11, which converts with strtoull(..., 0), reads no octal or hexadecimal in it.
template <class T>
CLI::Validator decimal_integer(T lo, T hi, const std::string& want, const std::string& name) {
  return CLI::Validator(
      [=](std::string& s) {
        T v{};
        const char* b = s.data();
        const char* e = b + s.size();
        if (b < e && *b == '+') ++b;
        const auto [p, ec] = std::from_chars(b, e, v);
        if (ec != std::errc() || p != e || !(lo <= v && v <= hi)) return "expected " + want + ", got '" + s + "'";
        s = std::to_string(v);
        return std::string();
      },
      want, name);
}

}  // namespace detail

/// A CLI11 validator for a name from a list, the one check of every option that takes one
/// (--layout, --index, --primitive, --format, --aov, ...): the value must be one of `names`
/// (std::string, std::string_view or const char*), exactly as listed. Refuses with one line in the
/// words of the project's other lists (join_alternatives): "expected adaptive or fixed, got
/// 'layered'", where CLI::IsMember's is "layered not in {adaptive,fixed}". --help shows the names
/// as IsMember does ("TEXT:{adaptive,fixed}"), in the order given.
template <class Names = std::initializer_list<std::string_view>>
CLI::Validator one_of(const Names& names) {
  std::vector<std::string> list;
  for (const auto& n : names) list.emplace_back(n);
  std::string set = "{";
  for (const std::string& n : list) set += (set.size() > 1 ? "," : "") + n;
  set += "}";
  const std::string want = "expected " + join_alternatives(list);
  return CLI::Validator(
      [list, want](const std::string& s) {
        for (const std::string& n : list)
          if (s == n) return std::string();
        return want + ", got '" + s + "'";
      },
      set, "ONE_OF");
}

/// The names --primitive takes (render, visibility, solar), in the order --help lists them: the
/// geometry each point stands for (render::Primitive, the jobs' `primitive`).
inline constexpr std::array<std::string_view, 2> kPrimitiveNames = {"sphere", "surfel"};

/// A CLI11 validator for a whole number in [lo, hi], read in decimal: "expected an integer >= 1,
/// got '1.5'" (the range in full when `hi` is below the largest long long), where CLI11's own line
/// is "Could not convert". Give it with ->transform(), not ->check(): it rewrites the text in
/// plain decimal before CLI11 converts it, which would read "010" as octal 8 and refuse "08".
inline CLI::Validator integer_in(long long lo, long long hi = std::numeric_limits<long long>::max()) {
  const std::string want = "an integer " + (hi == std::numeric_limits<long long>::max()
                                                ? ">= " + std::to_string(lo)
                                                : "in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return detail::decimal_integer(lo, hi, want, "INT");
}
/// A CLI11 validator for a random seed (--seed): an unsigned 64-bit integer in decimal, where
/// CLI11 alone would wrap "-1" to 2^64-1 and read "010" as octal. Give it with ->transform(), as
/// integer_in.
inline CLI::Validator random_seed() {
  return detail::decimal_integer<std::uint64_t>(0, std::numeric_limits<std::uint64_t>::max(),
                                                "an unsigned 64-bit integer", "UINT64");
}
/// The largest --threads N (a count above the cores runs on all of them).
inline constexpr long long kMaxThreadsOption = 1024;
/// Adds --threads N to `c` for `threads` (JobControl::threads): 0..kMaxThreadsOption, 0 (the
/// default) = all cores. `identical` ends the help text: what is the same for any count ("the
/// image is identical for any count").
inline CLI::Option* add_threads_option(CLI::App& c, unsigned& threads, const std::string& identical) {
  return c
      .add_option("--threads", threads,
                  "Worker threads, 0 = all cores (default 0); a count above the cores runs on all of them (the log "
                  "says how many); " + identical)
      ->transform(integer_in(0, kMaxThreadsOption));
}
/// Adds --index TYPE to `c` for `type` (IndexOptions::type, whose value is the default): one of
/// kIndexTypes, refused when the options are parsed, before a cloud is read.
inline CLI::Option* add_index_option(CLI::App& c, std::string& type) {
  return c
      .add_option("--index", type,
                  "Index built over a cloud read into memory (ignored for an index file, .rsi, and a COPC file "
                  "queried in place: their own octree)")
      ->check(one_of(kIndexTypes))
      ->capture_default_str();
}
/// finite_number(-max, max): any finite number.
inline CLI::Validator any_finite() {
  return finite_number(-std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
}
/// finite_number(0, max): a finite number >= 0 (replaces CLI::NonNegativeNumber).
inline CLI::Validator non_negative() { return finite_number(0.0, std::numeric_limits<double>::max()); }
/// finite_number(0, max, open): a finite number > 0 (replaces CLI::PositiveNumber).
inline CLI::Validator positive() { return finite_number(0.0, std::numeric_limits<double>::max(), true); }

/// The value of --radius: "auto" (nullopt: the job chooses the radius from the point spacing) or a
/// number sphere_radius_problem accepts. Otherwise throws the OptionError the job throws for that
/// number ("radius: expected a finite number > 0 (world units) or auto, got -1", the field printed
/// as the flag); text that is no number is shown quoted ("got 'abc'").
inline std::optional<double> parse_radius(const std::string& text) {
  if (text == "auto") return std::nullopt;
  char* end = nullptr;
  const double r = std::strtod(text.c_str(), &end);
  const bool number = end != text.c_str() && *end == '\0';
  if (const std::string why = sphere_radius_problem(number ? r : std::nan("")); !why.empty())
    throw OptionError({option("radius"), ": " + why + ", got " + (number ? shortest_text(r) : "'" + text + "'")});
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
