#include "rayscan/octree/ray_query.hpp"

#include "rayscan/octree/any_index.hpp"
#include "rayscan/octree/detail/ray_query_impl.hpp"
#include "rayscan/base/number_text.hpp"
#include "rayscan/base/option_error.hpp"

#include <atomic>
#include <cmath>

namespace rayscan {

void set_entry_point_search(EntryPointSearch mode) {
  detail::g_entry_point_search.store(static_cast<int>(mode), std::memory_order_relaxed);
}
void set_entry_point_search(bool on) { set_entry_point_search(on ? EntryPointSearch::automatic : EntryPointSearch::off); }

namespace {
// interleaved_pairs(): -1 until set or first read (then the CPU's default), else 0 / 1.
std::atomic<int> g_interleaved_pairs{-1};
}  // namespace

bool interleaved_pairs_default() { return false; }

bool interleaved_pairs() {
  int v = g_interleaved_pairs.load(std::memory_order_relaxed);
  if (v < 0) {
    int unset = -1;
    const int d = interleaved_pairs_default() ? 1 : 0;
    v = g_interleaved_pairs.compare_exchange_strong(unset, d, std::memory_order_relaxed) ? d : unset;
  }
  return v != 0;
}

void set_interleaved_pairs(bool on) { g_interleaved_pairs.store(on ? 1 : 0, std::memory_order_relaxed); }

void RayQuery::validate() const {
  // OptionErrors naming the fields, so that each front end writes them as its own options
  // (--radius, --t-min for the CLI; radius=, t_min= for Python).
  if (std::isnan(radius)) throw OptionError({"ray query: ", option("radius"), " must not be NaN"});
  if (std::isnan(t_min)) throw OptionError({"ray query: ", option("t_min"), " must not be NaN"});
  if (std::isnan(t_max)) throw OptionError({"ray query: ", option("t_max"), " must not be NaN"});
  if (radius < 0.0)
    throw OptionError({"ray query: ", option("radius"), " must be >= 0, got " + shortest_text(radius)});
  if (t_min > t_max)
    throw OptionError({"ray query: ", option("t_min"), " " + shortest_text(t_min) + " must not exceed ",
                       option("t_max"), " " + shortest_text(t_max)});
  if (order == RayOrder::sphere_hit && !(radius < kInf))
    throw OptionError({"ray query: order sphere_hit requires a finite ", option("radius")});
  for (const Plane& pl : planes) {
    const double len = glm::length(pl.normal);
    if (!(len > 0.0) || !std::isfinite(len) || !std::isfinite(glm::length(pl.point)))
      throw std::invalid_argument("ray query: plane normal must be non-zero and finite");
  }
}

// The ray query's entry points for the core's indexes (declared extern in ray_query.hpp), compiled
// once here from the private definitions.
RAYSCAN_RAY_QUERY_INSTANCES(template, Octree)
RAYSCAN_RAY_QUERY_INSTANCES(template, KdTree)
RAYSCAN_RAY_QUERY_INSTANCES(template, BruteForceIndex)

}  // namespace rayscan
