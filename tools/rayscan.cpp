// The `rayscan` command line: one program, PDAL-style subcommands.
#include "atomic_file.hpp"
#include "commands.hpp"
#include "option_names.hpp"
#include "processes.hpp"
#include "rayscan/base/option_error.hpp"

#include "rayscan/base/input_file.hpp"
#include "rayscan/base/interrupt.hpp"
#include "rayscan/base/list_text.hpp"
#include "rayscan/base/version.hpp"
#include "rayscan/octree/simd.hpp"

#include <cstdio>
#include <exception>
#include <iostream>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#ifdef RAYSCAN_HAVE_MPI
#include "rayscan/mpi/session.hpp"
namespace rayscan::cli {
extern mpi::Session* g_session;
}
#endif

namespace {

// One process: print the line, exit 2. Under MPI: the root prints one line and every rank ends
// (rayscan::mpi::Session::fail; does not return).
int fail(const std::string& line) {
#ifdef RAYSCAN_HAVE_MPI
  if (rayscan::cli::g_session) {
    rayscan::cli::g_session->fail(line);
    return 2;
  }
#endif
  std::cerr << line << "\n";
  return 2;
}

// `code`, or 2 with one line when the help or version text just printed could not be written
// (rayscan --help > /dev/full). Under MPI only rank 0 prints, so only it can fail here; no abort
// is needed, as no rank goes on to work.
int output_checked(int code) {
  try {
    rayscan::cli::check_standard_output();
  } catch (const std::exception& e) {
    std::cerr << "rayscan: " << e.what() << "\n";
    return 2;
  }
  return code;
}

// After a failed parse: when the command line stops at a command that needs a subcommand (the
// program itself, `db`) and the next word is not an option, the one line naming that word and the
// commands there are: "rayscan: unknown command 'visibilty' (expected render, visibility, ...)".
// Else "" (CLI11's own message stands).
std::string unknown_command(const rayscan::cli::TypedCommandLine& line, int argc, char** argv) {
  const CLI::App* at = &line.command();
  const std::string& where = line.path();
  const int next = line.next();  // the argument after the last command parsed
  if (at->get_require_subcommand_min() == 0 || next >= argc || argv[next][0] == '-') return "";
  std::vector<std::string> names;
  for (const CLI::App* sub : at->get_subcommands({})) names.push_back(sub->get_name());
  return where + ": unknown command '" + rayscan::one_line(argv[next]) + "' (expected " +
         rayscan::join_alternatives(names) + ")";
}

}  // namespace

int main(int argc, char** argv) {
#ifdef RAYSCAN_HAVE_MPI
  // Under mpirun (and only then) MPI is initialised; without a launcher this is one process.
  std::optional<rayscan::mpi::Session> session;
  try {
    session.emplace(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "rayscan: " << rayscan::one_line(e.what()) << "\n";
    return 2;
  }
  rayscan::cli::g_session = &*session;
#endif
  // SIGINT, SIGTERM and SIGHUP remove every command's temporary files before they end it (the
  // program's, not the library's: the Python module leaves its host's signals alone).
  rayscan::install_interrupt_handler();
  CLI::App app{"rayscan: ray queries, rendering and analysis of raw point clouds "
               "(after Teuscher et al., \"Ray Queries On Raw Point Clouds\")"};
  app.require_subcommand(1);
  app.set_version_flag("--version", rayscan::software_name() + ", " + rayscan::simd_description());

  std::vector<std::pair<CLI::App*, rayscan::cli::Runner>> commands;
  auto reg = [&](rayscan::cli::Runner (*add)(CLI::App&)) {
    const std::size_t before = app.get_subcommands({}).size();
    rayscan::cli::Runner run = add(app);
    commands.emplace_back(app.get_subcommands({})[before], std::move(run));
  };
  // In the order of docs/cli.md's table: --help lists them so, and so does a mistyped command's line.
  reg(rayscan::cli::add_render_command);
  reg(rayscan::cli::add_visibility_command);
  reg(rayscan::cli::add_solar_command);
  reg(rayscan::cli::add_query_command);
  reg(rayscan::cli::add_index_command);
  reg(rayscan::cli::add_info_command);
  reg(rayscan::cli::add_translate_command);
  reg(rayscan::cli::add_compare_command);
  reg(rayscan::cli::add_db_command);
  reg(rayscan::cli::add_version_command);

  // The outcome of parsing: go on, or end now (--help, --version: exit 0; a usage error: exit 2).
  // Under mpirun every rank parses; only rank 0 prints (Session::agree_on_start).
  bool end = false;
  int end_code = 0;
  std::string end_out, end_err;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    end = true;
    if (e.get_exit_code() == 0) {  // --help, --version
      std::ostringstream out, err;
      end_code = app.exit(e, out, err);
      end_out = out.str() + err.str();
    } else {
      // One line, "rayscan <command>: <message>" like every other error.
      std::string where = "rayscan";
      for (auto& [sub, run] : commands)
        if (sub->parsed()) where += " " + sub->get_name();
      end_code = 2;
      // An option is named as it was given (TypedCommandLine), not by CLI11's first name for it.
      const rayscan::cli::TypedCommandLine line(app, argc, argv);
      const std::string unknown = unknown_command(line, argc, argv);
      end_err = !unknown.empty() ? unknown : where + ": " + rayscan::one_line(line.message(e.what())) + " (see --help)";
    }
  }
#ifdef RAYSCAN_HAVE_MPI
  if (const std::optional<int> code = session->agree_on_start({end, end_code, end_out, end_err}))
    return output_checked(*code);
#else
  if (end) {
    std::cout << end_out << std::flush;
    if (!end_err.empty()) std::cerr << end_err << "\n";
    return output_checked(end_code);
  }
#endif
  const rayscan::cli::TypedCommandLine typed(app, argc, argv);
  for (auto& [sub, run] : commands) {
    if (!sub->parsed()) continue;
    try {
      rayscan::cli::set_command_name("rayscan " + sub->get_name());
      const int code = run();
      rayscan::cli::check_standard_output();  // (a command's report lost on a full disk is a failure)
#ifdef RAYSCAN_HAVE_MPI
      session->finish();
#endif
      return code;
    } catch (const std::exception& e) {
      // One line per error: control characters in paths or values are escaped. An option the
      // library names by its field is printed as this command's flag, spelled as it was given.
      const std::string name = sub->get_name();
      const auto* option_error = dynamic_cast<const rayscan::OptionError*>(&e);
      // An allocation that failed (std::bad_alloc from any step of the job) says so in words.
      const std::string message =
          option_error ? option_error->spelled([&](std::string_view f) { return typed.flag(f); })
          : dynamic_cast<const std::bad_alloc*>(&e) ? "out of memory (" + std::string(e.what()) + ")"
                                                  : std::string(e.what());
      return fail("rayscan " + name + ": " + rayscan::one_line(message));
    }
  }
  return 2;
}
