// The command line's spelling of the jobs' option fields: an OptionError names a field of a
// job's options struct (library term), the CLI prints the flag that sets it.
#pragma once

#include <string>
#include <string_view>

namespace rayscan::cli {

/// The flag of subcommand `command` ("render", "visibility", ...) that sets the job option
/// `field`: the exceptions listed in option_names.cpp, else "--" + field with '_' written as '-'
/// (`raster_value` -> `--raster-value`).
std::string flag_for(std::string_view command, std::string_view field);

/// The names CLI11 registers for that option: flag_for's flag, then the alias the table in
/// option_names.cpp gives it, if any, so that one concept has one name across the commands
/// (`visibility --sky-view` also takes `solar`'s `--sky-rays`): "--sky-view,--sky-rays".
std::string option_names(std::string_view command, std::string_view field);

}  // namespace rayscan::cli
