// Subcommands of the `rayscan` program (PDAL-style: `rayscan <command> [options]`). Each command
// lives in its own cmd_<name>.cpp and registers itself on the CLI11 app here.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <stdexcept>
#include <string>

namespace rayscan::cli {

/// An error the user caused (bad option, unreadable or malformed file): printed as one line
/// "rayscan <command>: <message>" and exit code 2.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Registers a subcommand on `app` and returns the callable that runs it after parsing.
/// The callable returns the process exit code (0 success; 1 "failed a check", e.g. compare).
using Runner = std::function<int()>;

Runner add_query_command(CLI::App& app);
Runner add_render_command(CLI::App& app);
Runner add_info_command(CLI::App& app);
Runner add_compare_command(CLI::App& app);
Runner add_visibility_command(CLI::App& app);
Runner add_index_command(CLI::App& app);
Runner add_translate_command(CLI::App& app);

}  // namespace rayscan::cli
