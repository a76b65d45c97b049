// Property test of the step compressor (seeded, randomised, many runs): every compressed run,
// decoded from the wire bodies and expanded with the MCU step law, reproduces every step time
// within its window  T_i - min(E, (T_i - T_{i-1})/2) <= t_i <= T_i + E,  in order, with the
// same directions and count; no run fails its re-expansion check. Each run draws a stream
// (printing-like trapezoid moves, reversals, 1 ms cubic pieces, or all three), an error bound
// E, an MCU clock rate, steps/mm, a run-length limit, how the steps are handed over (the
// generator's chunks or one push() at a time) and early closes (flush_if_due).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "drivers/stepgen/run_codec.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "segment_streams.hpp"

namespace feedloop::stepgen {
namespace {

struct Recorder final : StepSink {
  std::vector<double> ticks;
  std::vector<int8_t> dirs;
  void on_steps(const double* t, const int8_t* d, size_t n) override {
    ticks.insert(ticks.end(), t, t + n);
    dirs.insert(dirs.end(), d, d + n);
  }
};

struct Bodies final : BatchSink {
  std::vector<std::vector<uint8_t>> bodies;
  uint64_t bytes = 0;
  void on_batch(const StepBatch& b) override {
    bodies.emplace_back(b.body, b.body + b.body_bytes);
    bytes += b.body_bytes;
  }
};

// Every body's runs expanded with the MCU's step law (step_run.hpp), in order. False at the first
// malformed body or invalid run (what was decoded before it stays in the vectors).
bool decode_bodies(const Bodies& sink, std::vector<int64_t>& clocks, std::vector<int8_t>& dirs) {
  for (const auto& body : sink.bodies) {
    RunDecoder dec;
    if (!dec.begin(body.data(), body.size())) return false;
    int64_t p = dec.first_clock();
    while (!dec.done()) {
      StepRun r;
      if (!dec.next(r) || !run_is_valid(p, r)) return false;
      for (uint32_t k = 1; k <= r.count; ++k) {
        clocks.push_back(run_step_clock(p, r, k));
        dirs.push_back(r.direction);
      }
      p = run_end_clock(p, r);
    }
  }
  return true;
}

struct Draw {
  int kind;  // 0 trapezoid, 1 reversals, 2 cubic, 3 all three in a row
  double err_us, clock_hz, steps_per_mm;
  uint32_t max_run_count;
  bool one_at_a_time;
  double flush_every_s;  // 0: never close runs early
};

std::vector<JointSegment> stream(std::mt19937_64& rng, int kind) {
  switch (kind) {
    case 0:
      return testing::trapezoid_stream(rng, 60);
    case 1:
      return testing::reversal_stream(rng, 150);
    case 2:
      return testing::cubic_stream(rng, 1500);
    default: {
      // Each part continues where the previous one stopped (time and position).
      auto a = testing::trapezoid_stream(rng, 20);
      auto append = [&a](const std::vector<JointSegment>& part) {
        const double t_end = a.back().end_s(), pos_end = a.back().position_mm(t_end);
        for (auto s : part) {
          s.t0_s += t_end;
          s.c0_mm += pos_end;
          a.push_back(s);
        }
      };
      append(testing::cubic_stream(rng, 500));
      append(testing::reversal_stream(rng, 50));
      return a;
    }
  }
}

// Replays the exact step times into the compressor as the draw says; returns the decoded clocks.
struct Outcome {
  std::vector<int64_t> clocks;
  std::vector<int8_t> dirs;
  StepCompressorStats stats;
  uint64_t bytes = 0;
};

Outcome compress(const Recorder& exact, const std::vector<JointSegment>& segs, const Draw& d,
                 double offset) {
  Bodies sink;
  StepBatcher batcher;
  batcher.configure(0, 200, &sink);
  StepCompressor comp;
  comp.configure({d.err_us * 1e-6 * d.clock_hz, d.max_run_count}, &batcher);
  comp.reset(static_cast<int64_t>(offset), offset);
  double next_flush_s = segs.front().t0_s + d.flush_every_s;
  size_t i = 0;
  const size_t n = exact.ticks.size();
  while (i < n) {
    // Hand over steps up to the next early close, as the engine does between servo cycles.
    size_t j = n;
    if (d.flush_every_s > 0) {
      const double due = offset + next_flush_s * d.clock_hz;
      j = static_cast<size_t>(
          std::upper_bound(exact.ticks.begin() + static_cast<long>(i), exact.ticks.end(), due) -
          exact.ticks.begin());
    }
    if (d.one_at_a_time) {
      for (size_t k = i; k < j; ++k) comp.push(exact.ticks[k], exact.dirs[k]);
    } else {
      for (size_t k = i; k < j; k += 256)
        comp.on_steps(&exact.ticks[k], &exact.dirs[k], std::min<size_t>(256, j - k));
    }
    i = j;
    if (d.flush_every_s > 0) {
      comp.flush_if_due(static_cast<int64_t>(offset + next_flush_s * d.clock_hz));
      batcher.flush_if_due(static_cast<int64_t>(offset + next_flush_s * d.clock_hz));
      next_flush_s += d.flush_every_s;
    }
  }
  comp.flush();
  batcher.flush();
  Outcome o;
  o.stats = comp.stats();
  o.bytes = sink.bytes;
  if (!decode_bodies(sink, o.clocks, o.dirs)) ADD_FAILURE() << "malformed body or invalid run";
  return o;
}

TEST(StepCompressorProperty, EveryRunReproducesEveryStepWithinTheBound) {
  constexpr int kRuns = 240;
  const double errs_us[] = {0.5, 1.0, 2.0, 5.0, 5.0, 10.0, 25.0, 50.0};
  const double clocks_hz[] = {16e6, 20e6, 48e6, 72e6, 72e6, 180e6, 400e6};
  const uint32_t run_limits[] = {1, 2, 3, 17, 255, 65535, 65535, 65535};
  std::mt19937_64 draw_rng(20240611);
  uint64_t steps = 0, runs = 0, bytes = 0;
  double worst_frac = 0.0;  // largest |t - T| as a fraction of the step's own bound
  for (int run = 0; run < kRuns; ++run) {
    std::uniform_int_distribution<int> pick(0, 1 << 20);
    Draw d;
    d.kind = pick(draw_rng) % 4;
    d.err_us = errs_us[pick(draw_rng) % 8];
    d.clock_hz = clocks_hz[pick(draw_rng) % 7];
    d.steps_per_mm = 20.0 + 380.0 * (pick(draw_rng) / double(1 << 20));
    d.max_run_count = run_limits[pick(draw_rng) % 8];
    d.one_at_a_time = pick(draw_rng) % 4 == 0;
    d.flush_every_s =
        pick(draw_rng) % 3 == 0 ? 0.0005 + 0.02 * (pick(draw_rng) / double(1 << 20)) : 0.0;
    std::mt19937_64 rng(1000 + static_cast<uint64_t>(run));
    const auto segs = stream(rng, d.kind);
    const double offset = 1e6 + 1e9 * (pick(draw_rng) / double(1 << 20));  // the MCU clock at t = 0
    Recorder exact;
    StepGenerator gen;
    gen.configure(d.steps_per_mm, TickMap{offset, d.clock_hz}, &exact);
    gen.set_position_mm(segs.front().c0_mm);
    for (const auto& s : segs) gen.add_segment(s);
    gen.flush();
    if (exact.ticks.empty()) continue;
    const Outcome o = compress(exact, segs, d, offset);
    const double E = d.err_us * 1e-6 * d.clock_hz;
    SCOPED_TRACE(::testing::Message()
                 << "run " << run << " kind " << d.kind << " E " << d.err_us << " us clock "
                 << d.clock_hz << " spm " << d.steps_per_mm << " limit " << d.max_run_count
                 << (d.one_at_a_time ? " push" : " chunks") << " flush " << d.flush_every_s);
    ASSERT_EQ(o.clocks.size(), exact.ticks.size());
    ASSERT_EQ(o.dirs, exact.dirs);
    EXPECT_EQ(o.stats.check_failures, 0u);
    EXPECT_EQ(o.stats.window_violations, 0u);
    EXPECT_EQ(o.stats.steps, exact.ticks.size());
    // Bounded work: a run's searches check at most 16 steps per step (plus 4096) before their
    // last check of at most the run's length.
    EXPECT_LE(o.stats.scanned, 17 * o.stats.steps + 4096 * o.stats.runs);
    double prev_t = offset, prev_clock = offset;
    for (size_t i = 0; i < o.clocks.size(); ++i) {
      const double t = exact.ticks[i], c = static_cast<double>(o.clocks[i]);
      const double lo = t - std::min(E, 0.5 * (t - prev_t)), hi = t + E;
      ASSERT_GE(c, lo) << "step " << i;
      ASSERT_LE(c, hi) << "step " << i;
      ASSERT_GT(c, prev_clock) << "step " << i;
      worst_frac = std::max(worst_frac, std::fabs(c - t) / E);
      prev_t = t;
      prev_clock = c;
    }
    steps += exact.ticks.size();
    runs += o.stats.runs;
    bytes += o.bytes;
  }
  std::printf(
      "%d runs: %llu steps, %llu compressed runs, %.3f body bytes/step, worst |t - T| = %.4f E\n",
      kRuns, static_cast<unsigned long long>(steps), static_cast<unsigned long long>(runs),
      static_cast<double>(bytes) / static_cast<double>(steps), worst_frac);
  EXPECT_GT(steps, 1000000u);
  EXPECT_LE(worst_frac, 1.0);
}

// Compresses the given exact times (in the generator's chunks, or one push() at a time) and
// checks every decoded step against its window, in order, with the same directions.
void check_stream(const std::vector<double>& t, const std::vector<int8_t>& d, double E,
                  uint32_t limit, bool one_at_a_time, double start) {
  Bodies sink;
  StepBatcher batcher;
  batcher.configure(0, 200, &sink);
  StepCompressor comp;
  comp.configure({E, limit}, &batcher);
  comp.reset(static_cast<int64_t>(start), start);
  if (one_at_a_time) {
    for (size_t i = 0; i < t.size(); ++i) comp.push(t[i], d[i]);
  } else {
    for (size_t i = 0; i < t.size(); i += 256)
      comp.on_steps(&t[i], &d[i], std::min<size_t>(256, t.size() - i));
  }
  comp.flush();
  batcher.flush();
  EXPECT_EQ(comp.stats().check_failures, 0u);
  EXPECT_EQ(comp.stats().window_violations, 0u);
  EXPECT_EQ(comp.stats().steps, t.size());
  EXPECT_LE(comp.stats().scanned, 17 * comp.stats().steps + 4096 * comp.stats().runs);
  std::vector<int64_t> clocks;
  std::vector<int8_t> dirs;
  ASSERT_TRUE(decode_bodies(sink, clocks, dirs)) << "malformed body or invalid run";
  ASSERT_EQ(clocks.size(), t.size());
  double prev_t = start, prev_clock = start;
  for (size_t i = 0; i < t.size(); ++i) {
    const double c = static_cast<double>(clocks[i]);
    ASSERT_GE(c, t[i] - std::min(E, 0.5 * (t[i] - prev_t))) << "step " << i;
    ASSERT_LE(c, t[i] + E) << "step " << i;
    ASSERT_GT(c, prev_clock) << "step " << i;
    ASSERT_EQ(dirs[i], d[i]) << "step " << i;
    prev_t = t[i];
    prev_clock = c;
  }
}

// Streams no generator makes: random intervals over six decades, exact quadratics (one run each
// until the limit), quadratics with jitter of +-E (every window's edge touched), runs of 2-tick
// steps, near-half-integer times, sudden jumps, direction flips. Tiny and large error bounds.
TEST(StepCompressorProperty, RandomAndAdversarialStreamsKeepTheBound) {
  std::mt19937_64 rng(987654321);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double errs[] = {1.0, 1.5, 3.0, 10.0, 100.0, 2000.0};
  const uint32_t limits[] = {2, 17, 255, 65535};
  for (int draw = 0; draw < 160; ++draw) {
    const double E = errs[draw % 6];
    const uint32_t limit = limits[(draw / 6) % 4];
    const double start = 1e6 * u01(rng);
    std::vector<double> t;
    std::vector<int8_t> d;
    double now = start;
    int8_t dir = 1;
    auto add = [&](double interval) {
      now += std::max(2.0, interval);
      t.push_back(now);
      d.push_back(dir);
    };
    while (t.size() < 20000) {
      const int kind = static_cast<int>(u01(rng) * 7);
      const int len = 1 + static_cast<int>(u01(rng) * 400);
      if (u01(rng) < 0.2) dir = static_cast<int8_t>(-dir);
      const double i0 = std::exp(std::log(2.0) + u01(rng) * std::log(1e6));
      const double a = (u01(rng) - 0.5) * 0.02 * i0;
      switch (kind) {
        case 0:  // random intervals
          for (int k = 0; k < len; ++k) add(std::exp(std::log(2.0) + u01(rng) * std::log(1e6)));
          break;
        case 1:  // an exact integer quadratic
          for (int k = 0; k < len; ++k) add(std::round(i0) + std::round(a) * k);
          break;
        case 2:  // a quadratic with jitter up to the bound
          for (int k = 0; k < len; ++k) add(i0 + a * k + E * (2.0 * u01(rng) - 1.0));
          break;
        case 3:  // 2-3 tick steps
          for (int k = 0; k < len; ++k) add(2.0 + u01(rng));
          break;
        case 4:  // times just off half-integers
          for (int k = 0; k < len; ++k) {
            add(i0);
            now = std::floor(now) + 0.5 + (u01(rng) - 0.5) * 1e-9;
            t.back() = now;
          }
          break;
        case 5:  // one jump
          add(1e7 * u01(rng));
          break;
        default:  // alternating long and short intervals
          for (int k = 0; k < len; ++k) add(k % 2 ? i0 : 2.0 + 0.1 * i0 * u01(rng));
          break;
      }
    }
    SCOPED_TRACE(::testing::Message() << "draw " << draw << " E " << E << " limit " << limit);
    check_stream(t, d, E, limit, draw % 5 == 0, start);
  }
}

// Long runs: a constant integer interval fits one (I, 0) for ever; runs stop at the count limit.
TEST(StepCompressorProperty, LongRunsStopAtTheCountLimit) {
  for (uint32_t limit : {1u, 1000u, 65535u}) {
    Bodies sink;
    StepBatcher batcher;
    batcher.configure(0, 200, &sink);
    StepCompressor comp;
    comp.configure({100.0, limit}, &batcher);
    std::vector<double> t(200000);
    std::vector<int8_t> d(t.size(), 1);
    for (size_t i = 0; i < t.size(); ++i) t[i] = 5000.0 * static_cast<double>(i + 1);
    for (size_t i = 0; i < t.size(); i += 256)
      comp.on_steps(&t[i], &d[i], std::min<size_t>(256, t.size() - i));
    comp.flush();
    EXPECT_EQ(comp.stats().steps, t.size());
    EXPECT_EQ(comp.stats().runs, (t.size() + limit - 1) / limit) << limit;
    EXPECT_EQ(comp.stats().check_failures, 0u);
  }
}

}  // namespace
}  // namespace feedloop::stepgen
