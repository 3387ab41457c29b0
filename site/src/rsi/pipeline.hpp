// The ordered parallel pipelines of the index build: work on items in parallel, hand them to one
// in-order sink, with a fixed number of items (and so of the caller's buffers) in flight. Used by
// the run writer, the merge and the node build. docs/index-format.md, "Build (external memory)".
#pragma once

#include "bytes.hpp"

#include <tbb/parallel_pipeline.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

namespace rayscan::io::rsi {

using detail::HugeArray;
using detail::round_up_direct;

/// Runs work(i) for i in [0, n) in parallel and then sink(i) for each i in order of i, one sink
/// at a time, with at most kPipelineSlots items in flight (TBB parallel_pipeline: the
/// serial_in_order last stage ends item i before item i + kPipelineSlots starts, so a caller's
/// buffer i % kPipelineSlots is never in use by two items).
constexpr std::size_t kPipelineSlots = 4;
template <class Work, class Sink>
void ordered_pipeline(std::size_t n, const Work& work, const Sink& sink, std::size_t slots = kPipelineSlots) {
  std::size_t next = 0;
  tbb::parallel_pipeline(
      slots,
      tbb::make_filter<void, std::size_t>(tbb::filter_mode::serial_in_order,
                                          [&](tbb::flow_control& fc) -> std::size_t {
                                            if (next == n) {
                                              fc.stop();
                                              return 0;
                                            }
                                            return next++;
                                          }) &
          tbb::make_filter<std::size_t, std::size_t>(tbb::filter_mode::parallel,
                                                     [&](std::size_t i) {
                                                       work(i);
                                                       return i;
                                                     }) &
          tbb::make_filter<std::size_t, void>(tbb::filter_mode::serial_in_order, [&](std::size_t i) { sink(i); }));
}

/// Runs fill(i, buffer) -> bytes for blocks i in [0, n) in parallel and write(i, buffer, bytes)
/// for each block in order of i, one write at a time (ordered_pipeline), each block in one of
/// kPipelineSlots buffers of `block_bytes` allocated once (huge pages: no fresh small pages per
/// block; rounded up to whole pages, so a writer may pad a block for O_DIRECT).
template <class Fill, class Write>
void pipelined_blocks(std::size_t n, std::size_t block_bytes, const Fill& fill, const Write& write) {
  std::array<HugeArray<std::uint8_t>, kPipelineSlots> slots;
  std::array<std::size_t, kPipelineSlots> bytes{};
  for (auto& sl : slots) sl = HugeArray<std::uint8_t>(round_up_direct(std::min<std::size_t>(block_bytes, n * block_bytes)));
  ordered_pipeline(
      n, [&](std::size_t i) { bytes[i % kPipelineSlots] = fill(i, slots[i % kPipelineSlots].data()); },
      [&](std::size_t i) { write(i, slots[i % kPipelineSlots].data(), bytes[i % kPipelineSlots]); });
}

}  // namespace rayscan::io::rsi
