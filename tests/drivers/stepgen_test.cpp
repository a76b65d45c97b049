// Step generation and compression: exact step times, the step-time error bound of the
// compressed runs after a full encode/decode round trip, bytes per step.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <new>
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
  StepSink* next = nullptr;
  void on_steps(const double* t, const int8_t* d, size_t n) override {
    ticks.insert(ticks.end(), t, t + n);
    dirs.insert(dirs.end(), d, d + n);
    if (next) next->on_steps(t, d, n);
  }
};

struct BatchCollector final : BatchSink {
  std::vector<std::vector<uint8_t>> bodies;
  uint64_t bytes = 0;
  void on_batch(const StepBatch& b) override {
    bodies.emplace_back(b.body, b.body + b.body_bytes);
    bytes += b.body_bytes;
  }
};

// Decodes every batch body and expands the runs with the MCU step law.
void decode_all(const BatchCollector& c, std::vector<int64_t>& clocks, std::vector<int8_t>& dirs) {
  for (const auto& body : c.bodies) {
    RunDecoder dec;
    ASSERT_TRUE(dec.begin(body.data(), body.size()));
    int64_t p = dec.first_clock();
    while (!dec.done()) {
      StepRun r;
      ASSERT_TRUE(dec.next(r));
      for (uint32_t k = 1; k <= r.count; ++k) {
        clocks.push_back(run_step_clock(p, r, k));
        dirs.push_back(r.direction);
      }
      p = run_end_clock(p, r);
    }
  }
}

struct RoundTrip {
  double max_err_ticks = 0.0;
  double bytes_per_step = 0.0;
  size_t steps = 0;
  StepCompressorStats stats;
};

RoundTrip round_trip(const std::vector<JointSegment>& segs, double steps_per_mm, double max_err_us) {
  const TickMap map{1000.0, 20e6};
  BatchCollector col;
  StepBatcher batcher;
  batcher.configure(0, 200, &col);
  StepCompressor comp;
  comp.configure({max_err_us * 20.0, 65535}, &batcher);
  Recorder rec;
  rec.next = &comp;
  StepGenerator gen;
  gen.configure(steps_per_mm, map, &rec);
  gen.set_position_mm(segs.front().c0_mm);
  for (const auto& s : segs) gen.add_segment(s);
  gen.flush();
  comp.flush();
  batcher.flush();
  std::vector<int64_t> clocks;
  std::vector<int8_t> dirs;
  decode_all(col, clocks, dirs);
  RoundTrip r;
  r.steps = rec.ticks.size();
  EXPECT_EQ(clocks.size(), rec.ticks.size());
  EXPECT_EQ(dirs, rec.dirs);
  for (size_t i = 0; i < std::min(clocks.size(), rec.ticks.size()); ++i)
    r.max_err_ticks = std::max(r.max_err_ticks, std::fabs(static_cast<double>(clocks[i]) - rec.ticks[i]));
  for (size_t i = 1; i < clocks.size(); ++i) EXPECT_GT(clocks[i], clocks[i - 1]) << "at step " << i;
  r.bytes_per_step = static_cast<double>(col.bytes) / std::max<size_t>(1, r.steps);
  r.stats = comp.stats();
  return r;
}

// Every emitted step lies on a half-integer threshold of s(t) and the count matches s(end).
void check_exact(const std::vector<JointSegment>& segs, double spm) {
  Recorder rec;
  StepGenerator gen;
  gen.configure(spm, TickMap{0.0, 1.0}, &rec);  // ticks == seconds
  gen.set_position_mm(segs.front().c0_mm);
  int64_t n = std::llround(segs.front().c0_mm * spm);
  size_t si = 0, checked = 0;
  for (const auto& s : segs) {
    gen.add_segment(s);
    gen.flush();
    for (; si < rec.ticks.size(); ++si) {
      const double t = rec.ticks[si];
      ASSERT_GE(t, s.t0_s - 1e-12);
      ASSERT_LE(t, s.end_s() + 1e-12);
      const double thr = static_cast<double>(n) + 0.5 * rec.dirs[si];
      n += rec.dirs[si];
      const double err_steps = std::fabs(s.position_mm(t) * spm - thr);
      const double v = std::fabs(s.velocity_mm_s(t) * spm);
      // Time error = position error / speed; near a turning point use the position error.
      const double time_err = v > 1.0 ? err_steps / v : 0.0;
      ASSERT_LT(time_err, 1e-9) << "step " << si;
      ASSERT_LT(err_steps, 1e-3) << "step " << si;
      ++checked;
    }
    ASSERT_EQ(n, gen.position_steps());
  }
  const auto& last = segs.back();
  EXPECT_NEAR(static_cast<double>(gen.position_steps()), last.position_mm(last.end_s()) * spm, 0.5 + 1e-9);
  EXPECT_GT(checked, 100u);
}

