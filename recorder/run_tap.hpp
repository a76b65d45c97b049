// Taps for the engine: a stepgen::RunSink that records every compressed run and forwards it, and
// a planner::MoveSink that records every final move and forwards it. Insert them into the existing
// chains (compressor -> RunTap -> batcher; lookahead -> MoveTap -> executor) so that what is
// recorded is exactly what is sent. Real-time safe (RecordWriter calls only).
#pragma once

#include "drivers/stepgen/step_run.hpp"
#include "planner/move.hpp"
#include "recorder/record_writer.hpp"

namespace feedloop::recorder {

class RunTap final : public stepgen::RunSink {
 public:
  RunTap(RecordWriter* writer, int joint, stepgen::RunSink* next) : writer_(writer), joint_(joint), next_(next) {}
  void on_run(int64_t start_clock, const stepgen::StepRun& run) override {
    if (writer_) writer_->step_run(joint_, start_clock, run);
    if (next_) next_->on_run(start_clock, run);
  }

 private:
  RecordWriter* writer_;
  int joint_;
  stepgen::RunSink* next_;
};

class MoveTap final : public planner::MoveSink {
 public:
  MoveTap(RecordWriter* writer, planner::MoveSink* next) : writer_(writer), next_(next) {}
  void on_move(const planner::PlannedMove& move) override {
    if (writer_) writer_->move(move);
    if (next_) next_->on_move(move);
  }
  void on_event(const planner::PlannerEvent& event) override {
    if (next_) next_->on_event(event);
  }

 private:
  RecordWriter* writer_;
  planner::MoveSink* next_;
};

}  // namespace feedloop::recorder
