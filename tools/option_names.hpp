// The command line's spelling of the jobs' option fields: an OptionError names a field of a
// job's options struct (library term), the CLI prints the flag that sets it.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace rayscan::cli {

/// The flag of subcommand `command` ("render", "visibility", ...) that sets the job option
/// `field`: the exceptions listed in option_names.cpp, else "--" + field with '_' written as '-'
/// (`raster_value` -> `--raster-value`).
std::string flag_for(std::string_view command, std::string_view field);

/// The names CLI11 registers for that option: flag_for's flag, then the alias the table in
/// option_names.cpp gives it, if any, so that one concept has one name across the commands
/// (`visibility --sky-view` also takes `solar`'s `--sky-rays`): "--sky-view,--sky-rays".
std::string option_names(std::string_view command, std::string_view field);

/// The command line as the user typed it, so that a message names an option by the spelling given:
/// CLI11 keeps an option's values but not the name each came with, and names the option by its
/// first long name (`visibility --sky-rays abc`: "--sky-view: expected ..."). Made from `argv`
/// after `app` parsed it or refused it; the words are classified by CLI11's own rules (a long
/// option with or without "=value", short options grouped, nothing after "--").
class TypedCommandLine {
 public:
  TypedCommandLine(const CLI::App& app, int argc, char** argv);

  /// The innermost command that parsed (`rayscan db import ...`: import; `app` when none did).
  [[nodiscard]] const CLI::App& command() const { return *command_; }
  /// "rayscan" and the names of the commands that parsed: "rayscan db import".
  [[nodiscard]] const std::string& path() const { return path_; }
  /// The index in argv of the first word after the innermost command's name (argc when none).
  [[nodiscard]] int next() const { return next_; }

  /// The names of `option` (one of command()'s) that the words after the command give it, in the
  /// order CLI11 lists them, joined by '/': "--sky-rays", "--sky-view/--sky-rays" when both were
  /// given, "-o" or "--out"; "" when it was not given.
  [[nodiscard]] std::string given_names(const CLI::Option& option) const;

  /// The flag that sets job option `field` (an OptionError's field), as given: given_names() of
  /// the option flag_for(top command, field) names, or that flag when it was not given.
  [[nodiscard]] std::string flag(std::string_view field) const;

  /// CLI11's refusal `what` with the option it names written as given: each of command()'s options
  /// given under another name than CLI11's own (Option::get_name()) is renamed where that name
  /// stands as a whole word ("--sky-view: expected an integer ..., got 'abc'" after --sky-rays abc
  /// reads "--sky-rays: expected ...").
  [[nodiscard]] std::string message(std::string what) const;

 private:
  const CLI::App* command_;
  std::string top_;   ///< the first command's name, flag_for's key ("db" for db import)
  std::string path_;  ///< path()
  int next_ = 0;      ///< next()
  std::vector<std::string> words_;  ///< argv from next()
};

}  // namespace rayscan::cli
