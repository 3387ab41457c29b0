// A test's switch of the entry-point search (set_entry_point_search), undone at the end of its
// scope: the octree's and the index file's query tests compare answers with the search on and off.
#pragma once

#include "rayscan/octree/ray_query.hpp"

namespace rayscan::test {

/// Turns the entry-point search (set_entry_point_search) back on, its default, at the end of a
/// scope that switches it.
struct EntrySearchGuard {
  EntrySearchGuard() = default;
  ~EntrySearchGuard() { set_entry_point_search(true); }
  EntrySearchGuard(const EntrySearchGuard&) = delete;
  EntrySearchGuard& operator=(const EntrySearchGuard&) = delete;
};

}  // namespace rayscan::test
