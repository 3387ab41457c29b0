#include "rayscan/threads.hpp"

#include <tbb/task_arena.h>

namespace rayscan {

unsigned resolve_threads(unsigned requested) {
  if (requested > 0) return requested;
  const int n = tbb::this_task_arena::max_concurrency();
  return n > 0 ? static_cast<unsigned>(n) : 1u;
}

}  // namespace rayscan
