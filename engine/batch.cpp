#include "engine/batch.hpp"

#include <chrono>
#include <cstdio>
#include <fstream>

#include "drivers/protocol/frame.hpp"
#include "gcode/line_splitter.hpp"
#include "gcode/parser.hpp"
#include "planner/interpreter.hpp"
#include "planner/kinematics.hpp"

namespace feedloop::engine {
namespace {

// Planner output -> joint segments -> step pipeline.
class MovesToSteps final : public planner::MoveSink {
 public:
  MovesToSteps(const planner::Kinematics& kin, double period_s, StepPipeline& steps)
      : emitter_(kin, period_s), steps_(steps) {}
  void on_move(const planner::PlannedMove& m) override {
    emitter_.emit(m, steps_);
    ++moves;
    if (++since_flush_ >= 64) {  // close runs that are complete well behind the newest move
      steps_.flush_due(m.start_time_s - 0.5);
      since_flush_ = 0;
    }
  }
  uint64_t moves = 0;

 private:
  planner::JointEmitter emitter_;
  StepPipeline& steps_;
  int since_flush_ = 0;
};

struct CountingBatchSink final : stepgen::BatchSink {
  void on_batch(const stepgen::StepBatch&) override {}
};

}  // namespace

Result<BatchSummary> run_batch(const std::string& gcode_path, const config::MachineConfig& cfg,
                               const BatchOptions& options) {
  std::ifstream in(gcode_path, std::ios::binary);
  if (!in) return Error{"cannot open " + gcode_path};
  in.seekg(0, std::ios::end);
  const auto file_bytes = static_cast<double>(in.tellg());
  in.seekg(0);
  const auto t0 = std::chrono::steady_clock::now();

  const planner::PlannerConfig pcfg = planner_config(cfg);
  if (Status s = pcfg.validate(); !s) return s.error();
  const auto kin = planner::make_kinematics(pcfg);
  StepPipelineParams sp;
  sp.steps_per_mm = steps_per_mm(cfg);
  sp.mcu_clock_hz = static_cast<double>(cfg.stepgen.mcu_clock_hz);
  sp.max_step_error_us = cfg.stepgen.max_step_error_us;
  CountingBatchSink batches;
  StepPipeline steps(sp, &batches);
  MovesToSteps sink(*kin, pcfg.servo_period_s, steps);
  planner::Planner planner(pcfg, sink);
  planner::Interpreter interp(pcfg, *kin, planner);

  BatchSummary sum;
  sum.file = gcode_path;
  sum.joint_names = joint_names(cfg);
  gcode::LineSplitter splitter;
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
    if (Status s = interp.execute(cmd); !s) {
      ++sum.rejected;
      note(s.error().to_string());
    }
  };
  std::vector<char> buf(1 << 20);
  double read_bytes = 0;
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    const auto got = static_cast<size_t>(in.gcount());
    if (got == 0) break;
    splitter.feed(std::string_view(buf.data(), got), on_line);
    read_bytes += static_cast<double>(got);
    if (options.on_progress) options.on_progress(file_bytes > 0 ? read_bytes / file_bytes : 1.0);
  }
  splitter.finish(on_line);
  planner.flush();
  steps.flush();

  sum.moves = sink.moves;
  sum.print_time_s = planner.print_time_s();
  for (int j = 0; j < kJoints; ++j) {
    sum.joints[static_cast<size_t>(j)] = steps.stats(j);
    const JointStepStats& s = sum.joints[static_cast<size_t>(j)];
    sum.total_steps += s.steps;
    sum.check_failures += s.check_failures;
    // Each batch travels as one QUEUE_STEPS message (type + axis bytes) in one frame.
    sum.wire_bytes += s.body_bytes + s.batches * (2 + protocol::kFrameOverhead);
  }
  sum.wire_bytes_per_step =
      sum.total_steps ? static_cast<double>(sum.wire_bytes) / static_cast<double>(sum.total_steps) : 0.0;
  sum.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return sum;
}

}  // namespace feedloop::engine
