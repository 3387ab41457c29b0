// Helpers of the job tests: the data files, a scratch folder, and the option fields an
// OptionError names.
#pragma once

#include "../common/run_command.hpp"
#include "../common/temp_dir.hpp"
#include "rayscan/base/option_error.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <variant>
#include <vector>

namespace rayscan::test {

/// A file of tests/data (e.g. "las/simple1_3.las").
inline std::filesystem::path data_file(const std::string& rel) { return std::filesystem::path(RAYSCAN_TEST_DATA) / rel; }

/// Runs `rayscan ARGS` (the build's program) and returns its exit code and its stdout and stderr.
inline CommandResult rayscan_cli(const std::string& args) { return run_command(quoted(RAYSCAN_BIN) + " " + args); }

/// This test process's scratch folder.
inline std::filesystem::path temp_dir() { return process_temp_dir("rayscan_jobs_tests"); }

/// The bytes of a file.
inline std::string file_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The options fields an OptionError names, in order.
inline std::vector<std::string> option_fields(const OptionError& e) {
  std::vector<std::string> fields;
  for (const OptionError::Part& p : e.parts())
    if (const auto* n = std::get_if<OptionName>(&p)) fields.push_back(n->field);
  return fields;
}

/// Calls f and returns the fields named by the OptionError it throws; fails the test when it
/// throws nothing or another exception.
template <class F>
std::vector<std::string> fields_of_option_error(F&& f) {
  try {
    f();
  } catch (const OptionError& e) {
    return option_fields(e);
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected an OptionError, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected an OptionError, nothing was thrown";
  return {};
}

}  // namespace rayscan::test