TEST(StepGenerator, QuadraticStepsAreExact) {
  std::mt19937_64 rng(1);
  check_exact(testing::trapezoid_stream(rng, 200), 80.0);
}

TEST(StepGenerator, ReversalsAreExact) {
  std::mt19937_64 rng(2);
  check_exact(testing::reversal_stream(rng, 500), 80.0);
}

TEST(StepGenerator, CubicStepsAreExact) {
  std::mt19937_64 rng(3);
  check_exact(testing::cubic_stream(rng, 3000), 160.0);
}

TEST(StepCompressor, ErrorBoundHoldsOnTrapezoidMoves) {
  std::mt19937_64 rng(4);
  const auto segs = testing::trapezoid_stream(rng, 400);
  for (double err_us : {5.0, 25.0, 1.0}) {
    const RoundTrip r = round_trip(segs, 80.0, err_us);
    std::printf(
        "trapezoid %4.0f us: %zu steps, max err %.2f us, %.3f B/step, %llu runs, %.2f "
        "searches/run, "
        "%.2f trials/search\n",
        err_us, r.steps, r.max_err_ticks / 20.0, r.bytes_per_step, (unsigned long long)r.stats.runs,
        double(r.stats.searches) / double(r.stats.runs),
        double(r.stats.trials) / double(r.stats.searches));
    EXPECT_GT(r.steps, 10000u);
    EXPECT_LE(r.max_err_ticks, err_us * 20.0);
    EXPECT_EQ(r.stats.check_failures, 0u);
    EXPECT_EQ(r.stats.window_violations, 0u);
    // Searches check their candidates against the run's steps: about once per step on printing
    // moves (1.1 on bench_stepgen's stream), not once per search per step.
    EXPECT_LE(static_cast<double>(r.stats.scanned), 3.0 * static_cast<double>(r.steps));
    if (err_us == 5.0) {
      EXPECT_LE(r.bytes_per_step, 1.0);
    }
  }
}

TEST(StepCompressor, ErrorBoundHoldsWithReversals) {
  std::mt19937_64 rng(5);
  const auto segs = testing::reversal_stream(rng, 2000);
  const RoundTrip r = round_trip(segs, 80.0, 5.0);
  std::printf("reversals: %zu steps, max err %.2f us, %.3f B/step\n", r.steps, r.max_err_ticks / 20.0,
              r.bytes_per_step);
  EXPECT_GT(r.steps, 1000u);
  EXPECT_LE(r.max_err_ticks, 100.0);
  EXPECT_EQ(r.stats.check_failures, 0u);
}

TEST(StepCompressor, ErrorBoundHoldsOnCubicPieces) {
  std::mt19937_64 rng(6);
  const auto segs = testing::cubic_stream(rng, 20000);
  const RoundTrip r = round_trip(segs, 160.0, 5.0);
  std::printf("cubic: %zu steps, max err %.2f us, %.3f B/step\n", r.steps, r.max_err_ticks / 20.0,
              r.bytes_per_step);
  EXPECT_GT(r.steps, 10000u);
  EXPECT_LE(r.max_err_ticks, 100.0);
  EXPECT_EQ(r.stats.check_failures, 0u);
}

TEST(StepCompressor, VerySlowAndVeryFastMoves) {
  std::vector<JointSegment> segs;
  double t = 0.0, pos = 0.0;
  testing::append_trapezoid(segs, t, pos, 0.3, 0.01, 100.0);     // 0.01 mm/s: 2.5 s per step
  testing::append_trapezoid(segs, t, pos, -200.0, 1000.0, 50000.0);  // 80 kHz step rate
  testing::append_trapezoid(segs, t, pos, 50.0, 2000.0, 100000.0);   // 160 kHz
  const RoundTrip r = round_trip(segs, 80.0, 5.0);
  EXPECT_EQ(r.steps, static_cast<size_t>(std::llround(0.3 * 80) + 200 * 80 + 50 * 80));
  EXPECT_LE(r.max_err_ticks, 100.0);
  EXPECT_EQ(r.stats.check_failures, 0u);
}

