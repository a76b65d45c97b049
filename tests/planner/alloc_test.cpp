// The steady-state path (Interpreter::execute -> Planner::add_move -> lookahead -> profiles ->
// joint output) allocates nothing: global operator new is counted around 20000 moves, arcs
// included. Its own binary, since it replaces operator new.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "planner/interpreter.hpp"
#include "planner/joint_output.hpp"
#include "planner_test_util.hpp"

namespace {
std::atomic<long> g_news{0};
}

void* operator new(std::size_t n) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace feedloop::planner {
namespace {

struct Counting : MoveSink, JointSink {
  const JointEmitter* em = nullptr;
  long moves = 0, segments = 0;
  void on_move(const PlannedMove& m) override {
    ++moves;
    em->emit(m, *this);
  }
  void on_joint_segment(int, const JointSegment&) override { ++segments; }
};

void run_without_allocation(const PlannerConfig& cfg, double cx, double cy) {
  auto kin = make_kinematics(cfg);
  JointEmitter em(*kin, cfg.servo_period_s);
  Counting sink;
  sink.em = &em;
  Planner planner(cfg, sink);
  Interpreter in(cfg, *kin, planner);
  std::vector<gcode::Command> cmds;
  for (int i = 0; i < 20000; ++i) {
    const double a = 0.05 * i, r = 20.0 + 10.0 * std::sin(0.01 * i);
    gcode::Command c;
    c.letter = 'G';
    if (i % 500 == 499) {
      c.code = 2;  // an arc back to the same point: a full circle of segments
      c.set('I', 3.0);
      c.set('J', 0.0);
    } else {
      c.code = 1;
      c.set('X', cx + r * std::cos(a));
      c.set('Y', cy + r * std::sin(a));
      c.set('E', 0.02 * i);
      c.set('F', 3000.0 + 100.0 * (i % 50));
    }
    c.where.line = i + 1;
    cmds.push_back(c);
  }
  gcode::Command z;
  z.letter = 'G';
  z.code = 1;
  z.set('Z', 10.0);
  ASSERT_TRUE(in.execute(z));
  for (int i = 0; i < 1000; ++i) ASSERT_TRUE(in.execute(cmds[i]));  // warm-up
  const long before = g_news.load();
  for (size_t i = 1000; i < cmds.size(); ++i) ASSERT_TRUE(in.execute(cmds[i])) << i;
  planner.flush();
  const long allocations = g_news.load() - before;
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(sink.moves, 19000);
  EXPECT_GT(sink.segments, 4 * sink.moves);
}

TEST(PlannerAllocations, CartesianSteadyStateAllocatesNothing) {
  run_without_allocation(test::cartesian_config(), 110.0, 110.0);
}

TEST(PlannerAllocations, DeltaSteadyStateAllocatesNothing) {
  run_without_allocation(test::delta_config(), 0.0, 0.0);
}

}  // namespace
}  // namespace feedloop::planner
