// Test helper: counts malloc calls by interposing glibc's malloc for the test binary that
// includes this header (include it in exactly one source file of that binary). Defines
// FEEDLOOP_COUNT_MALLOC where counting works (glibc, no sanitizer: sanitizers own malloc); tests
// set g_counting around the code under test and read g_mallocs.
#pragma once

#include <atomic>
#include <cstddef>

#if !defined(FEEDLOOP_SANITIZED) && defined(__GLIBC__)
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
