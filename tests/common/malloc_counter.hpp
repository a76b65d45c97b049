// Test helper: counts malloc calls of the test binary that includes this header (include it in
// exactly one source file of that binary). Tests set g_counting around the code under test and
// read g_mallocs. Two ways, so the count works in the normal and in the sanitizer build (the one
// CI runs):
//   - normal build (glibc): this binary interposes malloc and forwards to glibc's __libc_malloc;
//   - ASan/UBSan build: the sanitizer owns malloc, so the count comes from its allocation hook
//     (__sanitizer_install_malloc_and_free_hooks, sanitizer/allocator_interface.h), which it calls
//     for every allocation, operator new included.
// FEEDLOOP_COUNT_MALLOC is defined where one of the two works. The sanitizer way is opt-in
// (-DFEEDLOOP_SANITIZER_MALLOC_HOOK) until a sanitizer build has run every allocation test with it.
#pragma once

#include <atomic>
#include <cstddef>

#if defined(FEEDLOOP_SANITIZED) && defined(FEEDLOOP_SANITIZER_MALLOC_HOOK)
// sanitizer/allocator_interface.h ships with clang, not with GCC; GCC's libsanitizer exports the
// same function.
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*, std::size_t),
                                                         void (*free_hook)(const volatile void*));
#define FEEDLOOP_COUNT_MALLOC 1
namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_mallocs{0};
void count_malloc_hook(const volatile void*, std::size_t) {
  if (g_counting.load(std::memory_order_relaxed)) g_mallocs.fetch_add(1, std::memory_order_relaxed);
}
// Installed before main() by a static initialiser of this translation unit.
[[maybe_unused]] const int g_malloc_hook_installed =
    __sanitizer_install_malloc_and_free_hooks(count_malloc_hook, nullptr);
}  // namespace
#elif defined(__GLIBC__) && !defined(FEEDLOOP_SANITIZED)
#define FEEDLOOP_COUNT_MALLOC 1
namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_mallocs{0};
}  // namespace
extern "C" void* __libc_malloc(std::size_t);
extern "C" void* malloc(std::size_t n) {  // NOLINT: interposes glibc's malloc for this test binary
  if (g_counting.load(std::memory_order_relaxed)) g_mallocs.fetch_add(1, std::memory_order_relaxed);
  return __libc_malloc(n);
}
#endif
