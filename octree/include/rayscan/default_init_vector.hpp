// Vectors whose resize(n) leaves trivial elements uninitialised, for the large arrays that a build
// fills in parallel right after sizing them.
//
// std::vector<T>::resize value-initialises: for the octree's 1e7-point bulk build that was a serial
// zeroing pass over 0.3 GB of positions, ids and nodes before the parallel passes wrote them
// again, and each page's first touch (its fault) happened in that serial pass instead of on the
// thread that fills it. With this allocator the pass that fills an array is the first to touch it.
// (The same idiom as Boost.Container's default_init_t; C++20 [allocator.requirements], [default.
// allocator].) Transparent huge pages were tried for these arrays and dropped: bench/README.md,
// "Issue 12, session 22".
#pragma once

#include <memory>
#include <new>
#include <utility>
#include <vector>

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

  /// Default-initialises *p when no arguments are given; otherwise constructs U(args...).
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0)
      ::new (static_cast<void*>(p)) U;
    else
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A std::vector on DefaultInitAllocator: `resize(n)` and `vector(n)` leave new trivial elements
/// indeterminate until written.
template <class T>
using DefaultInitVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace rayscan
