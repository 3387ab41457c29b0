#include "rayscan/octree/any_index.hpp"

#include "rayscan/base/list_text.hpp"
#include "rayscan/base/option_error.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <utility>

namespace rayscan {

namespace {

/// What an octree's index type puts before its layout's name (octree_index_type).
constexpr std::string_view kOctreePrefix = "octree-";

}  // namespace

std::string octree_index_type(OctreeLayout layout) { return std::string(kOctreePrefix) + to_string(layout); }

std::optional<OctreeLayout> octree_layout_of(std::string_view type) {
  if (!type.starts_with(kOctreePrefix)) return std::nullopt;
  type.remove_prefix(kOctreePrefix.size());
  return parse_octree_layout(std::string(type));
}

const char* to_string(IndexOption o) {
  switch (o) {
    case IndexOption::capacity: return "capacity";
    case IndexOption::max_depth: return "max_depth";
    case IndexOption::depth: return "depth";
    case IndexOption::insertion: return "insertion";
  }
  return "?";
}

bool index_option_applies(std::string_view type, IndexOption o) {
  const bool splits_by_capacity = type == "octree-adaptive" || type == "octree-layered";
  switch (o) {
    case IndexOption::capacity: return splits_by_capacity || type == "kdtree";
    case IndexOption::max_depth: return splits_by_capacity;
    case IndexOption::depth: return type == "octree-fixed";
    case IndexOption::insertion: return splits_by_capacity || type == "octree-fixed";
  }
  return false;
}

void check_applicable(std::string_view type, const GivenIndexOptions& given, const IndexChoiceWords& words) {
  std::vector<std::string_view> offered(words.types.begin(), words.types.end());
  if (offered.empty())
    for (std::string_view t : kIndexTypes)
      if (!words.layouts || octree_layout_of(t)) offered.push_back(t);
  if (std::find(offered.begin(), offered.end(), type) == offered.end()) return;
  auto value = [&](std::string_view t) {
    const std::optional<OctreeLayout> layout = words.layouts ? octree_layout_of(t) : std::nullopt;
    return words.quote + (layout ? std::string(to_string(*layout)) : std::string(t)) + words.quote;
  };
  const std::pair<bool, IndexOption> options[] = {{given.capacity, IndexOption::capacity},
                                                  {given.max_depth, IndexOption::max_depth},
                                                  {given.depth, IndexOption::depth},
                                                  {given.insertion, IndexOption::insertion}};
  for (const auto& [is_given, o] : options) {
    if (!is_given || index_option_applies(type, o)) continue;
    std::vector<std::string> users;  // as the front end writes them (value)
    for (std::string_view t : offered)
      if (index_option_applies(t, o)) users.push_back(value(t));
    const std::string got = words.option + value(type);
    // (No front end takes an option that none of its types uses; such a one is refused plainly.)
    if (users.empty()) throw OptionError({option(to_string(o)), " does not apply to " + got});
    throw OptionError({option(to_string(o)),
                       " applies to " + words.option + join_words(users, "and") + " only (got " + got + ")"});
  }
}

std::uint32_t index_capacity(const IndexOptions& opts) {
  if (opts.capacity) return *opts.capacity;
  if (const std::optional<OctreeLayout> layout = octree_layout_of(opts.type)) return default_capacity(*layout);
  if (opts.type == "kdtree") return kDefaultKdTreeLeaf;
  return 0;
}

AnyIndex make_index(std::span<const Vec3> positions, const IndexOptions& opts) {
  const std::string& t = opts.type;
  if (const std::optional<OctreeLayout> layout = octree_layout_of(t)) {
    OctreeConfig c = OctreeConfig::for_layout(*layout);
    c.capacity = opts.capacity.value_or(c.capacity);  // (index_capacity, without parsing the layout again)
    c.depth = opts.depth;
    c.max_depth = opts.max_depth;
    return opts.insertion ? Octree::build_by_insertion(positions, c)
                          : Octree::build_bulk(positions, c);
  }
  if (t == "kdtree") return KdTree(positions, index_capacity(opts));
  if (t == "brute") return BruteForceIndex(positions);
  throw std::invalid_argument("index type '" + t + "': expected " + join_alternatives(kIndexTypes));
}

std::size_t index_memory_bytes(const AnyIndex& index) {
  return std::visit([](const auto& i) { return i.memory_bytes(); }, index);
}

}  // namespace rayscan
