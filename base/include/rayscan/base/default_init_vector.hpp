// Vectors whose resize(n) leaves trivial elements uninitialised, for the large arrays that a build
// fills in parallel right after sizing them.
//
// std::vector<T>::resize value-initialises: for the octree's 1e7-point bulk build that was a serial
// zeroing pass over 0.3 GB of positions, ids and nodes before the parallel passes wrote them
// again, and each page's first touch (its fault) happened in that serial pass instead of on the
// thread that fills it. With this allocator the pass that fills an array is the first to touch it.
// (The same idiom as Boost.Container's default_init_t; C++20 [allocator.requirements], [default.
// allocator].)
//
// Arrays of 4 MiB and more are allocated 2 MiB-aligned and advised MADV_HUGEPAGE (transparent
// huge pages; the THP mode "madvise", Debian's default, honours the advice). glibc serves such
// allocations from fresh maps (always above its largest mmap threshold, 32 MiB, and below it
// until a free has raised the threshold: a process's first build), whose first touch faults each
// 4 KiB page: a 1e7-point build took ~120,000 faults and more system CPU than the build's own
// work on the benchmark VM (bench/notes/), ~9 us per fault; huge pages take
// 1/512 of the faults (1e7: 1,476 -> 544 ms; 1e6 cold: 108-151 -> 62-69 ms), for ~1 MiB of
// rounding per array (1e6 points: 30.7 -> 31.9 B/pt resident). Smaller arrays keep
// std::allocator. (Huge pages for every array of the build, small ones included, measured slower
// first builds on that VM; the figures above are for this threshold, cold and warm.)
#pragma once

#include <cstddef>
#include <cstdlib>
#include <limits>
#include <memory>
#include <new>
#include <utility>
#include <vector>

#include <sys/mman.h>

namespace rayscan {

/// std::allocator<T> whose construct(p) with no arguments default-initialises (no zeroing for
/// trivial types; a class's default member initialisers still run). With arguments it constructs
/// from them, like std::allocator. Equal instances are interchangeable.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  using value_type = T;
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() noexcept = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}

  /// Arrays of at least this many bytes get huge pages (see the file comment).
  static constexpr std::size_t kHugeBytes = std::size_t{4} << 20;
  /// The transparent huge page size of x86-64 and the alignment of those arrays.
  static constexpr std::size_t kHugePage = std::size_t{2} << 20;

  /// n elements, uninitialised: std::allocator's below kHugeBytes, else a 2 MiB-aligned block
  /// advised MADV_HUGEPAGE. Throws std::bad_alloc (std::bad_array_new_length for n above
  /// max_size()).
  [[nodiscard]] T* allocate(std::size_t n) {
    if (n > (std::numeric_limits<std::size_t>::max() - kHugePage) / sizeof(T)) throw std::bad_array_new_length();
    if (n * sizeof(T) < kHugeBytes) return std::allocator<T>::allocate(n);
    const std::size_t bytes = huge_bytes(n);
    void* p = std::aligned_alloc(kHugePage, bytes);
    if (p == nullptr) throw std::bad_alloc();
    (void)::madvise(p, bytes, MADV_HUGEPAGE);  // advice only: without THP, 4 KiB pages
    return static_cast<T*>(p);
  }
  /// Frees what allocate(n) returned.
  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) < kHugeBytes)
      std::allocator<T>::deallocate(p, n);
    else
      std::free(p);
  }

  /// Default-initialises *p when no arguments are given; otherwise constructs U(args...).
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0)
      ::new (static_cast<void*>(p)) U;
    else
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }

 private:
  static std::size_t huge_bytes(std::size_t n) { return (n * sizeof(T) + kHugePage - 1) / kHugePage * kHugePage; }
};

/// A std::vector on DefaultInitAllocator: `resize(n)` and `vector(n)` leave new trivial elements
/// indeterminate until written.
template <class T>
using DefaultInitVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace rayscan