TEST(RunCodec, RejectsTruncatedInput) {
  uint8_t buf[64];
  RunEncoder enc;
  ASSERT_TRUE(enc.begin(buf, sizeof buf, 123456789));
  ASSERT_TRUE(enc.append({2500, -3, 17, -1}));
  RunDecoder dec;
  ASSERT_TRUE(dec.begin(buf, enc.size() - 1));
  StepRun r;
  EXPECT_FALSE(dec.next(r));
  ASSERT_TRUE(dec.begin(buf, enc.size()));
  ASSERT_TRUE(dec.next(r));
  EXPECT_EQ(r.interval_ticks, 2500);
  EXPECT_EQ(r.add_ticks, -3);
  EXPECT_EQ(r.count, 17u);
  EXPECT_EQ(r.direction, -1);
}

}  // namespace
}  // namespace feedloop::stepgen

// ---- RT discipline: the step path allocates nothing in steady state (STYLE.md convention 6).
namespace {
std::atomic<uint64_t> g_allocations{0};
}  // namespace
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace feedloop::stepgen {
namespace {

struct CountingSink final : BatchSink {
  uint64_t bytes = 0;
  void on_batch(const StepBatch& b) override { bytes += b.body_bytes; }
};

TEST(StepPath, NoAllocationInSteadyState) {
  std::mt19937_64 rng(8);
  const auto segs = testing::trapezoid_stream(rng, 300);
  const auto cubic = testing::cubic_stream(rng, 3000);
  CountingSink sink;
  StepBatcher batcher;
  batcher.configure(0, 200, &sink);
  StepCompressor comp;
  comp.configure({100.0, 65535}, &batcher);
  StepGenerator gen;
  gen.configure(80.0, TickMap{0.0, 20e6}, &comp);
  const uint64_t before = g_allocations.load();
  for (const auto& s : segs) gen.add_segment(s);
  JointSegment c0 = cubic.front();
  const double shift = segs.back().end_s() - c0.t0_s, dpos = segs.back().position_mm(segs.back().end_s()) - c0.c0_mm;
  for (auto c : cubic) {
    c.t0_s += shift;
    c.c0_mm += dpos;
    gen.add_segment(c);
    comp.flush_if_due(static_cast<int64_t>(c.t0_s * 20e6));
  }
  gen.flush();
  comp.flush();
  batcher.flush();
  const uint64_t allocations = g_allocations.load() - before;
  EXPECT_GT(sink.bytes, 1000u);
  EXPECT_GT(gen.steps_emitted(), 100000u);
  EXPECT_EQ(allocations, 0u);
}

}  // namespace
}  // namespace feedloop::stepgen

#include "drivers/stepgen/axis_stepper.hpp"

namespace feedloop::stepgen {
namespace {

TEST(AxisStepper, SameStepsAsThePiecesAndDueFlushesKeepTheBound) {
  std::mt19937_64 rng(9);
  const auto segs = testing::trapezoid_stream(rng, 100);
  BatchCollector col;
  AxisStepper ax;
  const TickMap map{0.0, 20e6};
  ax.configure(2, 80.0, {}, map, &col);
  ax.start_at(0.0);
  for (const auto& s : segs) {
    ax.add_segment(s);
    ax.flush_due(static_cast<int64_t>(map.ticks(s.t0_s)));  // closes runs as time passes
  }
  ax.finish();
  std::vector<int64_t> clocks;
  std::vector<int8_t> dirs;
  decode_all(col, clocks, dirs);
  // Reference: the exact times from a bare generator.
  Recorder rec;
  StepGenerator gen;
  gen.configure(80.0, map, &rec);
  for (const auto& s : segs) gen.add_segment(s);
  gen.flush();
  ASSERT_EQ(clocks.size(), rec.ticks.size());
  EXPECT_EQ(ax.steps(), rec.ticks.size());
  double max_err = 0;
  for (size_t i = 0; i < clocks.size(); ++i) max_err = std::max(max_err, std::fabs(clocks[i] - rec.ticks[i]));
  EXPECT_LE(max_err, 100.0);
  EXPECT_EQ(dirs, rec.dirs);
  EXPECT_EQ(ax.body_bytes(), col.bytes);
}

}  // namespace
}  // namespace feedloop::stepgen
