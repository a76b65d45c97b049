// One compressed run of steps, and the MCU step law that expands it (the contract between the
// host compressor, the wire codec and the device):
//
//   a run starts from the previous step's clock P (or the batch's first_clock);
//   step k (k = 1..count) happens at  P + k*interval + add*k*(k-1)/2   [MCU ticks]
//   i.e. next = last + interval; interval += add   (the same law as Klipper's queue_step).
//
// All steps of a run go in one direction (+1 or -1 in joint coordinates).
#pragma once

#include <cstdint>

namespace feedloop::stepgen {

struct StepRun {
  int64_t interval_ticks = 0;  // ticks from the previous step to the first step of the run
  int32_t add_ticks = 0;       // change of the interval after each step
  uint32_t count = 0;          // number of steps, >= 1
  int8_t direction = 1;        // +1 or -1
};

// Clock of step k (1-based) of a run that starts at start_clock.
inline int64_t run_step_clock(int64_t start_clock, const StepRun& r, uint32_t k) {
  const int64_t kk = k;
  return start_clock + kk * r.interval_ticks + static_cast<int64_t>(r.add_ticks) * (kk * (kk - 1) / 2);
}

// Clock of the last step of the run (the next run's start).
inline int64_t run_end_clock(int64_t start_clock, const StepRun& r) {
  return run_step_clock(start_clock, r, r.count);
}

// True when the run keeps the step law's preconditions: at least one step, every interval at
// least one tick (the first and the last; intervals are linear in k, so all of them) and every
// step clock of the run, as run_step_clock() computes it, representable. A run that breaks them
// would step back in time, never end or overflow; the device refuses it (a malformed message).
inline bool run_is_valid(int64_t start_clock, const StepRun& r) {
  if (r.count < 1 || r.interval_ticks < 1) return false;
  const int64_t n = r.count;
  int64_t last_interval = 0, span = 0, pairs = 0, quad = 0, end = 0;
  if (__builtin_mul_overflow(n - 1, static_cast<int64_t>(r.add_ticks), &last_interval) ||
      __builtin_add_overflow(last_interval, r.interval_ticks, &last_interval) || last_interval < 1)
    return false;
  // run_step_clock(start, r, n) = (start + n*interval) + add*(n*(n-1)/2); the terms for k < n are
  // no larger, and the partial sums stay between start and the end (intervals are positive).
  return !__builtin_mul_overflow(n, r.interval_ticks, &span) &&
         !__builtin_add_overflow(start_clock, span, &end) &&
         !__builtin_mul_overflow(n, n - 1, &pairs) &&
         !__builtin_mul_overflow(static_cast<int64_t>(r.add_ticks), pairs / 2, &quad) &&
         !__builtin_add_overflow(end, quad, &end);
}

// Receives runs from the compressor. Called from the step path: implementations must not
// allocate in steady state.
class RunSink {
 public:
  virtual ~RunSink() = default;
  // start_clock: clock of the step before the run's first step (the run's reference P).
  virtual void on_run(int64_t start_clock, const StepRun& run) = 0;
};

}  // namespace feedloop::stepgen
