// run_simulated (see sim_run.hpp): the daemon's engine::Machine around the motion executor and
// the MCU bridge (sessions, mock transports, virtual MCUs, plants) built by the daemon's own
// factory, driven in virtual time from one thread: commands go through the machine's planner
// stage (Machine::execute_inline, heaters and waits included) and its servo stage runs one
// period at a time in between (Machine::servo_cycle_inline), as the machine's two threads
// interleave them, but deterministically (the same input gives the same samples, bit for bit).
#include "engine/sim_run.hpp"

#include <cmath>
#include <sstream>

#include "core/clock.hpp"
#include "engine/executor_factory.hpp"
#include "engine/machine.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/motion_executor.hpp"
#include "gcode/parser.hpp"

namespace feedloop::engine {
namespace {

// Servo thread: each sample with the plant's ground truth at the same instant (the bridge has
// advanced the plants to the cycle's time before the executor publishes).
class Recorder final : public TelemetryTap {
 public:
  Recorder(SimRunResult& out, McuBridge& bridge, bool keep, std::vector<LostStepInjection> inject,
           std::vector<EncoderGlitchInjection> glitches)
      : out_(out),
        bridge_(bridge),
        keep_(keep),
        inject_(std::move(inject)),
        glitches_(std::move(glitches)) {}
  void on_servo_sample(const ServoSample& s) override {
    for (LostStepInjection& i : inject_)
      if (i.steps != 0 && s.print_time_s >= i.at_s) {
        bridge_.inject_lost_steps(i.joint, i.steps);
        i.steps = 0;
      }
    for (EncoderGlitchInjection& g : glitches_)
      if (g.offset_mm != 0.0 && s.print_time_s >= g.at_s) {
        bridge_.inject_encoder_offset(g.joint, g.offset_mm);
        g.offset_mm = 0.0;
      }
    if (!keep_ && !on_sample_) return;
    SimRunSample r;
    r.servo = s;
    r.actual_mm.fill(NAN);
    r.actual_nozzle_mm.fill(NAN);
    if (SimulatedPlant* plant = bridge_.plant()) {
      for (int j = 0; j < 3; ++j) r.actual_mm[static_cast<size_t>(j)] = plant->carriage_mm(j);
      r.actual_nozzle_mm = plant->nozzle_mm();
    }
    if (on_sample_) on_sample_(r);
    if (keep_) out_.samples.push_back(r);
  }
  std::function<void(const SimRunSample&)> on_sample_;
  void on_servo_event(const ServoEvent& e) override {
    out_.events.push_back(e);
    if (e.kind == ServoEventKind::kEncoderFault || e.kind == ServoEventKind::kFollowingError ||
        e.kind == ServoEventKind::kMcuFault)
      ++out_.faults;
  }

