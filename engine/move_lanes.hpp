// Batch mode's two step lanes, each stepped in order by whichever of two threads is free.
//
// A lane is a set of joints with its own stepper (joint segments -> exact step times ->
// compression -> batches): x and the extruder in one, y and z in the other. Each lane must see
// every planned move once, in order, and no two threads may step one lane at a time; apart from
// that, it does not matter which thread steps a lane. The moves wait in a ring that the reading
// thread fills; a lane's cursor is the next move it has not stepped. Either thread takes the free
// lane furthest behind, steps a chunk of its moves (the lock released meanwhile), and gives it
// back. The reading thread steps only when the ring is full (it is also the one that parses and
// plans); the helper thread steps whenever a lane has moves and is free.
//
// Why not one lane per thread (what batch mode did before): the work then splits evenly only
// while both threads get a core each. Beside another busy process, three runnable threads share
// two cores and one of ours runs half the time: with a fixed split the other one finished its
// half and waited (two threads took longer than one: docs/decisions.md, "Batch mode: two threads
// share the lanes"). With shared lanes, the thread that has a core steps both lanes while the
// other is off, up to the ring's length apart.
//
// Not for real-time paths: the threads block on a mutex and a condition variable (a chunk is
// ~64 moves, tens of microseconds of work, so the lock is taken rarely).
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

#include "planner/move.hpp"

namespace feedloop::engine {

// Stepper: anything with on_move(const planner::PlannedMove&).
template <class Stepper>
class MoveLanes {
 public:
  static constexpr size_t kLanes = 2;

  // capacity: moves the ring holds (rounded up to a power of two); publish_every: moves the
  // reading thread writes before it makes them visible to the steppers; chunk: moves a thread
  // steps on a lane before it gives the lane back.
  MoveLanes(std::array<Stepper*, kLanes> steppers, size_t capacity, size_t publish_every,
            size_t chunk)
      : ring_(std::bit_ceil(std::max<size_t>(capacity, 2))),
        mask_(ring_.size() - 1),
        publish_every_(std::clamp<size_t>(publish_every, 1, ring_.size())),
        chunk_(std::max<size_t>(chunk, 1)) {
    for (size_t l = 0; l < kLanes; ++l) lanes_[l].stepper = steppers[l];
    room_until_ = ring_.size();
  }
  ~MoveLanes() { finish(); }
  MoveLanes(const MoveLanes&) = delete;
  MoveLanes& operator=(const MoveLanes&) = delete;

  void start() {
    helper_ = std::thread([this] { helper_run(); });
  }

  // The reading thread. Steps lanes itself while the ring is full.
  void push(const planner::PlannedMove& m) {
    if (written_ == room_until_) make_room();
    ring_[written_ & mask_] = m;
    if (++written_ - published_ >= publish_every_) publish();
  }

  // The reading thread, at the end of input: every lane steps every move, then the helper ends.
  // The lanes' own end of input (their open runs) is the caller's, after this returns.
  void finish() {
    {
      std::unique_lock lk(mu_);
      if (closed_) return;
      head_ = published_ = written_;
      closed_ = true;
      cv_.notify_all();
      while (!all_stepped()) {
        if (!step_one_chunk(lk)) cv_.wait(lk);
      }
    }
    if (helper_.joinable()) helper_.join();
  }

  // Chunks each thread stepped (for the summary and the tests).
  uint64_t chunks_by_reader() const { return chunks_[0]; }
  uint64_t chunks_by_helper() const { return chunks_[1]; }

 private:
  struct Lane {
    Stepper* stepper = nullptr;
    uint64_t cursor = 0;  // next move to step (guarded by mu_)
    bool held = false;    // a thread is stepping it (guarded by mu_)
  };

  bool all_stepped() const {
    for (const Lane& l : lanes_)
      if (l.held || l.cursor != head_) return false;
    return true;
  }
  uint64_t slowest_cursor() const {
    uint64_t c = lanes_[0].cursor;
    for (const Lane& l : lanes_) c = std::min(c, l.cursor);
    return c;
  }

  // Makes the written moves visible; notes how far the reader may write without asking again.
  void publish() {
    std::lock_guard lk(mu_);
    head_ = published_ = written_;
    room_until_ = slowest_cursor() + ring_.size();
    cv_.notify_all();
  }

  void make_room() {
    std::unique_lock lk(mu_);
    head_ = published_ = written_;
    cv_.notify_all();
    for (;;) {
      room_until_ = slowest_cursor() + ring_.size();
      if (written_ < room_until_) return;
      if (!step_one_chunk(lk, 0)) cv_.wait(lk);
    }
  }

  // With the lock held: steps a chunk of the free lane furthest behind (the lock released while
  // it steps). False when no lane is free with moves to step.
  bool step_one_chunk(std::unique_lock<std::mutex>& lk, int who = 0) {
    Lane* lane = nullptr;
    for (Lane& l : lanes_)
      if (!l.held && l.cursor < head_ && (lane == nullptr || l.cursor < lane->cursor)) lane = &l;
    if (lane == nullptr) return false;
    lane->held = true;
    const uint64_t begin = lane->cursor, end = std::min<uint64_t>(head_, begin + chunk_);
    lk.unlock();
    for (uint64_t i = begin; i < end; ++i) lane->stepper->on_move(ring_[i & mask_]);
    lk.lock();
    lane->cursor = end;
    lane->held = false;
    ++chunks_[who];
    cv_.notify_all();
    return true;
  }

  void helper_run() {
    std::unique_lock lk(mu_);
    for (;;) {
      if (step_one_chunk(lk, 1)) continue;
      if (closed_ && all_stepped()) return;
      cv_.wait(lk);
    }
  }

  std::vector<planner::PlannedMove> ring_;
  const size_t mask_;
  const size_t publish_every_, chunk_;
  // The reading thread's own: moves written, the last published count, and how far it may write.
  uint64_t written_ = 0, published_ = 0, room_until_ = 0;
  // Guarded by mu_.
  uint64_t head_ = 0;  // moves the steppers may read
  bool closed_ = false;
  std::array<Lane, kLanes> lanes_{};
  std::array<uint64_t, 2> chunks_{};
  std::mutex mu_;
  std::condition_variable cv_;
  std::thread helper_;
};

}  // namespace feedloop::engine
