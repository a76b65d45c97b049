// engine/move_lanes.hpp: each lane steps every move once and in order, whichever thread steps it,
// with a ring far shorter than the input (so the reading thread has to step lanes too).
#include "engine/move_lanes.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <vector>

namespace feedloop::engine {
namespace {

struct RecordingStepper {
  std::vector<uint64_t> seen;
  std::chrono::microseconds work{0};
  void on_move(const planner::PlannedMove& m) {
    if (work.count() > 0 && m.index % 97 == 0) std::this_thread::sleep_for(work);
    seen.push_back(m.index);
  }
};

void expect_in_order(const RecordingStepper& s, uint64_t moves) {
  ASSERT_EQ(s.seen.size(), moves);
  for (uint64_t i = 0; i < moves; ++i) ASSERT_EQ(s.seen[i], i) << "at " << i;
}

TEST(MoveLanes, EachLaneStepsEveryMoveOnceInOrder) {
  constexpr uint64_t kMoves = 20000;
  RecordingStepper a, b;
  b.work = std::chrono::microseconds(50);  // one lane slower: the lanes drift apart
  uint64_t by_reader = 0, by_helper = 0;
  {
    MoveLanes<RecordingStepper> lanes({&a, &b}, 64, 8, 16);
    lanes.start();
    planner::PlannedMove m;
    for (uint64_t i = 0; i < kMoves; ++i) {
      m.index = i;
      lanes.push(m);
    }
    lanes.finish();
    by_reader = lanes.chunks_by_reader();
    by_helper = lanes.chunks_by_helper();
  }
  expect_in_order(a, kMoves);
  expect_in_order(b, kMoves);
  // Every chunk is at most 16 moves of one lane, so at least 2 * 20000 / 16 chunks.
  EXPECT_GE(by_reader + by_helper, 2 * kMoves / 16);
  EXPECT_GT(by_helper, 0u);
  EXPECT_GT(by_reader, 0u) << "a ring of 64 moves and 20000 moves: the reader had to step";
}

TEST(MoveLanes, FinishWithoutMovesAndTwiceIsHarmless) {
  RecordingStepper a, b;
  MoveLanes<RecordingStepper> lanes({&a, &b}, 16, 4, 4);
  lanes.start();
  lanes.finish();
  lanes.finish();
  EXPECT_TRUE(a.seen.empty());
  EXPECT_TRUE(b.seen.empty());
}

// A partly filled ring (fewer moves than one publication) still reaches both lanes at the end.
TEST(MoveLanes, TheLastUnpublishedMovesAreSteppedAtTheEnd) {
  RecordingStepper a, b;
  MoveLanes<RecordingStepper> lanes({&a, &b}, 1024, 64, 64);
  lanes.start();
  planner::PlannedMove m;
  for (uint64_t i = 0; i < 5; ++i) {
    m.index = i;
    lanes.push(m);
  }
  lanes.finish();
  expect_in_order(a, 5);
  expect_in_order(b, 5);
}

}  // namespace
}  // namespace feedloop::engine
