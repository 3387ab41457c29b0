// flag_for and option_names (option_names.hpp): the fields whose flag is not "--" + the field name,
// and the flags that have an alias.
#include "option_names.hpp"

#include <array>

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

}  // namespace rayscan::cli
