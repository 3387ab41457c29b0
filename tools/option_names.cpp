// flag_for and option_names (option_names.hpp): the fields whose flag is not "--" + the field name,
// and the flags that have an alias; TypedCommandLine: an option named as the user gave it.
#include "option_names.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cctype>

namespace rayscan::cli {

namespace {

struct Spelling {
  std::string_view command, field, flag;
  std::string_view alias = {};  ///< another flag for the option: the one other commands give the concept
};

// The options structs: jobs::VisibilityJobOptions, jobs::SceneOverrides, jobs::CompareJobOptions,
// jobs::IndexJobOptions with the io::IndexBuildOptions it fills (and its OctreeConfig),
// jobs::TranslateJobOptions, jobs::DbImportJobOptions with the sql::ImportOptions it fills.
constexpr std::array kSpellings{
    Spelling{"visibility", "observers", "--observer"},
    Spelling{"visibility", "observers_file", "--observers"},
    Spelling{"visibility", "sky_rays", "--sky-view", "--sky-rays"},  // (solar --sky-rays)
    Spelling{"visibility", "camera_file", "--from-camera"},
    Spelling{"render", "camera_file", "--camera"},
    Spelling{"render", "colmap_dir", "--colmap"},
    Spelling{"render", "colmap_image", "--image"},
    Spelling{"render", "aovs", "--aov"},
    Spelling{"compare", "channels", "--channel"},
    Spelling{"index", "memory_bytes", "--memory"},
    Spelling{"db", "memory_bytes", "--memory"},
    Spelling{"db", "chunk_size", "--chunk", "--chunk-size"},  // (translate --chunk-size)
    Spelling{"db", "out", "-o"},
    Spelling{"translate", "compression", "--format"},
};

}  // namespace

std::string flag_for(std::string_view command, std::string_view field) {
  for (const Spelling& s : kSpellings)
    if (s.command == command && s.field == field) return std::string(s.flag);
  std::string flag = "--";
  for (char c : field) flag += c == '_' ? '-' : c;
  return flag;
}

std::string option_names(std::string_view command, std::string_view field) {
  std::string names = flag_for(command, field);
  for (const Spelling& s : kSpellings)
    if (s.command == command && s.field == field && !s.alias.empty()) names += "," + std::string(s.alias);
  return names;
}

namespace {

/// The values an option given without one ("--k" rather than "--k=3" or "-k3") takes from the
/// words after it whatever they look like (CLI11's App::_parse_arg); 0 for a flag.
int values_taken(const CLI::Option& o) {
  if (o.get_items_expected_max() == 0) return 0;
  return std::max(0, std::min(o.get_type_size_min(), o.get_items_expected_min()));
}

/// Whether `c` continues an option's name, so that "--lat" does not stand as a word in "--latitude"
/// or in a path "x--lat-o.las" (the QGIS plugin's rule, runner.name_options).
bool name_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-'; }

}  // namespace

TypedCommandLine::TypedCommandLine(const CLI::App& app, int argc, char** argv)
    : command_(&app), path_("rayscan"), next_(1) {
  while (true) {
    const CLI::App* parsed = nullptr;
    for (const CLI::App* sub : command_->get_subcommands({}))
      if (sub->parsed()) parsed = sub;
    if (!parsed) break;
    while (next_ < argc && parsed->get_name() != argv[next_]) ++next_;
    next_ = std::min(next_ + 1, argc);
    if (top_.empty()) top_ = parsed->get_name();
    path_ += " " + parsed->get_name();
    command_ = parsed;
  }
  words_.assign(argv + std::min(next_, argc), argv + argc);
}

std::string TypedCommandLine::given_names(const CLI::Option& option) const {
  std::vector<std::string> given;  // the names of `option` among the words: "--sky-rays", "-o"
  int skip = 0;                    // words still to pass over: the values of the option before
  for (const std::string& word : words_) {
    if (skip > 0) {
      --skip;
      continue;
    }
    if (word == "--") break;  // every word after it is positional
    std::string name, value;
    if (CLI::detail::split_long(word, name, value)) {
      const CLI::Option* o = command_->get_option_no_throw("--" + name);
      if (o == &option) given.push_back("--" + name);
      if (o && value.empty()) skip = values_taken(*o);
      continue;
    }
    // "-qo FILE": flags, then an option that takes a value takes the rest of the word ("-oFILE")
    // or the words after it.
    std::string cluster = word;
    while (CLI::detail::split_short(cluster, name, value)) {
      const CLI::Option* o = command_->get_option_no_throw("-" + name);
      if (!o) break;
      if (o == &option) given.push_back("-" + name);
      if (o->get_items_expected_max() > 0) {
        if (value.empty()) skip = values_taken(*o);
        break;
      }
      cluster = "-" + value;
    }
  }
  // In CLI11's order of the names (short, then long), each once.
  std::string names;
  auto add = [&](const std::string& name) {
    if (std::find(given.begin(), given.end(), name) != given.end()) names += (names.empty() ? "" : "/") + name;
  };
  for (const std::string& s : option.get_snames()) add("-" + s);
  for (const std::string& l : option.get_lnames()) add("--" + l);
  return names;
}

std::string TypedCommandLine::flag(std::string_view field) const {
  const std::string flag = flag_for(top_, field);
  if (const CLI::Option* o = command_->get_option_no_throw(flag))
    if (std::string given = given_names(*o); !given.empty()) return given;
  return flag;
}

std::string TypedCommandLine::message(std::string what) const {
  for (const CLI::Option* o : command_->get_options()) {
    const std::string name = o->get_name(), given = given_names(*o);
    if (name.empty() || given.empty() || given == name) continue;
    for (std::size_t at = what.find(name); at != std::string::npos; at = what.find(name, at)) {
      const std::size_t end = at + name.size();
      if ((at > 0 && name_char(what[at - 1])) || (end < what.size() && name_char(what[end]))) {
        at = end;
        continue;
      }
      what.replace(at, name.size(), given);
      at += given.size();
    }
  }
  return what;
}

}  // namespace rayscan::cli
