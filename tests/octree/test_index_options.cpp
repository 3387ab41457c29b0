// Which build options each index type uses (index_option_applies) and the refusal of the others
// (check_applicable), against the builder itself: an option a type is said not to use leaves
// make_index's index unchanged, one it uses changes it.
#include "test_util.hpp"

#include "rayscan/base/option_error.hpp"
#include "rayscan/octree/any_index.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>
#include <vector>

using namespace rayscan;
using namespace rayscan::test;

namespace {

constexpr std::array<const char*, 5> kTypes = {"octree-adaptive", "octree-layered", "octree-fixed", "kdtree",
                                               "brute"};
constexpr std::array<IndexOption, 4> kOptions = {IndexOption::capacity, IndexOption::max_depth, IndexOption::depth,
                                                 IndexOption::insertion};

/// Node n of a and node m of b hold the same box, slots and children, recursively.
template <class I>
bool same_subtree(const I& a, typename I::Node n, const I& b, typename I::Node m) {
  const AABB ba = a.node_bounds(n), bb = b.node_bounds(m);
  const SlotRange sa = a.node_points(n), sb = b.node_points(m);
  if (ba.lo != bb.lo || ba.hi != bb.hi || sa.begin != sb.begin || sa.end != sb.end ||
      a.child_count(n) != b.child_count(m))
    return false;
  for (unsigned i = 0; i < a.child_count(n); ++i)
    if (!same_subtree(a, a.child(n, i), b, b.child(m, i))) return false;
  return true;
}

/// The same index: one type, the same slot order, ids and node tree (through the SpatialIndex
/// concept, so that every type is compared alike).
bool same_index(const AnyIndex& a, const AnyIndex& b) {
  if (a.index() != b.index()) return false;
  return std::visit(
      [&](const auto& x) {
        const auto& y = std::get<std::decay_t<decltype(x)>>(b);
        const auto px = x.positions(), py = y.positions();
        const auto ix = x.ids(), iy = y.ids();
        return std::equal(px.begin(), px.end(), py.begin(), py.end()) &&
               std::equal(ix.begin(), ix.end(), iy.begin(), iy.end()) && x.empty() == y.empty() &&
               (x.empty() || same_subtree(x, x.root(), y, y.root()));
      },
      a);
}

/// `base` with option o set to a value other than its default, one that changes the tree of a
/// type that uses it on make_points(3000): capacity 4 (default 64 or 32), max_depth 1 (21),
/// depth 3 (6), insertion.
IndexOptions with_option(IndexOptions base, IndexOption o) {
  switch (o) {
    case IndexOption::capacity: base.capacity = 4; break;
    case IndexOption::max_depth: base.max_depth = 1; break;
    case IndexOption::depth: base.depth = 3; break;
    case IndexOption::insertion: base.insertion = true; break;
  }
  return base;
}

GivenIndexOptions given_only(IndexOption o) {
  GivenIndexOptions g;
  switch (o) {
    case IndexOption::capacity: g.capacity = true; break;
    case IndexOption::max_depth: g.max_depth = true; break;
    case IndexOption::depth: g.depth = true; break;
    case IndexOption::insertion: g.insertion = true; break;
  }
  return g;
}

/// check_applicable's message, or "" when it accepts.
std::string refusal(std::string_view type, const GivenIndexOptions& given, const IndexChoiceWords& words = {}) {
  try {
    check_applicable(type, given, words);
  } catch (const OptionError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// The rule, written out as the specification (docs/cli.md, docs/python.md): capacity and max_depth
// for the octrees that split by capacity (the kd-tree takes a capacity as its leaf size), depth for
// the fixed octree, insertion for every octree.
TEST(IndexOptions, WhichTypeUsesWhichOption) {
  struct Row {
    const char* type;
    bool capacity, max_depth, depth, insertion;
  };
  const Row rows[] = {
      {"octree-adaptive", true, true, false, true}, {"octree-layered", true, true, false, true},
      {"octree-fixed", false, false, true, true},   {"kdtree", true, false, false, false},
      {"brute", false, false, false, false},        {"rtree", false, false, false, false},
  };
  for (const Row& r : rows) {
    SCOPED_TRACE(r.type);
    EXPECT_EQ(index_option_applies(r.type, IndexOption::capacity), r.capacity);
    EXPECT_EQ(index_option_applies(r.type, IndexOption::max_depth), r.max_depth);
    EXPECT_EQ(index_option_applies(r.type, IndexOption::depth), r.depth);
    EXPECT_EQ(index_option_applies(r.type, IndexOption::insertion), r.insertion);
  }
  EXPECT_STREQ(to_string(IndexOption::max_depth), "max_depth");
}

// Why an option is refused: the builder ignores it. Every type x option: an option the rule says a
// type does not use builds the very same index as the default; one it uses builds another (except
// insertion, another algorithm for the same tree: Octree.InsertionAndBulkBuildIdenticalTrees).
TEST(IndexOptions, ARefusedOptionIsOneTheBuilderIgnores) {
  const auto pts = make_points(3000, Dist::uniform, 11);
  for (const char* type : kTypes) {
    IndexOptions base;
    base.type = type;
    const AnyIndex plain = make_index(pts, base);
    for (IndexOption o : kOptions) {
      SCOPED_TRACE(std::string(type) + " " + to_string(o));
      const bool same = same_index(plain, make_index(pts, with_option(base, o)));
      if (!index_option_applies(type, o)) {
        EXPECT_TRUE(same) << "a refused option changes the index";
      } else if (o != IndexOption::insertion) {
        EXPECT_FALSE(same) << "an accepted option changes nothing here";
      }
    }
  }
}

// check_applicable refuses exactly the combinations the rule excludes, with an OptionError naming
// the option by its field (each front end spells it) and listing the types that use it.
TEST(IndexOptions, CheckApplicableRefusesEachUnusedOption) {
  for (const char* type : kTypes)
    for (IndexOption o : kOptions) {
      SCOPED_TRACE(std::string(type) + " " + to_string(o));
      try {
        check_applicable(type, given_only(o));
        EXPECT_TRUE(index_option_applies(type, o)) << "not refused";
      } catch (const OptionError& e) {
        EXPECT_FALSE(index_option_applies(type, o)) << "refused: " << e.what();
        ASSERT_FALSE(e.parts().empty());
        const auto* name = std::get_if<OptionName>(&e.parts().front());
        ASSERT_NE(name, nullptr);
        EXPECT_EQ(name->field, to_string(o));
        EXPECT_EQ(e.spelled([](std::string_view f) { return "--" + std::string(f); }).rfind("--", 0), 0u);
      }
    }
  EXPECT_EQ(refusal("brute", given_only(IndexOption::capacity)),
            "capacity applies to index type octree-adaptive, octree-layered and kdtree only (got index type brute)");
  EXPECT_EQ(refusal("kdtree", given_only(IndexOption::insertion)),
            "insertion applies to index type octree-adaptive, octree-layered and octree-fixed only (got index type "
            "kdtree)");
  // Several unused options: the first of capacity, max_depth, depth, insertion is named.
  GivenIndexOptions all{true, true, true, true};
  EXPECT_EQ(refusal("brute", all).rfind("capacity applies", 0), 0u);
  EXPECT_EQ(refusal("kdtree", all).rfind("max_depth applies", 0), 0u);
  EXPECT_EQ(refusal("octree-fixed", all).rfind("capacity applies", 0), 0u);
  EXPECT_EQ(refusal("octree-adaptive", all).rfind("depth applies", 0), 0u);
  // An unknown type is left to make_index, which names the types.
  EXPECT_EQ(refusal("rtree", all), "");
}

// Each front end's words: the choosing option, layouts instead of types, quotes and the types it
// offers. These are the messages `rayscan query`, `rayscan index` and the Python Octree print once
// the option is spelled (tests/octree/test_query_cli.cpp, tests/jobs/test_job_cli.cpp,
// python/tests/test_argument_types.py).
TEST(IndexOptions, MessagesInEachFrontEndsWords) {
  IndexChoiceWords query;
  query.option = "--index ";
  EXPECT_EQ(refusal("octree-adaptive", given_only(IndexOption::depth), query),
            "depth applies to --index octree-fixed only (got --index octree-adaptive)");

  IndexChoiceWords index;
  index.option = "--layout ";
  index.layouts = true;
  index.types = {"octree-adaptive", "octree-fixed"};
  EXPECT_EQ(refusal("octree-fixed", given_only(IndexOption::max_depth), index),
            "max_depth applies to --layout adaptive only (got --layout fixed)");
  // A type the front end does not offer is its own to refuse (the index job: no layered layout).
  EXPECT_EQ(refusal("octree-layered", given_only(IndexOption::depth), index), "");

  IndexChoiceWords python;
  python.option = "layout=";
  python.layouts = true;
  python.quote = "'";
  EXPECT_EQ(refusal("octree-fixed", given_only(IndexOption::capacity), python),
            "capacity applies to layout='adaptive' and 'layered' only (got layout='fixed')");
  EXPECT_EQ(refusal("octree-layered", given_only(IndexOption::depth), python),
            "depth applies to layout='fixed' only (got layout='layered')");
  // The kd-tree and brute are no layouts: not offered, not checked.
  EXPECT_EQ(refusal("kdtree", given_only(IndexOption::depth), python), "");
}

// An octree's index type and its layout map to each other (octree_index_type, octree_layout_of),
// against the list of index types written by hand here: each octree layout to its type and back,
// the other types to none, and an unknown layout refused as parse_octree_layout refuses it, listing
// the layouts in kOctreeLayouts' order, which is kIndexTypes' order of the octrees.
TEST(IndexOptions, OctreeTypesAndLayoutsMapToEachOther) {
  const std::pair<OctreeLayout, const char*> octrees[] = {
      {OctreeLayout::adaptive, "octree-adaptive"}, {OctreeLayout::layered, "octree-layered"}, {OctreeLayout::fixed, "octree-fixed"}};
  for (const auto& o : octrees) {
    EXPECT_EQ(octree_index_type(o.first), o.second);
    EXPECT_EQ(octree_layout_of(o.second), std::optional<OctreeLayout>(o.first)) << o.second;
    EXPECT_NE(std::find(kIndexTypes.begin(), kIndexTypes.end(), o.second), kIndexTypes.end()) << o.second;
  }
  ASSERT_EQ(kOctreeLayouts.size(), std::size(octrees));
  for (std::size_t i = 0; i < kOctreeLayouts.size(); ++i) {
    EXPECT_EQ(kOctreeLayouts[i], octrees[i].first) << i;
    EXPECT_EQ(kIndexTypes[i], octrees[i].second) << i;
    EXPECT_EQ(parse_octree_layout(octree_layout_names()[i]), octrees[i].first) << i;
  }
  EXPECT_EQ(octree_layout_names("'"), (std::vector<std::string>{"'adaptive'", "'layered'", "'fixed'"}));
  for (const char* other : {"kdtree", "brute", "", "octree"}) EXPECT_EQ(octree_layout_of(other), std::nullopt) << other;
  try {
    (void)octree_layout_of("octree-grid");
    ADD_FAILURE() << "octree-grid accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "octree layout 'grid': expected adaptive, layered or fixed");
  }
}
