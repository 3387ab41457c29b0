// Worker-thread counts: the one rule every job uses to turn a requested count into a real one.
#pragma once

namespace rayscan {

/// The number of worker threads a job runs with: every core TBB may use
/// (tbb::this_task_arena::max_concurrency(), i.e. the process's CPU affinity, capped by an active
/// tbb::global_control max_allowed_parallelism limit) when `requested` is 0, else `requested`
/// capped at that count (TBB runs no more threads than that: an arena asked for more would only
/// print TBB's "number of workers is currently limited" warning). Jobs give the same result for any
/// count; only the wall time changes.
[[nodiscard]] unsigned resolve_threads(unsigned requested);

}  // namespace rayscan
