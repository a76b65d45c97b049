// The sanitizer stage of scripts/test.sh (clang, ASan + UBSan + libFuzzer coverage, -O1) runs the
// simulations ~12 times slower than the GCC stage. A test whose cost there is statistics over many
// repetitions of a path that other tests already run under the sanitizers is skipped there, and
// says so; the GCC stage runs it whole (docs/decisions.md, "CI time").
#pragma once

#include <gtest/gtest.h>

#ifdef FEEDLOOP_SANITIZED
#define FEEDLOOP_GCC_STAGE_ONLY(why) GTEST_SKIP() << "runs in the GCC stage only (CI time): " << why
#else
#define FEEDLOOP_GCC_STAGE_ONLY(why) static_cast<void>(0)
#endif
