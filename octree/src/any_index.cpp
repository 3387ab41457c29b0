#include "rayscan/octree/any_index.hpp"

#include "rayscan/base/option_error.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <utility>

namespace rayscan {

namespace {

constexpr std::string_view kOctreePrefix = "octree-";

}  // namespace

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
      if (!words.layouts || t.starts_with(kOctreePrefix)) offered.push_back(t);
  if (std::find(offered.begin(), offered.end(), type) == offered.end()) return;
  auto value = [&](std::string_view t) {
    if (words.layouts && t.starts_with(kOctreePrefix)) t.remove_prefix(kOctreePrefix.size());
    return words.quote + std::string(t) + words.quote;
  };
  const std::pair<bool, IndexOption> options[] = {{given.capacity, IndexOption::capacity},
                                                  {given.max_depth, IndexOption::max_depth},
                                                  {given.depth, IndexOption::depth},
                                                  {given.insertion, IndexOption::insertion}};
  for (const auto& [is_given, o] : options) {
    if (!is_given || index_option_applies(type, o)) continue;
    std::vector<std::string_view> users;
    for (std::string_view t : offered)
      if (index_option_applies(t, o)) users.push_back(t);
    const std::string got = words.option + value(type);
    // (No front end takes an option that none of its types uses; such a one is refused plainly.)
    if (users.empty()) throw OptionError({option(to_string(o)), " does not apply to " + got});
    std::string list;
    for (std::size_t i = 0; i < users.size(); ++i)
      list += (i == 0 ? "" : i + 1 == users.size() ? " and " : ", ") + value(users[i]);
    throw OptionError({option(to_string(o)), " applies to " + words.option + list + " only (got " + got + ")"});
  }
}

std::uint32_t index_capacity(const IndexOptions& opts) {
  if (opts.capacity) return *opts.capacity;
  if (std::string_view(opts.type).starts_with(kOctreePrefix))
    return default_capacity(parse_octree_layout(opts.type.substr(kOctreePrefix.size())));
  if (opts.type == "kdtree") return kDefaultKdTreeLeaf;
  return 0;
}

AnyIndex make_index(std::span<const Vec3> positions, const IndexOptions& opts) {
  const std::string& t = opts.type;
  if (t.starts_with(kOctreePrefix)) {
    OctreeConfig c = OctreeConfig::for_layout(parse_octree_layout(t.substr(kOctreePrefix.size())));
    c.capacity = opts.capacity.value_or(c.capacity);  // (index_capacity, without parsing the layout again)
    c.depth = opts.depth;
    c.max_depth = opts.max_depth;
    return opts.insertion ? Octree::build_by_insertion(positions, c)
                          : Octree::build_bulk(positions, c);
  }
  if (t == "kdtree") return KdTree(positions, index_capacity(opts));
  if (t == "brute") return BruteForceIndex(positions);
  std::string expected;  // "a, b, c or d", from the one list of index types
  for (std::size_t i = 0; i < kIndexTypes.size(); ++i)
    expected += (i == 0 ? "" : i + 1 == kIndexTypes.size() ? " or " : ", ") + std::string(kIndexTypes[i]);
  throw std::invalid_argument("index type '" + t + "': expected " + expected);
}

std::size_t index_memory_bytes(const AnyIndex& index) {
  return std::visit([](const auto& i) { return i.memory_bytes(); }, index);
}

}  // namespace rayscan
