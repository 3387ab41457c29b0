#include "rayscan/base/threads.hpp"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>

namespace rayscan {

unsigned resolve_threads(unsigned requested) {
  if (requested > 0) return requested;
  // The arena's concurrency (process affinity) capped by a global_control limit, if one is active.
  const std::size_t arena = static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency()));
  const std::size_t limit =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  return static_cast<unsigned>(std::max<std::size_t>(1, std::min(arena, limit)));
}

}  // namespace rayscan
