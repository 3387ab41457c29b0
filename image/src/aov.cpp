#include "rayscan/image/aov.hpp"

#include "rayscan/base/list_text.hpp"

#include <vector>

namespace rayscan {

const std::vector<Aov>& all_aovs() {
  static const std::vector<Aov> v{Aov::depth, Aov::normal, Aov::position, Aov::index, Aov::albedo, Aov::cost};
  return v;
}

const char* to_string(Aov aov) {
  switch (aov) {
    case Aov::depth: return "depth";
    case Aov::normal: return "normal";
    case Aov::position: return "position";
    case Aov::index: return "index";
    case Aov::albedo: return "albedo";
    case Aov::cost: return "cost";
  }
  return "?";
}

std::optional<Aov> parse_aov(std::string_view name) {
  for (Aov a : all_aovs())
    if (name == to_string(a)) return a;
  return std::nullopt;
}

std::string aov_names_expected() {
  std::vector<const char*> names;
  for (Aov a : all_aovs()) names.push_back(to_string(a));
  return "expected " + join_alternatives(names);
}

const std::vector<std::string>& aov_channels(Aov aov) {
  static const std::vector<std::string> depth{"Z"}, normal{"N.X", "N.Y", "N.Z"}, position{"P.X", "P.Y", "P.Z"},
      index{"id"}, albedo{"albedo.R", "albedo.G", "albedo.B"}, cost{"cost"};
  switch (aov) {
    case Aov::depth: return depth;
    case Aov::normal: return normal;
    case Aov::position: return position;
    case Aov::index: return index;
    case Aov::albedo: return albedo;
    case Aov::cost: return cost;
  }
  return cost;
}

}  // namespace rayscan
