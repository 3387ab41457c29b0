// The benchmark programs' command lines (CLI11) with the rayscan program's conventions: --help
// prints the options and exits 0; a usage error (an unknown option, a value that is not a number,
// a missing argument) prints one line "PROGRAM: message (see --help)" and exits 2.
#pragma once

#include "rayscan/base/input_file.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace rayscan::bench {

/// Parses argv into `app` and returns when the program is to run; exits 0 after --help and 2
/// after a usage error (one line on stderr, named by the program's file name).
inline void parse_or_exit(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) std::exit(app.exit(e));  // --help
    const std::string msg = one_line(e.what());  // (as the rayscan program's usage errors)
    const std::string& name = app.get_name();  // (argv[0] unless the app was given a name)
    std::fprintf(stderr, "%s: %s (see --help)\n", name.substr(name.find_last_of('/') + 1).c_str(), msg.c_str());
    std::exit(2);
  }
}

}  // namespace rayscan::bench
