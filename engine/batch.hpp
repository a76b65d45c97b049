// Batch mode: a whole G-code file through the pipeline in virtual time, without hardware
// (`feedloop batch FILE --config CFG`). Parser -> interpreter -> lookahead -> joint segments ->
// step generation -> compression -> batches, against an ideal plant (the batches are encoded and
// counted, as Klipper's batch mode writes its MCU commands to a file).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "core/result.hpp"
#include "engine/step_pipeline.hpp"

namespace feedloop::engine {

// How far batch mode takes the file, for bench/batch's time per stage: parse the lines; also
// plan the moves; also compute every exact step time; also compress them into runs; also encode
// the runs into QUEUE_STEPS batches (everything: the only stage with complete output).
enum class BatchStage { parse, plan, step_times, compression, output };

struct BatchOptions {
  // Called now and then with the fraction of the file read (0..1).
  std::function<void(double fraction)> on_progress;
  size_t max_messages = 20;  // warnings kept in the summary
  // 2: the reading thread parses and plans; joints 0 and 3, and joints 1 and 2, are two lanes
  // that the reading thread and a helper step, whichever is free (engine/move_lanes.hpp).
  // 1: everything on the calling thread. 0 (auto): 2 when the process may run on two cores or
  // more (core/allowed_cores.hpp), also beside other busy processes, else 1. The runs, batches
  // and statistics are bit-identical either way.
  int threads = 0;
  BatchStage last_stage = BatchStage::output;
  // Test taps, both optional. Each is called from a thread that steps the joint concerned, never
  // from two at once for the same joint (with two threads, either may step a joint, one after
  // the other): keep per-joint state apart.
  planner::JointSink* segment_tap = nullptr;  // every joint segment before step generation
  stepgen::BatchSink* batch_tap = nullptr;    // every QUEUE_STEPS batch body
};

struct BatchSummary {
  std::string file;
  int64_t lines = 0;
  int64_t commands = 0;
  int64_t rejected = 0;         // lines that failed to parse or execute (nothing of them ran)
  int64_t unknown_commands = 0;
  uint64_t moves = 0;
  double print_time_s = 0.0;
  std::array<std::string, kJoints> joint_names;
  std::array<JointStepStats, kJoints> joints{};
  uint64_t total_steps = 0;
  uint64_t wire_bytes = 0;      // QUEUE_STEPS messages incl. message header and frame overhead
  double wire_bytes_per_step = 0.0;
  uint64_t check_failures = 0;
  double wall_s = 0.0;
  double cpu_s = 0.0;           // CPU time of the process during the run (all threads)
  int threads = 1;              // threads that stepped the joints
  std::vector<std::string> messages;  // first rejected lines / warnings, "file:line:col: ..."
};

Result<BatchSummary> run_batch(const std::string& gcode_path, const config::MachineConfig& cfg,
                               const BatchOptions& options = {});

}  // namespace feedloop::engine