 private:
  SimRunResult& out_;
  McuBridge& bridge_;
  bool keep_;
  std::vector<LostStepInjection> inject_;
  std::vector<EncoderGlitchInjection> glitches_;
};

}  // namespace

Result<SimRunResult> run_simulated(const config::MachineConfig& cfg,
                                   const std::vector<std::string>& gcode_lines,
                                   const SimRunOptions& options) {
  MotionOptions mo = motion_options(cfg);
  mo.max_buffered_s = 1e6;       // execute() never waits for the servo: this thread runs both
  mo.input_pause_flush_s = 0.0;  // idle_tick() releases the lookahead at once
  mo.settle_tail_s = 0.0;        // options.settle_s keeps the cycles running instead
  auto stack = make_motion_stack(cfg, mo);
  if (!stack.ok()) return stack.error();
  if (!stack.value().bridge)
    return Error{"run_simulated: the config has no MCUs (use the mock transport)"};
  MotionExecutor& ex = *stack.value().executor;
  McuBridge& bridge = *stack.value().bridge;
  VirtualClock clock;  // the caller's now_ns below is the time; nothing sleeps on this clock
  Machine machine(machine_options(cfg), clock, std::move(stack.value().executor));

  SimRunResult out;
  if (options.keep_samples) out.samples.reserve(1 << 16);
  Recorder rec(out, bridge, options.keep_samples, options.lose_steps, options.encoder_glitches);
  rec.on_sample_ = options.on_sample;
  ex.set_telemetry(&rec);

  const double period_s = 1.0 / cfg.servo.rate_hz;
  const int64_t period_ns = static_cast<int64_t>(std::llround(period_s * 1e9));
  int64_t now_ns = 1'000'000'000;
  const int64_t end_ns = now_ns + static_cast<int64_t>(options.timeout_s * 1e9);
  size_t next_stall = 0;
  int64_t ready_ns = -1;
  auto cycle = [&] {
    now_ns += period_ns;
    if (ready_ns >= 0 && next_stall < options.stalls.size() &&
        now_ns - ready_ns >= static_cast<int64_t>(options.stalls[next_stall].at_s * 1e9)) {
      now_ns += static_cast<int64_t>(std::llround(options.stalls[next_stall].duration_s * 1e9));
      ++next_stall;
    }
    (void)machine.servo_cycle_inline(now_ns);  // never fails: the machine is not started
  };
  // A command that waits for the machine (G28 through the endstops, M400) runs its cycles here.
  ex.set_inline_driver([&] {
    cycle();
    if (now_ns >= end_ns) machine.emergency_stop("run_simulated: timeout");  // the wait ends
  });
  while (!bridge.ready() && now_ns < end_ns) cycle();
  if (!bridge.ready()) {
    char why[256] = "";
    if (bridge.fault()) bridge.fault_message(why, sizeof why);
    return Error{std::string("run_simulated: the simulated MCUs did not become ready") +
                 (why[0] ? ": " : "") + why};
  }
  ready_ns = now_ns;
  const int64_t idle_end = now_ns + static_cast<int64_t>(std::llround(options.idle_before_s * 1e9));
  while (now_ns < idle_end) cycle();

  int line_no = 0;
  for (const std::string& line : gcode_lines) {
    ++line_no;
    if (options.on_progress && line_no % 1000 == 0)
      options.on_progress(static_cast<double>(line_no) / static_cast<double>(gcode_lines.size()));
    auto cmd = gcode::parse_line(line, SourceLocation{"sim_run", line_no, 0});
    if (!cmd.ok()) {
      ++out.rejected;
      if (out.error.empty()) out.error = cmd.error().message;
      continue;
    }
    if (Status st = machine.execute_inline(cmd.value()); !st) {
      ++out.rejected;
      if (out.error.empty())
        out.error = "line " + std::to_string(line_no) + ": " + st.error().message;
      continue;
    }
    ++out.commands;
    // Keep the move queue from filling: let the machine run while much is queued.
    MachineStatus s;
    ex.motion_status(s);
    while (s.segments_queued > 1024 && now_ns < end_ns) {
      cycle();
      ex.motion_status(s);
    }
  }
  machine.idle_tick_inline();  // releases the lookahead's tail
  while (ex.motion_pending() && now_ns < end_ns) cycle();
  const int64_t settle_end = now_ns + static_cast<int64_t>(options.settle_s * 1e9);
  while (now_ns < settle_end) cycle();
  MachineStatus s;
  ex.motion_status(s);
  out.motion_time_s = s.planned_until_s;
  out.lost_step_events = s.lost_step_events;
  out.tracking_error_mean_mm = s.tracking_error_mean_mm;
  out.tracking_error_max_mm = s.tracking_error_max_mm;
  out.tracking_error_samples = s.tracking_error_samples;
  out.device_loops = s.device_loops;
  if (out.error.empty() && s.last_error[0] != '\0') out.error = s.last_error;
  if (ex.motion_pending() && out.error.empty())
    out.error = "motion did not finish within the timeout";
  if (SimulatedPlant* plant = bridge.plant())
    for (int j = 0; j < 3; ++j) {
      out.lost_full_steps[static_cast<size_t>(j)] = plant->lost_full_steps(j);
      out.slip_events[static_cast<size_t>(j)] = plant->slip_events(j);
    }
  out.late_cycles = s.late_cycles;
  out.deadline_misses = machine.servo_status().deadline_misses;
  ex.set_telemetry(nullptr);
  return out;
}

}  // namespace feedloop::engine
