// Test helper shared by every area: whether this test binary is built with a sanitizer.
#pragma once

namespace rayscan::test {

/// True when the test is compiled with AddressSanitizer, MemorySanitizer or ThreadSanitizer (GCC's
/// __SANITIZE_ADDRESS__, Clang's __has_feature). Such a build reserves its shadow memory beyond any
/// `ulimit -v`, so tests that bound a child's address space cannot run under it.
inline constexpr bool kSanitized =
#if defined(__SANITIZE_ADDRESS__)
    true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer) || __has_feature(thread_sanitizer)
    true;
#else
    false;
#endif
#else
    false;
#endif

}  // namespace rayscan::test
