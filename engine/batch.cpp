// Batch mode (see batch.hpp). The driver is the daemon's: each command goes through
// engine::Machine's planner stage (Machine::execute_inline: the same dispatch the planner thread
// runs, heaters and waits included) into a BatchExecutor, the executor without a servo stage:
// interpreter -> lookahead -> joint segments -> steps, as fast as the CPU allows.
// Threads: the calling thread reads, parses, plans and, with one thread, steps every joint. With
// two, the joints are two lanes, each with its own JointEmitter and StepPipeline (joint_mask),
// and the planned moves wait in a ring from which either thread steps whichever lane is free and
// furthest behind (engine/move_lanes.hpp). Every lane closes runs on the same schedule (every 64
// of its moves), so the output does not depend on threading.
#include "engine/batch.hpp"

#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <thread>

#include "core/allowed_cores.hpp"
#include "core/clock.hpp"
#include "drivers/protocol/frame.hpp"
#include "engine/machine.hpp"
#include "engine/move_lanes.hpp"
#include "gcode/file_lines.hpp"
#include "gcode/line_splitter.hpp"
#include "gcode/parser.hpp"
#include "planner/interpreter.hpp"
#include "planner/kinematics.hpp"
#include "planner/pressure_advance.hpp"

namespace feedloop::engine {
namespace {

// With two threads, the joints are two lanes (engine/move_lanes.hpp) that either thread steps.
constexpr unsigned kMainJoints = 0x6u;    // y (or B) and z (or C)
constexpr unsigned kWorkerJoints = 0x9u;  // x (or A) and the extruder
constexpr size_t kRingMoves = 4096;       // moves the lanes may be apart (~1.7 MB)
constexpr size_t kPublishMoves = 64;      // moves the reading thread hands over at a time
constexpr size_t kChunkMoves = 64;        // moves a thread steps on a lane at a time

double process_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Joint segments of the owned joints -> optional tap -> step pipeline.
class SegmentFanout final : public planner::JointSink {
 public:
  SegmentFanout(StepPipeline& steps, planner::JointSink* tap) : steps_(steps), tap_(tap) {}
  void on_joint_segment(int joint, const JointSegment& segment) override {
    if (!steps_.owns(joint)) return;
    if (tap_ != nullptr) tap_->on_joint_segment(joint, segment);
    steps_.on_joint_segment(joint, segment);
  }

 private:
  StepPipeline& steps_;
  planner::JointSink* tap_;
};

// Planned moves -> joint segments -> one step pipeline (one thread's share of the joints).
// Pressure advance (planner/pressure_advance.hpp) as in the daemon's exact path: on when the
// first move has K > 0 (batch mode is one motion from rest); the extruder's segments then come
// from the advance, h behind the newest move, and its tail at the end.
class MoveStepper {
 public:
  MoveStepper(const planner::Kinematics& kin, double period_s, StepPipeline& steps,
              planner::JointSink* tap)
      : kin_(kin),
        emitter_(kin, period_s),
        steps_(steps),
        fanout_(steps, tap),
        period_s_(period_s) {
    no_extruder_.next = &fanout_;
  }
  void on_move(const planner::PlannedMove& m) {
    if (m.index == 0) {
      // The step streams start where the first move starts (a delta's carriages are hundreds
      // of mm up at the home position; starting them at 0 made the first segment a jump).
      const planner::Joints q = kin_.inverse({m.start_mm[0], m.start_mm[1], m.start_mm[2]});
      for (int j = 0; j < 3; ++j) steps_.set_position_mm(j, q[static_cast<size_t>(j)]);
      steps_.set_position_mm(3, m.start_mm[planner::kE]);
      pa_on_ = steps_.owns(3) && m.pressure_advance_s > 0.0;
      if (pa_on_) {
        pa_ = std::make_unique<planner::PressureAdvance>();
        pa_->restart(m.start_mm[planner::kE], m.pressure_advance_smooth_time_s);
        pa_->set_emitted_from(m.start_time_s - pa_->half_window_s());
      }
    }
    if (pa_on_) {
      emitter_.emit(m, no_extruder_);
      pa_->push(m);
      emit_extruder(pa_->input_end_s() - pa_->half_window_s());
    } else {
      emitter_.emit(m, fanout_);
    }
    if (++since_flush_ >= 64) {  // close runs that are complete well behind the newest move
      steps_.flush_due(m.start_time_s - 0.5);
      since_flush_ = 0;
    }
  }
  // End of input: the extruder's advance returns to rest after the last move.
  void finish() {
    if (pa_on_) emit_extruder(pa_->input_end_s() + pa_->half_window_s());
  }

