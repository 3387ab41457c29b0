#include "rayscan/base/threads.hpp"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>

namespace rayscan {

unsigned resolve_threads(unsigned requested) {
  // The arena's concurrency (process affinity) capped by a global_control limit, if one is active:
  // the most threads TBB runs at once. An arena asked for more gets no more workers (TBB prints a
  // warning and ignores the request), so a larger request is capped here and every job logs and
  // reports the count it really runs with.
  const std::size_t arena = static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency()));
  const std::size_t limit =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  const std::size_t most = std::max<std::size_t>(1, std::min(arena, limit));
  return static_cast<unsigned>(requested > 0 ? std::min<std::size_t>(requested, most) : most);
}

}  // namespace rayscan
