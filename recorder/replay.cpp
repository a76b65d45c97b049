// record_virtual_print / replay_print (see replay.hpp).
#include "recorder/replay.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "config/config.hpp"
#include "config/file_text.hpp"
#include "engine/config_mapping.hpp"
#include "engine/executor_factory.hpp"
#include "engine/machine.hpp"
#include "engine/mcu_bridge.hpp"
#include "engine/motion_executor.hpp"
#include "gcode/parser.hpp"
#include "recorder/log_reader.hpp"
#include "recorder/options_from_config.hpp"
#include "recorder/step_stream.hpp"

namespace feedloop::recorder {
namespace fs = std::filesystem;

std::vector<std::string> print_log_parts(const std::string& last_path) {
  std::vector<std::string> out;
  const fs::path p(last_path);
  const std::string file = p.filename().string();
  const size_t cut = file.rfind("_p");
  if (cut == std::string::npos) return {last_path};
  const std::string prefix = file.substr(0, cut + 2);
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(p.parent_path(), ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) == 0 && e.path().extension() == ".flrec") out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

namespace {

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string describe_move_mismatch(size_t i, const std::vector<MoveRecord>& a, const std::vector<MoveRecord>& b) {
  if (i >= a.size()) return "the replay planned more moves (" + std::to_string(b.size()) + " vs " + std::to_string(a.size()) + ")";
  if (i >= b.size()) return "the replay planned fewer moves (" + std::to_string(b.size()) + " vs " + std::to_string(a.size()) + ")";
  const MoveRecord& x = a[i];
  const MoveRecord& y = b[i];
  std::string s = "move " + std::to_string(i) + " (G-code line " + std::to_string(x.line) + "): ";
  if (x.line != y.line) return s + "from line " + std::to_string(x.line) + " vs " + std::to_string(y.line);
  if (x.start_time_s != y.start_time_s)
    return s + "starts at " + fmt("%.9g", x.start_time_s) + " s vs " + fmt("%.9g", y.start_time_s) + " s";
  if (x.start_mm != y.start_mm || x.end_mm != y.end_mm) return s + "geometry differs";
  if (x.v_exit_mm_s != y.v_exit_mm_s)
    return s + "exit speed " + fmt("%.9g", x.v_exit_mm_s) + " vs " + fmt("%.9g", y.v_exit_mm_s) +
           " mm/s (the lookahead was released at another point)";
  return s + "velocity profile differs";
}

uint64_t s_moves(const engine::MotionExecutor& ex) {
  engine::MachineStatus st;
  ex.motion_status(st);
  return st.moves_planned;
}

int64_t first_step_clock(const std::vector<StepRunRecord>& runs) {
  for (const StepRunRecord& r : runs)
    if (r.run.count > 0) return stepgen::run_step_clock(r.start_clock, r.run, 1);
  return 0;
}

}  // namespace

Result<VirtualPrintResult> record_virtual_print(const config::MachineConfig& cfg, const std::string& config_yaml,
                                                const std::vector<std::string>& lines,
                                                const std::string& directory, const std::string& print_name,
                                                const VirtualPrintOptions& options) {
  if (!cfg.uses_simulator())
    return Error{"a virtual-time run needs a simulated printer (mcus with transport: mock)"};
  // Joints in the engine's order, up to the last that is an axis of the config.
  std::vector<std::string> names;
  for (const std::string& n : engine::joint_names(cfg)) names.push_back(n);
  while (!names.empty() && cfg.axis(names.back()) == nullptr) names.pop_back();
  config::MachineConfig rcfg = cfg;
  rcfg.recorder.enabled = true;
  rcfg.recorder.directory = directory;
  auto ro = recorder_options_from_config(rcfg, config_yaml, names, config::PathVars{});
  if (!ro) return ro.error();
  VirtualClock clock(0);  // as feedloopd --virtual-time's machine clock
  ro->clock = &clock;
  ro->servo_ring_bytes = options.servo_ring_bytes;
  auto rec = Recorder::create(std::move(*ro));
  if (!rec) return rec.error();
  Recorder& r = **rec;
  EngineRecording er(r, clock, options.recording);

  engine::MotionOptions mo = engine::motion_options(cfg);
  mo.max_buffered_s = 1e9;       // execute() never waits for the servo side: this thread runs both
  mo.input_pause_flush_s = 0.0;  // idle_tick() releases the lookahead at once (end, M400)
  mo.settle_tail_s = 0.0;        // as feedloopd --virtual-time: idle time does not pass
  mo.m400_waits_for_rest = true;  // as feedloopd --virtual-time
  auto stack = engine::make_motion_stack(cfg, mo, &er);
  if (!stack) return stack.error();
  engine::MotionExecutor& ex = *stack->executor;
  if (!stack->bridge) return Error{"a virtual-time run needs the config's MCUs (mock transport)"};
  ex.set_telemetry(&er);
  // The daemon's machine, driven from this thread (engine/machine.hpp, one-thread runs): its
  // planner stage takes the commands (heaters and their waits included), its servo stage runs
  // one period at a time.
  engine::Machine machine(engine::machine_options(cfg), clock, std::move(stack->executor));

  VirtualPrintResult out;
  if (Status s = r.start_print(print_name); !s) return s.error();
  const double period_s = 1.0 / cfg.servo.rate_hz;
  const auto period_ns = static_cast<int64_t>(std::llround(period_s * 1e9));
  const auto poll_ns = static_cast<int64_t>(options.poll_period_s * 1e9);
  const int64_t start_ns = clock.now_ns();
  const int64_t end_ns = start_ns + static_cast<int64_t>(options.timeout_s * 1e9);
  int64_t next_poll_ns = start_ns + poll_ns;
  Status io_status = Status::Ok();
  auto poll = [&] {
    if (Status s = r.poll(); !s && io_status) io_status = s;
  };
  auto cycle = [&] {
    const int64_t now = clock.now_ns() + period_ns;
    clock.sleep_until_ns(now);
    (void)machine.servo_cycle_inline(now);  // never fails: the machine is not started
    if (now >= next_poll_ns) {
      poll();
      next_poll_ns = now + poll_ns;
    }
  };
  // A command that waits for the machine (G28 through the endstops) runs the cycles itself.
  ex.set_inline_driver([&] {
    cycle();
    if (clock.now_ns() >= end_ns) machine.emergency_stop("virtual print: timeout");
  });
  auto run_until_idle = [&] {
    machine.idle_tick_inline();
    while (ex.motion_pending() && clock.now_ns() < end_ns) cycle();
  };
  // As in feedloopd --virtual-time, time stands still until there is motion: the first servo
  // cycle (which starts the MCUs) comes once moves are queued, and motion starts in the cycle in
  // which the MCUs become ready. Recordings of the virtual-time daemon then replay bit for bit.

  int line_no = 0;
  gcode::Command cmd;
  for (const std::string& line : lines) {
    ++line_no;
    r.writer(Stream::io).gcode_line(clock.now_ns(), GcodeSource::file, line);
    Status st = gcode::parse_line(line, SourceLocation{print_name, line_no, 0}, cmd);
    if (st && cmd.empty()) continue;
    if (st && cmd.is('M', 400)) {  // the planner thread would wait for the machine: run it dry
      run_until_idle();
      ++out.commands;
      continue;
    }
    if (st) st = machine.execute_inline(cmd);
    if (!st) {
      ++out.rejected;
      if (out.first_error.empty()) out.first_error = "line " + std::to_string(line_no) + ": " + st.error().to_string();
      continue;
    }
    ++out.commands;
    // Keep the move queue and the rings from filling: let the machine run while much is queued.
    engine::MachineStatus s;
    ex.motion_status(s);
    while (s.segments_queued > 1024 && clock.now_ns() < end_ns) {
      cycle();
      ex.motion_status(s);
    }
    if (line_no % 256 == 0) poll();
  }
  run_until_idle();
  const int64_t settle_end = clock.now_ns() + static_cast<int64_t>(options.settle_s * 1e9);
  while (clock.now_ns() < settle_end) cycle();
  ex.set_telemetry(nullptr);
  if (er.anchors() == 0 && s_moves(ex) > 0) return Error{"the simulated MCUs did not become ready"};
  if (ex.motion_pending()) return Error{"the motion did not finish within " + fmt("%g", options.timeout_s) + " s of virtual time"};
  out.virtual_s = seconds_from_ns(clock.now_ns() - start_ns);
  out.anchors = er.anchors();
  out.encoder_samples = er.encoder_samples();
  const std::string last = r.stats().current_path;
  if (Status s = r.end_print(); !s) return s.error();
  if (!io_status) return io_status.error();
  out.recorder = r.stats();
  if (!out.recorder.last_error.empty()) return Error{"recorder: " + out.recorder.last_error};
  out.logs = print_log_parts(last);
  return out;
}

Result<RecordedPrint> read_recorded_print(const std::vector<std::string>& logs) {
  if (logs.empty()) return Error{"no log given"};
  RecordedPrint p;
  for (size_t i = 0; i < logs.size(); ++i) {
    std::error_code ec;
    if (!fs::exists(logs[i], ec)) return Error{logs[i] + ": no such file"};
    auto r = LogReader::open(logs[i]);
    if (!r) return r.error();  // names the file already
    if (i == 0) {
      p.header = r->header();
      p.encoders.resize(p.header.joints.size());
    } else if (r->header().joints != p.header.joints || r->header().print_name != p.header.print_name) {
      return Error{logs[i] + ": not a part of the same print as " + logs[0]};
    }
    while (const DecodedRecord* d = r->next()) {
      ++p.records;
      if (const auto* g = std::get_if<GcodeLineRecord>(&d->record)) p.gcode.push_back(*g);
      else if (const auto* m = std::get_if<MoveRecord>(&d->record)) p.moves.push_back(*m);
      else if (const auto* e = std::get_if<EncoderRecord>(&d->record)) {
        if (e->joint >= 0 && static_cast<size_t>(e->joint) < p.encoders.size())
          p.encoders[static_cast<size_t>(e->joint)].push_back(*e);
      } else if (const auto* ev = std::get_if<EventRecord>(&d->record)) {
        if (ev->kind == EventKind::time_anchor) p.anchors_s.push_back(ev->value);
      }
    }
    // A replay of a partial recording would be compared against a partial step stream.
    if (r->error()) return Error{logs[i] + ": " + r->error()->to_string()};
  }
  return p;
}

JointResidual encoder_residual(const std::string& joint, const std::vector<EncoderRecord>& recorded,
                               int64_t recorded_first_step, const std::vector<EncoderRecord>& simulated,
                               int64_t simulated_first_step, double resolution_mm) {
  JointResidual res;
  res.joint = joint;
  if (recorded.empty() || simulated.empty()) return res;
  // Encoder samples are recorded when the reading changes: a reading holds until the next one.
  double sum = 0.0, sum2 = 0.0;
  size_t k = 0;
  for (const EncoderRecord& e : recorded) {
    const int64_t c = e.clock - recorded_first_step + simulated_first_step;
    if (c < simulated.front().clock) continue;
    while (k + 1 < simulated.size() && simulated[k + 1].clock <= c) ++k;
    const double d_um = static_cast<double>(e.counts - simulated[k].counts) * resolution_mm * 1e3;
    ++res.samples;
    sum += d_um;
    sum2 += d_um * d_um;
    res.max_abs_um = std::max(res.max_abs_um, std::abs(d_um));
  }
  if (res.samples > 0) {
    const auto n = static_cast<double>(res.samples);
    res.mean_um = sum / n;
    res.rms_um = std::sqrt(sum2 / n);
  }
  return res;
}

Result<ReplayReport> replay_print(const std::vector<std::string>& logs, const ReplayOptions& options) {
  auto recorded = read_recorded_print(logs);
  if (!recorded) return recorded.error();
  auto recorded_steps = read_step_streams(logs);
  if (!recorded_steps) return recorded_steps.error();
  ReplayReport rep;
  rep.recorded_logs = logs;

  Result<config::MachineConfig> cfg = Error{""};
  std::string yaml;
  if (options.config_path.empty()) {
    rep.config_source = "log header";
    yaml = recorded->header.config_yaml;
    if (yaml.empty()) return Error{logs[0] + ": the log header holds no config; give one with --config"};
    cfg = config::load_config_text(yaml, logs[0] + " (config in the header)");
  } else {
    rep.config_source = options.config_path;
    auto text = config::read_config_file_text(options.config_path, "config file");
    if (!text) return text.error();
    yaml = std::move(text.value());
    cfg = config::load_config_text(yaml, options.config_path);
  }
  if (!cfg) return cfg.error();

  std::vector<std::string> lines;
  lines.reserve(recorded->gcode.size());
  for (const GcodeLineRecord& g : recorded->gcode) {
    if (g.original_length > g.text.size())
      return Error{logs[0] + ": a G-code line of " + std::to_string(g.original_length) +
                   " bytes was cut on recording; the print cannot be replayed exactly"};
    lines.push_back(g.text);
  }
  rep.gcode_lines = lines.size();

  std::string dir = options.out_dir;
  const bool temp = dir.empty();
  if (temp) {
    std::string tmpl = (fs::temp_directory_path() / "feedloop-replay-XXXXXX").string();
    if (::mkdtemp(tmpl.data()) == nullptr) return Error{"cannot create a temporary directory for the replay log"};
    dir = tmpl;
  }
  auto run = record_virtual_print(*cfg, yaml, lines, dir, recorded->header.print_name + "_replay", options.run);
  auto cleanup = [&] {
    if (temp && !options.keep_log) {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  };
  if (!run) {
    cleanup();
    return run.error();
  }
  rep.rejected = run->rejected;
  rep.first_error = run->first_error;
  auto replayed = read_recorded_print(run->logs);
  auto replayed_steps = read_step_streams(run->logs);
  if (!replayed || !replayed_steps) {
    cleanup();
    return !replayed ? replayed.error() : replayed_steps.error();
  }
  if (!temp || options.keep_log) rep.replay_logs = run->logs;
  cleanup();

  // Moves, anchors, steps.
  rep.recorded_moves = recorded->moves.size();
  rep.replayed_moves = replayed->moves.size();
  for (size_t i = 0; i < std::max(recorded->moves.size(), replayed->moves.size()); ++i) {
    if (i < recorded->moves.size() && i < replayed->moves.size() && recorded->moves[i] == replayed->moves[i]) continue;
    rep.move_mismatch = describe_move_mismatch(i, recorded->moves, replayed->moves);
    break;
  }
  rep.recorded_anchors = recorded->anchors_s.size();
  rep.replayed_anchors = replayed->anchors_s.size();
  for (size_t i = 0; i < std::max(rep.recorded_anchors, rep.replayed_anchors); ++i) {
    if (i < recorded->anchors_s.size() && i < replayed->anchors_s.size() &&
        recorded->anchors_s[i] == replayed->anchors_s[i])
      continue;
    if (i < recorded->anchors_s.size() && i < replayed->anchors_s.size())
      rep.anchor_mismatch = "motion start " + std::to_string(i) + ": offset " + fmt("%.9f", recorded->anchors_s[i]) +
                            " s vs " + fmt("%.9f", replayed->anchors_s[i]) + " s";
    else
      rep.anchor_mismatch = "motion starts: " + std::to_string(rep.recorded_anchors) + " recorded vs " +
                            std::to_string(rep.replayed_anchors) + " replayed";
    break;
  }
  for (const auto& runs : recorded_steps->runs)
    for (const StepRunRecord& r : runs) rep.steps_compared += r.run.count;
  if (auto mm = compare_step_streams(*recorded_steps, *replayed_steps)) rep.step_mismatch = mm->to_string(recorded_steps->joints);

  // Encoder residual per joint.
  const auto& joints = recorded->header.joints;
  for (size_t j = 0; j < joints.size() && j < replayed->encoders.size(); ++j) {
    if (recorded->encoders[j].empty() || replayed->encoders[j].empty() || !(joints[j].encoder_resolution_mm > 0))
      continue;
    const int64_t fa = j < recorded_steps->runs.size() ? first_step_clock(recorded_steps->runs[j]) : 0;
    const int64_t fb = j < replayed_steps->runs.size() ? first_step_clock(replayed_steps->runs[j]) : 0;
    rep.residuals.push_back(encoder_residual(joints[j].name, recorded->encoders[j], fa, replayed->encoders[j], fb,
                                             joints[j].encoder_resolution_mm));
  }
  return rep;
}

std::string ReplayReport::to_text() const {
  std::ostringstream o;
  o << "recording: " << recorded_logs.size() << " part(s), " << gcode_lines << " G-code lines; config from "
    << config_source << "\n";
  if (rejected > 0) o << "rejected lines in the replay: " << rejected << " (first: " << first_error << ")\n";
  o << "moves: " << recorded_moves << " recorded, " << replayed_moves << " replayed: "
    << (move_mismatch ? "DIFFERENT, " + *move_mismatch : std::string("identical")) << "\n";
  o << "time anchors: " << recorded_anchors << " recorded, " << replayed_anchors << " replayed: "
    << (anchor_mismatch ? "DIFFERENT, " + *anchor_mismatch : std::string("identical")) << "\n";
  o << "step stream: " << steps_compared << " steps: "
    << (step_mismatch ? "DIFFERENT, first difference: " + *step_mismatch : std::string("bit-identical")) << "\n";
  if (residuals.empty()) {
    o << "encoder residual: no joint has encoder samples in both the recording and the replay\n";
  } else {
    o << "encoder residual (recorded - simulated):\n";
    char b[160];
    std::snprintf(b, sizeof b, "  %-6s %10s %10s %10s %10s\n", "joint", "samples", "rms_um", "max_um", "mean_um");
    o << b;
    for (const JointResidual& r : residuals) {
      std::snprintf(b, sizeof b, "  %-6s %10llu %10.3f %10.3f %10.3f\n", r.joint.c_str(),
                    static_cast<unsigned long long>(r.samples), r.rms_um, r.max_abs_um, r.mean_um);
      o << b;
    }
  }
  for (const std::string& l : replay_logs) o << "replay log: " << l << "\n";
  return o.str();
}

}  // namespace feedloop::recorder