 private:
  void emit_extruder(double until_s) {
    pa_->emit_until(until_s, period_s_,
                    [this](const JointSegment& s) { fanout_.on_joint_segment(3, s); });
    pa_->trim_before(pa_->emitted_until_s());
  }
  struct NoExtruder final : planner::JointSink {
    planner::JointSink* next = nullptr;
    void on_joint_segment(int joint, const JointSegment& s) override {
      if (joint != 3) next->on_joint_segment(joint, s);
    }
  };
  const planner::Kinematics& kin_;
  planner::JointEmitter emitter_;
  StepPipeline& steps_;
  SegmentFanout fanout_;
  NoExtruder no_extruder_;
  double period_s_;
  bool pa_on_ = false;
  std::unique_ptr<planner::PressureAdvance> pa_;
  int since_flush_ = 0;
};

// Planner output: counted, then stepped here (one thread) or handed to the lanes (two).
class MoveDispatch final : public planner::MoveSink {
 public:
  MoveDispatch(MoveStepper& local, bool step) : local_(local), step_(step) {}
  void set_lanes(MoveLanes<MoveStepper>* lanes) { lanes_ = lanes; }
  void on_move(const planner::PlannedMove& m) override {
    ++moves;
    if (!step_) return;
    if (lanes_ != nullptr)
      lanes_->push(m);
    else
      local_.on_move(m);
  }
  uint64_t moves = 0;

 private:
  MoveStepper& local_;
  MoveLanes<MoveStepper>* lanes_ = nullptr;
  bool step_;
};

struct CountingBatchSink final : stepgen::BatchSink {
  stepgen::BatchSink* tap = nullptr;
  void on_batch(const stepgen::StepBatch& b) override {
    if (tap != nullptr) tap->on_batch(b);
  }
};

// The planner stage's back end in batch mode: what MotionExecutor does on the planner thread
// (interpreter, lookahead, joint segments), with the steps made at once instead of by a servo
// stage on a clock.
class BatchExecutor final : public CommandExecutor {
 public:
  BatchExecutor(const planner::PlannerConfig& pcfg, const StepPipelineParams& sp, bool threaded,
                bool step, const BatchOptions& options)
      : kin_(planner::make_kinematics(pcfg)),
        steps_(sp, &batches_),
        local_(*kin_, pcfg.servo_period_s, steps_, options.segment_tap),
        dispatch_(local_, step),
        planner_(pcfg, dispatch_),
        interp_(pcfg, *kin_, planner_) {
    batches_.tap = worker_batches_.tap = options.batch_tap;
    if (threaded) {
      StepPipelineParams wp = sp;
      wp.joint_mask = kWorkerJoints;
      worker_steps_ = std::make_unique<StepPipeline>(wp, &worker_batches_);
      worker_local_ = std::make_unique<MoveStepper>(*kin_, pcfg.servo_period_s, *worker_steps_,
                                                    options.segment_tap);
      lanes_ = std::make_unique<MoveLanes<MoveStepper>>(
          std::array<MoveStepper*, 2>{worker_local_.get(), &local_}, kRingMoves, kPublishMoves,
          kChunkMoves);
      dispatch_.set_lanes(lanes_.get());
      lanes_->start();
    }
  }
  Status execute(const gcode::Command& cmd, const std::atomic<bool>& /*cancel*/) override {
    return interp_.execute(cmd);
  }
  void position(double out_mm[4]) const override {
    const planner::Vec4& p = interp_.state().logical_mm;
    for (int i = 0; i < 4; ++i) out_mm[i] = p[static_cast<size_t>(i)];
  }
  // End of input: the lookahead's tail, every lane's moves, the open runs.
  void finish() {
    planner_.flush();
    if (lanes_) {
      lanes_->finish();
      worker_local_->finish();
      worker_steps_->flush();
    }
    local_.finish();
    steps_.flush();
  }
  uint64_t moves() const { return dispatch_.moves; }
  double print_time_s() const { return planner_.print_time_s(); }
  const StepPipeline& owner(int joint) const {
    return steps_.owns(joint) ? steps_ : *worker_steps_;
  }

 private:
  std::unique_ptr<planner::Kinematics> kin_;
  CountingBatchSink batches_, worker_batches_;
  StepPipeline steps_;
  MoveStepper local_;
  std::unique_ptr<StepPipeline> worker_steps_;
  std::unique_ptr<MoveStepper> worker_local_;
  std::unique_ptr<MoveLanes<MoveStepper>> lanes_;
  MoveDispatch dispatch_;
  planner::Planner planner_;
  planner::Interpreter interp_;
};

}  // namespace

Result<BatchSummary> run_batch(const std::string& gcode_path, const config::MachineConfig& cfg,
                               const BatchOptions& options) {
  // The size for progress only: a pipe (`feedloop batch <(zcat f.gcode.gz)`) has none and is
  // read to its end all the same.
  std::error_code size_error;
  const auto size = std::filesystem::file_size(gcode_path, size_error);
  const double file_bytes = size_error ? 0.0 : static_cast<double>(size);
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = process_cpu_s();

  const planner::PlannerConfig pcfg = planner_config(cfg);
  if (Status s = pcfg.validate(); !s) return s.error();
  const int threads =
      options.threads == 0 ? (core::allowed_cores() >= 2 ? 2 : 1) : std::min(options.threads, 2);
  const bool threaded = threads >= 2 && options.last_stage >= BatchStage::step_times;
  StepPipelineParams sp;
  sp.steps_per_mm = steps_per_mm(cfg);
  sp.mcu_clock_hz = static_cast<double>(cfg.stepgen.mcu_clock_hz);
  sp.max_step_error_us = cfg.stepgen.max_step_error_us;
  sp.joint_mask = threaded ? kMainJoints : (kMainJoints | kWorkerJoints);
  sp.compress = options.last_stage >= BatchStage::compression;
  sp.encode = options.last_stage >= BatchStage::output;
  auto owned = std::make_unique<BatchExecutor>(
      pcfg, sp, threaded, options.last_stage >= BatchStage::step_times, options);
  BatchExecutor& exec = *owned;
  VirtualClock clock;  // batch mode has no servo stage: nothing advances it
  MachineOptions mo;
  mo.servo_rate_hz = 1.0 / pcfg.servo_period_s;
  Machine machine(mo, clock, std::move(owned));

  BatchSummary sum;
  sum.file = gcode_path;
  sum.joint_names = joint_names(cfg);
  gcode::Command cmd;
  SourceLocation where{gcode_path, 0, 0};
  auto note = [&](const std::string& msg) {
    if (sum.messages.size() < options.max_messages) sum.messages.push_back(msg);
  };
  auto on_line = [&](const gcode::SplitLine& l) {
    ++sum.lines;
    where.line = static_cast<int>(l.number);
    if (l.too_long) {
      ++sum.rejected;
      note(where.to_string() + ": line too long (" + std::to_string(l.length_bytes) + " bytes)");
      return;
    }
    if (Status s = gcode::parse_line(l.text, where, cmd); !s) {
      ++sum.rejected;
      note(s.error().to_string());
      return;
    }
    if (cmd.empty()) return;
    ++sum.commands;
    if (cmd.unknown) ++sum.unknown_commands;
    if (options.last_stage == BatchStage::parse) return;
    if (Status s = machine.execute_inline(cmd); !s) {
      ++sum.rejected;
      note(s.error().to_string());
    }
  };
  double read_bytes = 0;
  const Status read = gcode::for_each_file_line_reporting(gcode_path, on_line, [&](size_t got) {
    read_bytes += static_cast<double>(got);
    if (options.on_progress)
      options.on_progress(file_bytes > 0 ? std::min(1.0, read_bytes / file_bytes) : 1.0);
  });
  if (!read) return read.error();
  exec.finish();

  sum.moves = exec.moves();
  sum.print_time_s = exec.print_time_s();
  for (int j = 0; j < kJoints; ++j) {
    const StepPipeline& owner = exec.owner(j);
    sum.joints[static_cast<size_t>(j)] = owner.stats(j);
    const JointStepStats& s = sum.joints[static_cast<size_t>(j)];
    sum.total_steps += s.steps;
    sum.check_failures += s.check_failures;
    // Each batch travels as one QUEUE_STEPS message (type + axis bytes) in one frame.
    sum.wire_bytes += s.body_bytes + s.batches * (2 + protocol::kFrameOverhead);
  }
  sum.wire_bytes_per_step =
      sum.total_steps ? static_cast<double>(sum.wire_bytes) / static_cast<double>(sum.total_steps)
                      : 0.0;
  sum.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  sum.cpu_s = process_cpu_s() - cpu0;
  sum.threads = threaded ? 2 : 1;
  return sum;
}

}  // namespace feedloop::engine
