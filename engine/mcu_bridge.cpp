// The machine's MCUs behind the step pipeline: see mcu_bridge.hpp.
#include "engine/mcu_bridge.hpp"

#include <algorithm>  // std::min, std::max
#include <cmath>      // std::fabs, NAN
#include <cstdio>     // snprintf
#include <cstdlib>
#include <cstring>    // memcpy

#include "core/clock.hpp"  // ns_from_seconds
#include "drivers/protocol/endstop_messages.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "engine/mcu_transport.hpp"
#include "engine/simulated_printer.hpp"
#include "engine/thermal_config.hpp"  // board_channels

namespace feedloop::engine {
namespace {

// The extruder (and any joint without a plant model): executes every step exactly.
struct IdealMotor final : device::MotorPort {
  int64_t steps = 0;
  void step(double, int d) override { steps += d; }
  void set_enabled(double, bool) override {}
  int64_t read_encoder_counts(double) override { return steps; }
};

}  // namespace

struct McuBridge::Mcu {
  std::string name;
  std::unique_ptr<SimulatedHeaterBoard> heaters;  // mock: the heaters it drives (outlives vmcu)
  std::unique_ptr<device::VirtualMcu> vmcu;
  std::unique_ptr<drivers::Transport> transport;
  drivers::MockTransport* mock = nullptr;
  std::unique_ptr<drivers::McuSession> session;
  std::vector<IdealMotor> ideal;  // motors without a plant model (sized before ports point at it)
  bool estop_sent = false;
  // Heaters and fans named on this MCU (config mcu:): their messages to and from the thermal loop.
  std::shared_ptr<SharedHeaterPort> heater_port;
  uint64_t frames_in = 0;        // frames from the MCU, as last seen
  double last_heard_s = -1e300;  // host time frames_in last grew
};

// Between a virtual MCU and its plant: checks each executed step against what was sent.
struct McuBridge::JointPort final : device::MotorPort {
  device::MotorPort* plant = nullptr;
  std::vector<double> intended_s;  // ring of intended host times of steps sent, not yet executed
  size_t head = 0, count = 0;
  JointTiming timing;
  int64_t swallow = 0;  // steps still to be lost (inject_lost_steps)
  int64_t encoder_offset_counts = 0;  // added to every encoder reading (inject_encoder_offset)
  bool homing = false;  // a homing sequence streams this joint's steps (not matched with batches)
  void push(double t_s) {
    if (count == intended_s.size()) return;  // more in flight than tracked: timing not checked
    intended_s[(head + count) % intended_s.size()] = t_s;
    ++count;
  }
  void step(double t_s, int direction) override {
    if (homing) {
      ++timing.homing_steps;
      plant->step(t_s, direction);
      return;
    }
    ++timing.steps_executed;
    if (count > 0) {
      timing.max_time_err_us = std::max(timing.max_time_err_us, std::fabs(t_s - intended_s[head]) * 1e6);
      head = (head + 1) % intended_s.size();
      --count;
    } else {
      ++timing.unexpected_steps;
    }
    if (swallow > 0) {  // fault injection: the driver misses these steps (a slip, seen from outside)
      --swallow;
      return;
    }
    plant->step(t_s, direction);
  }
  // The device loop's own steps: not the host's, so not matched against what was sent.
  void device_step(double t_s, int direction) override {
    ++timing.device_steps;
    plant->step(t_s, direction);
  }
  void set_enabled(double t_s, bool on) override { plant->set_enabled(t_s, on); }
  void set_step_fraction(double t_s, float f) override { plant->set_step_fraction(t_s, f); }
  int64_t read_encoder_counts(double t_s) override {
    return plant->read_encoder_counts(t_s) + encoder_offset_counts;
  }
  bool read_endstop(double t_s) override { return plant->read_endstop(t_s); }
  bool read_encoder_index(double t_s) override { return plant->read_encoder_index(t_s); }
};

McuBridge::McuBridge(const config::MachineConfig&, const McuBridgeOptions& options) : options_(options) {
  for (auto& e : encoder_mm_) e.store(NAN);
  for (auto& e : encoder_time_s_) e.store(NAN);
  for (auto& e : homed_mm_) e.store(NAN);
  for (auto& e : steps_homed_mm_) e.store(NAN);
  for (auto& e : homed_truth_mm_) e.store(NAN);
  for (auto& e : first_touch_mm_) e.store(NAN);
  for (auto& e : endstop_state_) e.store(-1);
}

McuBridge::~McuBridge() = default;

Result<std::unique_ptr<McuBridge>> McuBridge::create(const config::MachineConfig& cfg,
                                                     const McuBridgeOptions& options) {
  std::unique_ptr<McuBridge> b(new McuBridge(cfg, options));
  if (Status s = b->build(cfg); !s) return s.error();
  return b;
}

Status McuBridge::build(const config::MachineConfig& cfg) {
  sample_buffer_.reserve(drivers::McuSession::kSampleCapacity);
  const auto names = joint_names(cfg);
  joint_names_ = names;
  const auto spm = steps_per_mm(cfg);
  const bool delta = cfg.kinematics == config::Kinematics::delta;

  // Plants first (the ports point into them).
  auto plant = make_simulated_printer(cfg);
  if (!plant) return plant.error();
  plant_ = std::move(plant.value());
  std::array<device::MotorPort*, kJoints> plant_port{};
  for (int j = 0; j < kJoints; ++j) {
    plant_port[static_cast<size_t>(j)] = plant_->motor(j);
    encoder_mm_per_count_[static_cast<size_t>(j)] = plant_->encoder_mm_per_count(j);
  }

  // The transports' I/O threads run just below the servo thread (SCHED_FIFO when it is): frames
  // the servo thread queues must not wait for a CPU behind every other process.
  const int io_priority = cfg.servo.realtime_priority > 1 ? cfg.servo.realtime_priority - 1 : 0;
  int index = 0;
  for (const config::McuConfig& mc : cfg.mcus) {
    auto m = std::make_unique<Mcu>();
    m->name = mc.name;
    std::vector<int> joints;
    for (const std::string& a : mc.axes) {
      int j = -1;
      for (int k = 0; k < kJoints; ++k)
        if (names[static_cast<size_t>(k)] == a) j = k;
      if (j < 0) return Error{"MCU '" + mc.name + "': axis '" + a + "' is not a joint of this machine"};
      if (joint_mcu_[static_cast<size_t>(j)] >= 0) return Error{"axis '" + a + "' is driven by two MCUs"};
      if (joints.size() >= static_cast<size_t>(device::VirtualMcu::kMaxAxes))
        return Error{"MCU '" + mc.name + "': more than 4 axes"};
      joint_mcu_[static_cast<size_t>(j)] = index;
      joint_motor_[static_cast<size_t>(j)] = static_cast<int>(joints.size());
      joints.push_back(j);
    }
    // Heaters and fans named on this MCU (one board for motion and heaters): their port, and on a
    // simulated MCU the thermal plants its VirtualMcu drives.
    const BoardChannels heaters = board_channels(cfg, mc.name);
    if (!heaters.empty()) {
      if (heaters.heaters.size() > 4 || heaters.fans.size() > 4)
        return Error{"MCU '" + mc.name + "': at most 4 heaters and 4 fans per board"};
      m->heater_port = std::make_shared<SharedHeaterPort>(mc.name);
      heater_ports_.push_back(m->heater_port);
      if (mc.transport == config::TransportType::mock)
        m->heaters = make_simulated_heater_board(cfg, heaters.heaters, heaters.fans,
                                                 static_cast<double>(mc.clock_hz));
    }
    if (mc.transport == config::TransportType::mock) {
      m->ideal.resize(joints.size());
      std::array<device::MotorPort*, device::VirtualMcu::kMaxAxes> ports{};
      for (size_t k = 0; k < joints.size(); ++k) {
        const auto js = static_cast<size_t>(joints[k]);
        auto port = std::make_unique<JointPort>();
        port->plant = plant_port[js] != nullptr ? plant_port[js] : &m->ideal[k];
        port->intended_s.assign(options_.step_ring, 0.0);
        ports[k] = port.get();
        ports_[js] = std::move(port);
      }
      device::VirtualMcuParams vp;
      vp.clock_hz = static_cast<double>(mc.clock_hz);
      vp.drift_ppm = (index % 2 == 0 ? 1.0 : -1.0) * options_.drift_ppm;
      vp.offset_s = (index + 1) * options_.clock_offset_s;
      vp.axis = static_cast<uint8_t>(joints.empty() ? 0 : joints[0]);
      std::snprintf(vp.name, sizeof vp.name, "%s", mc.name.c_str());
      m->vmcu = joints.size() > 1 || m->heaters
                    ? std::make_unique<device::VirtualMcu>(
                          vp, ports.data(), static_cast<int>(std::max<size_t>(joints.size(), 1)),
                          m->heaters ? &m->heaters->board() : nullptr)
                    : std::make_unique<device::VirtualMcu>(vp, ports[0]);
      drivers::MockFaults f = options_.faults;
      f.seed += static_cast<uint64_t>(index) * 7919;
      auto t = std::make_unique<drivers::MockTransport>(*m->vmcu, f, mc.name);
      m->mock = t.get();
      simulated_ = true;
      m->transport = std::move(t);
    } else {
      m->transport = make_hardware_transport(mc, io_priority);
    }
    drivers::McuSessionParams sp;
    sp.name = mc.name;
    sp.watchdog_s = options_.watchdog_s;
    bool has_encoder = false;
    for (int j : joints) {
      const config::AxisConfig* a = cfg.axis(names[static_cast<size_t>(j)]);
      if (a && a->encoder) {
        has_encoder = true;
        if (mc.transport != config::TransportType::mock)
          encoder_mm_per_count_[static_cast<size_t>(j)] = a->encoder->resolution_um * 1e-3;
      }
      if (delta && j < 3) has_encoder = true;  // the simulated delta has carriage encoders
    }
    // One sample per servo period; closed loop needs each one at once (the PI's loop delay),
    // open loop batches ten per report (telemetry only).
    sp.encoder_period_s = has_encoder ? 1.0 / cfg.servo.rate_hz : 0.0;
    // Host loop: each sample at once (the PI's loop delay); device loop or open loop: telemetry.
    sp.samples_per_report =
        cfg.control.mode == config::ControlMode::pi && cfg.control.loop == config::ControlLoop::host ? 1 : 10;
    m->session = std::make_unique<drivers::McuSession>(sp, *m->transport);
    mcus_.push_back(std::move(m));
    ++index;
  }
  for (int j = 0; j < kJoints; ++j)
    if (joint_mcu_[static_cast<size_t>(j)] < 0 && spm[static_cast<size_t>(j)] > 0 && j < 3)
      return Error{"axis '" + names[static_cast<size_t>(j)] + "' is driven by no MCU (mcus: ... axes)"};
  // The device loop of each joint with an encoder (control.loop: device).
  for (int j = 0; j < kJoints; ++j) {
    const size_t js = static_cast<size_t>(j);
    if (joint_mcu_[js] < 0 || !(spm[js] > 0.0)) continue;
    const config::McuConfig& mc = cfg.mcus[static_cast<size_t>(joint_mcu_[js])];
    const device::LoopParams lp = DeviceLoopLink::params_from_config(
        cfg, j, encoder_mm_per_count_[js], 1.0 / spm[js], static_cast<double>(mc.clock_hz));
    if (lp.enabled) {
      if (const device::LoopParamError e = device::validate_loop_params(lp); e != device::LoopParamError::kOk)
        return Error{"control (device loop of '" + names[js] + "'): " + device::loop_param_error_name(e)};
    }
    loop_link_.set_joint(j, static_cast<uint8_t>(joint_motor_[js]), lp);
  }
  publish_loop_telemetry();  // which joints have a device loop, before any report
  // The encoders' measured delay (model.gantry.<axis>.encoder_delay_ms, the identified
  // time_delay): a reading stands for the carriage that long before it was sampled. Cartesian
  // joints are the axes; a CoreXY's encoders read the carriage's X and Y, not its motors.
  for (int j = 0; j < kJoints; ++j)
    if (cfg.kinematics == config::Kinematics::cartesian)
      if (const config::GantryModelConfig* g = cfg.model.gantry_for(names[static_cast<size_t>(j)]))
        encoder_delay_s_[static_cast<size_t>(j)] = g->encoder_delay_ms * 1e-3;
  // Homing sequences for the joints with an endstop (axes.<name>.homing), built now so that a G28
  // allocates nothing on the servo thread. Cartesian axes and delta carriages (each on its own
  // switch); on a CoreXY machine the Cartesian carriage's X and Y (each moves both motors: A =
  // x + y, B = x - y, planner/linear_kinematics.hpp). The X switch is read on motor A's endstop
  // input, the Y switch on B's; the other motor follows, its stop relayed by the host
  // (drivers/host/homing.hpp, docs/decisions.md "CoreXY homing").
  corexy_ = cfg.kinematics == config::Kinematics::corexy;
  for (auto& hj : homing_joints_) hj = {-1, -1};
  for (int j = 0; j < 3; ++j) {
    const size_t js = static_cast<size_t>(j);
    const config::AxisConfig* a = cfg.axis(names[js]);
    if (a == nullptr || !a->homing || joint_mcu_[js] < 0 || !(spm[js] > 0.0)) continue;
    const config::HomingConfig& h = *a->homing;
    drivers::HomingParams hp;
    hp.axis_name = names[js];
    hp.motor = static_cast<uint8_t>(joint_motor_[js]);
    hp.mm_per_step = 1.0 / spm[js];
    hp.position_endstop_mm = h.position_endstop_mm;
    hp.direction = h.direction == config::EndstopSide::min ? -1 : 1;
    hp.max_travel_mm = h.max_travel_mm;
    hp.homing_speed_mm_s = h.homing_speed_mm_s;
    hp.second_homing_speed_mm_s = h.second_homing_speed_mm_s;
    hp.retract_dist_mm = h.retract_dist_mm;
    hp.second_touch = h.retract_dist_mm > 0.0;
    hp.accel_mm_s2 = a->max_accel_mm_s2;
    hp.queue_ahead_s = cfg.stepgen.queue_ahead_ms * 1e-3;
    // A joint with a linear encoder homes to the carriage (the simulated delta has carriage
    // encoders); a CoreXY carriage keeps the steps (its encoders are the motors' belts').
    hp.report_encoder = (a->encoder.has_value() || cfg.kinematics == config::Kinematics::delta) &&
                        encoder_mm_per_count_[js] > 0.0 &&
                        cfg.kinematics != config::Kinematics::corexy;
    // A CoreXY carriage's index and stall homing use the belts' encoders (A's for X, B's for Y:
    // the primary motor's; the follower's too for the result, McuBridge::poll_homing).
    if ((h.index || h.stall) && corexy_ && j < 2) {
      const size_t os = static_cast<size_t>(1 - j);
      if (!(encoder_mm_per_count_[js] > 0.0) || !(encoder_mm_per_count_[os] > 0.0))
        return Error{"axes." + names[js] +
                     ".homing: encoder-index and stall homing of a corexy carriage read both "
                     "belts' encoders: give x and y an encoder"};
      hp.report_encoder = true;
    }
    // Encoder-index homing: the next mark lies within one period of the switch.
    hp.index_search = h.index && hp.report_encoder && a->encoder;
    if (hp.report_encoder) hp.encoder_mm_per_count = encoder_mm_per_count_[js];
    if (h.stall) {
      if (!hp.report_encoder)
        return Error{"axes." + names[js] +
                     ".homing.stall: stall homing needs the carriage's encoder (axes." + names[js] +
                     ".encoder)"};
      hp.stall = true;
      hp.second_touch = false;
      hp.stall_threshold_mm = h.stall_threshold_mm;
      hp.encoder_mm_per_count = encoder_mm_per_count_[js];
    }
    if (hp.index_search) hp.index_search_mm = a->encoder->index_period_mm * 1.05;
    index_period_mm_[js] = hp.index_search ? a->encoder->index_period_mm : 0.0;
    index_position_mm_[js] = h.index_position_mm ? *h.index_position_mm : NAN;
    drivers::McuSession* follower_session = nullptr;
    homing_joints_[js] = {j, -1};
    if (corexy_ && j < 2) {
      // X: A (+1 step per x step) with B following (+1); Y: B (-1 per y step) with A (+1).
      const int other = 1 - j;
      const size_t os = static_cast<size_t>(other);
      if (joint_mcu_[os] < 0)
        return Error{"axes." + names[js] + ".homing: the corexy carriage needs both motors on an MCU"};
      if (spm[0] != spm[1])
        return Error{"axes." + names[js] + ".homing: corexy homing needs the same steps_per_mm on x and y (" +
                     std::to_string(spm[0]) + " and " + std::to_string(spm[1]) + ")"};
      hp.motor_sign = j == 0 ? 1 : -1;
      hp.has_follower = true;
      hp.follower_motor = static_cast<uint8_t>(joint_motor_[os]);
      hp.follower_sign = 1;
      follower_session = mcus_[static_cast<size_t>(joint_mcu_[os])]->session.get();
      homing_joints_[js] = {j, other};
    }
    if (Status st = drivers::check_homing_params(hp); !st)
      return Error{"axes." + names[js] + ".homing: " + st.error().message};
    homing_[js] = std::make_unique<drivers::HomingSequence>(
        hp, *mcus_[static_cast<size_t>(joint_mcu_[js])]->session, follower_session);
    endstop_max_[js] = hp.direction > 0;
  }
  return Status::Ok();
}

// ---- homing -------------------------------------------------------------------------------------

// One joint's sequence started: its device loop off (it would hold the carriage against the
// homing's steps; the next motion configures it again, with targets in the re-based frame), its
// steps not matched with the pipeline's batches.
bool McuBridge::begin_joint_homing(int j, double now_s) {
  const size_t js = static_cast<size_t>(j);
  for (const int m : homing_joints_[js]) {  // the motors this sequence moves
    if (m < 0) continue;
    drivers::McuSession& session = *mcus_[static_cast<size_t>(joint_mcu_[static_cast<size_t>(m)])]->session;
    if (loop_link_.enabled(m)) {
      loop_link_.disable(m, session,
                         static_cast<int64_t>(std::llround(session.tick_map().ticks(now_s + 0.01))));
      loops_configured_ = false;
    }
    if (ports_[static_cast<size_t>(m)]) ports_[static_cast<size_t>(m)]->homing = true;
  }
  homing_started_ |= 1u << j;
  if (Status st = homing_[js]->start(0, now_s); !st) {
    std::snprintf(homing_error_, sizeof homing_error_, "%s", st.error().message.c_str());  // rare
    return false;
  }
  return true;
}

// Does sequence `seq` move a motor on MCU `mcu`?
bool McuBridge::homing_uses_mcu(int seq, int mcu) const {
  for (const int m : homing_joints_[static_cast<size_t>(seq)])
    if (m >= 0 && joint_mcu_[static_cast<size_t>(m)] == mcu) return true;
  return false;
}

// Joints on different MCUs home together; joints sharing an MCU one after the other (the MCU's
// ENDSTOP_TRIGGER / ENDSTOP_STATE answers are per MCU, drivers/host/homing.hpp).
bool McuBridge::start_pending_homings(double now_s) {
  for (int j = 0; j < kJoints; ++j) {
    const unsigned bit = 1u << j;
    if ((homing_mask_ & bit) == 0 || (homing_started_ & bit) != 0) continue;
    bool mcu_busy = false;
    for (int k = 0; k < kJoints; ++k) {
      if ((homing_started_ >> k & 1u) == 0 || !homing_[static_cast<size_t>(k)]->running()) continue;
      for (const int m : homing_joints_[static_cast<size_t>(j)])
        if (m >= 0 && homing_uses_mcu(k, joint_mcu_[static_cast<size_t>(m)])) mcu_busy = true;
    }
    if (mcu_busy) continue;
    if (!begin_joint_homing(j, now_s)) return false;
  }
  return true;
}

bool McuBridge::start_homing(unsigned joint_mask, double host_s, char* why, size_t cap) {
  auto refuse = [&](const char* text, const std::string& axis) {
    std::snprintf(why, cap, "%s%s", axis.c_str(), text);
    return false;
  };
  if (homing_state_ == HomingState::kRunning) return refuse("a homing is already running", "");
  if (phase_ != Phase::kRunning) return refuse("the MCUs are not ready", "");
  if (joint_mask == 0) return refuse("no axis to home", "");
  for (int j = 0; j < kJoints; ++j)
    if ((joint_mask >> j & 1u) != 0 && !homing_[static_cast<size_t>(j)])
      return refuse(": no endstop (axes.<name>.homing) on this axis",
                    joint_names_[static_cast<size_t>(j)]);
  const double now_s = host_s - epoch_s_;
  homing_mask_ = joint_mask;
  homing_started_ = 0;
  homing_finished_ = 0;
  homing_shift_mm_ = {};
  homing_result_mm_ = {};
  homing_state_ = HomingState::kRunning;
  homing_settle_until_s_ = -1.0;
  homing_error_[0] = '\0';
  if (!start_pending_homings(now_s)) {
    std::snprintf(why, cap, "%s", homing_error_);
    abort_homing("an axis could not start");
    std::snprintf(homing_error_, sizeof homing_error_, "%s", why);
    return false;
  }
  return true;
}

void McuBridge::abort_homing(const char* why) {
  if (homing_state_ != HomingState::kRunning) return;
  for (int j = 0; j < kJoints; ++j)
    if ((homing_started_ >> j & 1u) != 0) homing_[static_cast<size_t>(j)]->abort(why);
  std::snprintf(homing_error_, sizeof homing_error_, "homing aborted: %s", why);
  end_homing(HomingState::kFailed);
}

void McuBridge::end_homing(HomingState state) {
  for (int j = 0; j < kJoints; ++j) {
    if ((homing_mask_ >> j & 1u) == 0) continue;
    for (const int m : homing_joints_[static_cast<size_t>(j)])
      if (m >= 0 && ports_[static_cast<size_t>(m)]) ports_[static_cast<size_t>(m)]->homing = false;
  }
  homing_state_ = state;
}

// Every homing joint's sequence advanced (after the sessions' poll); once all are done the
// carriages get a moment to settle (the report's ground truth is taken at rest), then kDone. One
// failure stops them all.
void McuBridge::poll_homing(double now_s) {
  bool all_done = true;
  for (int j = 0; j < kJoints; ++j) {
    const size_t js = static_cast<size_t>(j);
    if ((homing_mask_ >> j & 1u) == 0) continue;
    if ((homing_started_ >> j & 1u) == 0) {
      all_done = false;
      continue;
    }
    drivers::HomingSequence& h = *homing_[js];
    const drivers::HomingPhase ph = h.poll(now_s);
    if (ph == drivers::HomingPhase::kFailed) {
      std::snprintf(homing_error_, sizeof homing_error_, "%s",
                    h.error() ? h.error()->message.c_str() : "homing failed");
      for (int k = 0; k < kJoints; ++k)
        if ((homing_started_ >> k & 1u) != 0 && k != j)
          homing_[static_cast<size_t>(k)]->abort("another axis failed");
      log(homing_error_);  // rare: allocates
      end_homing(HomingState::kFailed);
      return;
    }
    if (ph != drivers::HomingPhase::kDone) {
      all_done = false;
    } else if (corexy_ && j < 2 && (homing_finished_ >> j & 1u) == 0) {
      homing_finished_ |= 1u << j;  // in the order they ran (X and Y share the motors)
      corexy_homed(j);
    }
  }
  if (homing_started_ != homing_mask_) {
    if (!start_pending_homings(now_s)) {
      const std::string why = homing_error_;  // rare: allocates
      abort_homing("an axis could not start");
      std::snprintf(homing_error_, sizeof homing_error_, "%s", why.c_str());
    }
    return;
  }
  if (!all_done) return;
  constexpr double kSettle_s = 0.15;  // the carriage rings out after the last stop
  if (homing_settle_until_s_ < 0.0) homing_settle_until_s_ = now_s + kSettle_s;
  if (now_s < homing_settle_until_s_) return;
  const std::array<double, 2> corexy_index_mm = corexy_index_homed_mm();
  for (int j = 0; j < kJoints; ++j) {
    const size_t js = static_cast<size_t>(j);
    if ((homing_mask_ >> j & 1u) == 0) continue;
    const drivers::HomingResult& r = homing_[js]->result();
    const bool cartesian_carriage = corexy_ && j < 2;
    const double steps_mm = cartesian_carriage ? homing_result_mm_[js] : r.position_mm;
    if (cartesian_carriage) {  // by the belts' encoders (index, stall) or by the steps
      const double by_index_mm = corexy_index_mm[js];
      const double by_stall_mm = corexy_stall_homed_mm(j, steps_mm);
      const double homed = std::isfinite(by_index_mm)   ? by_index_mm
                           : std::isfinite(by_stall_mm) ? by_stall_mm
                                                        : steps_mm;
      publish_homed(j, homed, steps_mm, std::isfinite(by_index_mm) || std::isfinite(by_stall_mm));
      continue;
    }
    // Carriage-referenced: at the trigger the carriage was at the endstop (the encoder's count
    // then, latched on the MCU); at rest now it is the encoder's travel since away from it, and the
    // steps at rest sit where the carriage does. The steps alone would put the carriage's lag
    // behind them at the trigger (v (c1/k1 + c2/k1 + c2/k2) on the two-mass belt, ~70 um at
    // 10 mm/s) into every later position (docs/homing.md "Carriage-referenced homing").
    // A count that puts the carriage more than kMaxLag_mm from the steps is not a lag (a broken
    // encoder or device): the steps' reference then, and the log says so.
    constexpr double kMaxLag_mm = 1.0;
    const double enc_mm = encoder_mm_[js].load(std::memory_order_relaxed);
    const double by_encoder_mm =
        homing_[js]->params().position_endstop_mm +
        (enc_mm - static_cast<double>(r.trigger_encoder_counts) * encoder_mm_per_count_[js]);
    bool by_encoder = !cartesian_carriage && r.has_trigger_encoder && std::isfinite(by_encoder_mm);
    if (by_encoder && std::fabs(by_encoder_mm - steps_mm) > kMaxLag_mm) {
      by_encoder = false;
      log("homing of " + joint_names_[js] + ": the encoder puts the carriage " +
          std::to_string(by_encoder_mm - steps_mm) +
          " mm from the steps at the trigger; homed by the steps");  // rare: allocates
    }
    // Encoder-index homing: the mark is the reference. Its position from the config, or measured
    // from the switch at the first homing (kept while the daemon runs; the log gives the value).
    double by_index_mm = NAN;
    if (by_encoder && r.has_index) {
      const double mark_from_switch_mm =
          homing_[js]->params().position_endstop_mm +
          static_cast<double>(r.index_encoder_counts - r.trigger_encoder_counts) *
              encoder_mm_per_count_[js];
      if (!std::isfinite(index_position_mm_[js])) {
        index_position_mm_[js] = mark_from_switch_mm;
        log("homing of " + joint_names_[js] + ": its encoder index mark is at " +
            std::to_string(mark_from_switch_mm) + " mm by the switch; set axes." +
            joint_names_[js] + ".homing.index_position_mm to keep it");  // once: allocates
      }
      by_index_mm = index_position_mm_[js] + (enc_mm - static_cast<double>(r.index_encoder_counts) *
                                                           encoder_mm_per_count_[js]);
    }
    const double homed = std::isfinite(by_index_mm) ? by_index_mm
                         : by_encoder               ? by_encoder_mm
                                                    : steps_mm;
    publish_homed(j, homed, steps_mm, by_encoder);
  }
  end_homing(HomingState::kDone);
}

// One joint's homing result for the planner (homed_position_mm) and the reports.
void McuBridge::publish_homed(int j, double homed, double steps_mm, bool by_encoder) {
  const size_t js = static_cast<size_t>(j);
  const drivers::HomingResult& r = homing_[js]->result();
  const bool cartesian_carriage = corexy_ && j < 2;
  homed_mm_[js].store(homed, std::memory_order_relaxed);
  steps_homed_mm_[js].store(steps_mm, std::memory_order_relaxed);
  encoder_referenced_[js].store(by_encoder, std::memory_order_relaxed);
  first_touch_mm_[js].store(r.first_trigger_mm + (homed - steps_mm), std::memory_order_relaxed);
  relay_lag_steps_[js].store(r.relay_lag_steps, std::memory_order_relaxed);
  double truth = NAN;
  if (plant_ && mcus_[static_cast<size_t>(joint_mcu_[js])]->vmcu) {
    // CoreXY: the carriage from the belts' ends, x = (A + B) / 2, y = (A - B) / 2.
    truth = !cartesian_carriage ? plant_->carriage_mm(j)
            : j == 0            ? 0.5 * (plant_->carriage_mm(0) + plant_->carriage_mm(1))
                                : 0.5 * (plant_->carriage_mm(0) - plant_->carriage_mm(1));
  }
  homed_truth_mm_[js].store(truth, std::memory_order_relaxed);
  homing_count_[js].fetch_add(1, std::memory_order_relaxed);
  endstop_state_[js].store(1, std::memory_order_relaxed);  // it stopped on its switch
}

// CoreXY stall homing of carriage axis j (X: motor A primary, B following; Y: B primary, A
// following): at the trip the frame held the carriage at position_endstop, and it held both belts
// until the follower's relayed stop; the axis's travel since is the belts' encoders' (x = (A + B)
// / 2, y = (A - B) / 2: half the primary's travel times its sign plus the follower's). NaN when
// not a stall homing or a count is missing; the steps' value when the encoders disagree with
// them by more than 1 mm (a broken encoder: logged).
double McuBridge::corexy_stall_homed_mm(int j, double steps_mm) {
  const drivers::HomingSequence& h = *homing_[static_cast<size_t>(j)];
  const drivers::HomingResult& r = h.result();
  const drivers::HomingParams& p = h.params();
  if (!p.stall || !r.has_trigger_encoder || !r.has_follower_encoder) return NAN;
  const size_t ps = static_cast<size_t>(j), fs = static_cast<size_t>(1 - j);
  const double d_primary_mm =
      encoder_mm_[ps].load(std::memory_order_relaxed) -
      static_cast<double>(r.trigger_encoder_counts) * encoder_mm_per_count_[ps];
  const double d_follower_mm =
      encoder_mm_[fs].load(std::memory_order_relaxed) -
      static_cast<double>(r.follower_stop_encoder_counts) * encoder_mm_per_count_[fs];
  const double homed =
      p.position_endstop_mm + 0.5 * (p.motor_sign * d_primary_mm + p.follower_sign * d_follower_mm);
  if (!std::isfinite(homed) || std::fabs(homed - steps_mm) > 1.0) {
    log("stall homing of " + joint_names_[ps] + ": the belts' encoders put the carriage " +
        std::to_string(homed - steps_mm) + " mm from the steps; homed by the steps");  // rare
    return NAN;
  }
  return homed;
}

// CoreXY encoder-index homing, X and Y in one G28: each belt's next index mark after its axis's
// switch is that belt's reference (A's for X, B's for Y, in the belts' coordinates A = x + y,
// B = x - y), and the carriage is x = (A + B) / 2, y = (A - B) / 2 from both. A mark's belt
// position (one of them: they repeat every index period) comes from
// axes.<x|y>.homing.index_position_mm or, at the first homing, from the switches (logged, to be
// kept in the config). NaN for both when not X and Y together with their marks (one axis alone:
// its switch is the reference).
std::array<double, 2> McuBridge::corexy_index_homed_mm() {
  std::array<double, 2> out{NAN, NAN};
  if (!corexy_ || (homing_mask_ & 3u) != 3u || !homing_[0] || !homing_[1]) return out;
  const drivers::HomingResult& rx = homing_[0]->result();
  const drivers::HomingResult& ry = homing_[1]->result();
  if (!rx.has_index || !ry.has_index) {
    if (rx.has_index || ry.has_index) log("corexy index homing needs X and Y homed together");
    return out;
  }
  // Each belt's travel since its mark (mm of belt), and where the switches put it now.
  const double a_since_mm = encoder_mm_[0].load(std::memory_order_relaxed) -
                            static_cast<double>(rx.index_encoder_counts) * encoder_mm_per_count_[0];
  const double b_since_mm = encoder_mm_[1].load(std::memory_order_relaxed) -
                            static_cast<double>(ry.index_encoder_counts) * encoder_mm_per_count_[1];
  const double a_by_switch_mm = homing_result_mm_[0] + homing_result_mm_[1];
  const double b_by_switch_mm = homing_result_mm_[0] - homing_result_mm_[1];
  const char* belt[2] = {"A (x + y)", "B (x - y)"};
  const double since[2] = {a_since_mm, b_since_mm};
  const double by_switch[2] = {a_by_switch_mm, b_by_switch_mm};
  double belt_mm[2];
  for (size_t i = 0; i < 2; ++i) {
    if (!std::isfinite(index_position_mm_[i])) {
      index_position_mm_[i] = by_switch[i] - since[i];
      log("homing of " + joint_names_[i] + ": belt " + belt[i] + "'s encoder index mark is at " +
          std::to_string(index_position_mm_[i]) + " mm by the switches; set axes." +
          joint_names_[i] + ".homing.index_position_mm to keep it");  // once: allocates
    }
    // The marks repeat every index period along the belt, and which one the search found depends
    // on the other axis (A = x + y at the X switch): the switches pick it, as the switch picks the
    // mark on a Cartesian axis (their error must stay within half a period).
    belt_mm[i] = index_position_mm_[i] + since[i];
    if (const double period = index_period_mm_[i]; period > 0.0)
      belt_mm[i] += period * std::round((by_switch[i] - belt_mm[i]) / period);
    if (!std::isfinite(belt_mm[i]) || std::fabs(belt_mm[i] - by_switch[i]) > 1.0) {
      log("corexy index homing: belt " + std::string(belt[i]) + " is " +
          std::to_string(belt_mm[i] - by_switch[i]) +
          " mm from where the switches put it; homed by the switches");  // rare
      return out;
    }
  }
  out[0] = 0.5 * (belt_mm[0] + belt_mm[1]);
  out[1] = 0.5 * (belt_mm[0] - belt_mm[1]);
  return out;
}

// The switches' states for M119: ENDSTOP_QUERY to every joint with an endstop every 100 ms while
// no homing runs (a homing takes the answers itself), the ENDSTOP_STATE answers read back.
void McuBridge::poll_endstops(double now_s) {
  if (homing_state_ == HomingState::kRunning) return;
  for (auto& m : mcus_) {
    protocol::EndstopStateMsg st[8];
    const int mi = static_cast<int>(&m - &mcus_[0]);
    for (size_t n; (n = m->session->take_endstop_states(st, 8)) > 0;)
      for (size_t i = 0; i < n; ++i)
        for (int j = 0; j < kJoints; ++j)
          if (joint_mcu_[static_cast<size_t>(j)] == mi &&
              joint_motor_[static_cast<size_t>(j)] == st[i].axis)
            endstop_state_[static_cast<size_t>(j)].store(st[i].pin != 0 ? 1 : 0,
                                                         std::memory_order_relaxed);
  }
  if (now_s < next_endstop_query_s_) return;
  next_endstop_query_s_ = now_s + 0.1;
  for (int j = 0; j < kJoints; ++j) {
    const size_t js = static_cast<size_t>(j);
    if (!homing_[js]) continue;
    drivers::McuSession& s = *mcus_[static_cast<size_t>(joint_mcu_[js])]->session;
    if (!s.ready() || s.negotiated_version() < 3) continue;
    protocol::EndstopQueryMsg q;
    q.axis = static_cast<uint8_t>(joint_motor_[js]);
    uint8_t buf[8];
    const size_t n = protocol::encode_endstop_query(q, buf, sizeof buf);
    if (n > 0) s.queue_message(buf, n);
  }
}

// A CoreXY sequence done: the homed axis at the endstop plus the mean of both motors' steps after
// the trigger (HomingResult::position_mm), and the other axis moved by the motors' difference over
// the whole sequence (the follower's relayed overshoot). Axes homed earlier in this G28 move with
// it (Y after X: the homed x shifts by what the Y homing did to x).
void McuBridge::corexy_homed(int axis) {
  const drivers::HomingSequence& h = *homing_[static_cast<size_t>(axis)];
  const drivers::HomingResult& r = h.result();
  const drivers::HomingParams& p = h.params();
  // Each motor's travel over the sequence (steps), as A and B.
  const double primary = static_cast<double>(r.stop_steps - r.start_steps);
  const double follower = static_cast<double>(r.follower_stop_steps - r.follower_start_steps);
  const double d_a = axis == 0 ? primary : follower;
  const double d_b = axis == 0 ? follower : primary;
  const std::array<double, 2> moved_mm = {0.5 * (d_a + d_b) * p.mm_per_step,
                                          0.5 * (d_a - d_b) * p.mm_per_step};
  const int other = 1 - axis;
  const size_t os = static_cast<size_t>(other);
  homing_shift_mm_[os] += moved_mm[os];
  if ((homing_finished_ >> other & 1u) != 0) homing_result_mm_[os] += moved_mm[os];
  homing_result_mm_[static_cast<size_t>(axis)] = r.position_mm;
  homing_shift_mm_[static_cast<size_t>(axis)] = 0.0;
}

double McuBridge::homing_shift_mm(int axis) const {
  if (axis < 0 || axis > 2 || !corexy_) return 0.0;
  return homing_shift_mm_[static_cast<size_t>(axis)];
}

double McuBridge::homed_position_mm(int joint) const {
  if (joint < 0 || joint >= kJoints) return NAN;
  return homed_mm_[static_cast<size_t>(joint)].load(std::memory_order_relaxed);
}

int64_t McuBridge::homing_last_step_clock(int joint) const {
  // Only the joints of the last homing (an earlier one's clock is long past the joint's stream).
  // A CoreXY motor is streamed by both carriage sequences: the later clock (one MCU's clock).
  if (joint < 0 || joint >= kJoints) return INT64_MIN;
  int64_t last = INT64_MIN;
  for (int k = 0; k < kJoints; ++k) {
    if (!homing_[static_cast<size_t>(k)] || (homing_started_ >> k & 1u) == 0) continue;
    const auto& hj = homing_joints_[static_cast<size_t>(k)];
    if (hj[0] == joint) last = std::max(last, homing_[static_cast<size_t>(k)]->last_queued_clock());
    if (hj[1] == joint)
      last = std::max(last, homing_[static_cast<size_t>(k)]->follower_last_queued_clock());
  }
  return last;
}

void McuBridge::homing_error(char* out, size_t cap) const {
  if (cap > 0) std::snprintf(out, cap, "%s", homing_error_);
}

int McuBridge::endstop_state(int joint) const {
  if (joint < 0 || joint >= kJoints || !homing_[static_cast<size_t>(joint)]) return -1;
  return endstop_state_[static_cast<size_t>(joint)].load(std::memory_order_relaxed);
}

bool McuBridge::endstop_at_max(int joint) const {
  return joint >= 0 && joint < kJoints && endstop_max_[static_cast<size_t>(joint)];
}

HomingReport McuBridge::homing_report(int joint) const {
  HomingReport r;
  if (joint < 0 || joint >= kJoints) return r;
  const size_t js = static_cast<size_t>(joint);
  r.homed_mm = homed_mm_[js].load();
  r.true_carriage_mm = homed_truth_mm_[js].load();
  r.first_touch_mm = first_touch_mm_[js].load();
  r.count = homing_count_[js].load();
  r.relay_lag_steps = relay_lag_steps_[js].load();
  r.steps_homed_mm = steps_homed_mm_[js].load();
  r.encoder_referenced = encoder_referenced_[js].load();
  return r;
}

// Host time -> the simulation's time line, which starts at the first start(): the virtual MCUs
// and plants begin at t = 0 (they would otherwise integrate from the host clock's epoch).
double McuBridge::sim_time(double host_s) {
  if (!have_epoch_) {
    epoch_s_ = host_s;
    have_epoch_ = true;
    // Real transports stamp their bytes with CLOCK_MONOTONIC, the real-time host clock
    // (core/clock.hpp MonotonicClock); the sessions' time line starts at the epoch.
    for (auto& m : mcus_) m->transport->set_time_base_ns(ns_from_seconds(epoch_s_));
  }
  return host_s - epoch_s_;
}

Status McuBridge::start(double host_s) {
  const double now_s = sim_time(host_s);
  started_ = true;
  last_service_s_ = now_s;
  phase_ = Phase::kStarting;
  ready_since_s_ = -1.0;
  for (auto& m : mcus_) {
    m->estop_sent = false;
    if (Status s = m->session->start(now_s); !s) {
      latch_fault(s.error().message);
      next_restart_s_ = now_s + options_.restart_period_s;
      return s;
    }
  }
  return Status::Ok();
}

void McuBridge::log(std::string message) {
  // FEEDLOOP_DEBUG_EVENTS=1: every link and device-loop event on stderr as it happens.
  static const bool debug = std::getenv("FEEDLOOP_DEBUG_EVENTS") != nullptr;
  if (debug) std::fprintf(stderr, "mcu: %s\n", message.c_str());
  std::lock_guard lock(events_mutex_);
  if (events_.size() < 1000) events_.push_back(std::move(message));
}

std::vector<std::string> McuBridge::events() const {
  std::lock_guard lock(events_mutex_);
  return events_;
}

void McuBridge::latch_fault(const std::string& message) {
  ready_.store(false, std::memory_order_release);
  if (phase_ == Phase::kFaulted) return;
  FaultText t;
  std::snprintf(t.text, sizeof t.text, "%s", message.c_str());
  fault_text_.store(t);
  fault_.store(true, std::memory_order_release);
  phase_ = Phase::kFaulted;
  ++faults_total_;
  log("fault: " + message);
  // Everything else stops now; the MCU that is gone stops on its own watchdog. A stopped MCU
  // turns its heaters off: the thermal loop learns it through their port (a thermal fault).
  for (auto& m : mcus_)
    if (m->heater_port)
      m->heater_port->fail(("the motion side stopped every MCU (" + message +
                            "); a stopped MCU turns its heaters off (one that is gone: by its own "
                            "3 s rule)")
                               .c_str());
  for (auto& m : mcus_)
    if (m->session->ready()) {
      m->session->emergency_stop();
      m->estop_sent = true;
    }
  next_restart_s_ = last_service_s_ + options_.restart_period_s;
  abort_homing(message.c_str());
}

void McuBridge::fault_message(char* out, size_t cap) const {
  if (cap == 0) return;
  const FaultText t = fault_text_.load();
  std::snprintf(out, cap, "%s", fault_.load() ? t.text : "");
}

// The motion MCUs' heaters (servo thread, RT-safe): the link's state published, the thermal
// loop's messages queued once the MCU is identified, its reports handed back with the clock map
// in host time (the sessions run on simulation time: host = simulation + epoch).
void McuBridge::service_heater_ports(double host_s) {
  for (auto& m : mcus_) {
    if (!m->heater_port) continue;
    SharedHeaterPort& port = *m->heater_port;
    drivers::McuSession& s = *m->session;
    const protocol::LinkStats& ls = s.link_stats();
    const uint64_t in = ls.delivered + ls.duplicates_dropped + ls.out_of_order_dropped;
    if (in != m->frames_in) {
      m->frames_in = in;
      m->last_heard_s = host_s;
    }
    port.publish(s.ready(), s.negotiated_version(), s.mcu_clock_hz(), m->last_heard_s);
    SharedHeaterPort::Message msg;
    if (s.ready())
      while (port.take_to_mcu(msg)) s.queue_message(msg.bytes, msg.n);
    const stepgen::TickMap tm = s.tick_map();
    drivers::HeaterPayload buf[8];
    for (size_t k; (k = s.take_heater_messages(buf, 8)) > 0;) {
      for (size_t i = 0; i < k; ++i) {
        msg.n = buf[i].n;
        std::memcpy(msg.bytes, buf[i].bytes, std::min<size_t>(buf[i].n, sizeof msg.bytes));
        msg.clock_ready = s.clock().ready();
        msg.offset_ticks = tm.offset_ticks - tm.ticks_per_s * epoch_s_;
        msg.ticks_per_s = tm.ticks_per_s;
        msg.arrival_s = host_s;
        port.deliver_from_mcu(msg);
      }
      if (k < 8) break;
    }
  }
}

SimulatedHeaterBoard* McuBridge::simulated_heater_board(int mcu) {
  if (mcu < 0 || mcu >= mcu_count()) return nullptr;
  return mcus_[static_cast<size_t>(mcu)]->heaters.get();
}

void McuBridge::poll_all(double now_s) {
  for (auto& m : mcus_) m->session->poll(now_s);
}

stepgen::TickMap McuBridge::tick_map(int joint) const {
  const int i = joint_mcu_[static_cast<size_t>(joint)];
  if (i < 0) return {0.0, 1.0};
  const stepgen::TickMap m = mcus_[static_cast<size_t>(i)]->session->tick_map();  // simulation time
  return {m.offset_ticks - m.ticks_per_s * epoch_s_, m.ticks_per_s};
}

void McuBridge::set_motors_enabled(unsigned joint_mask, bool on) {
  joint_mask &= (1u << kJoints) - 1u;
  if (!on) {
    // A driver switched off holds nothing: a delta's carriages slide under the effector's weight,
    // and a loop still running reads that as a following error (or, falling fast, as an
    // implausible encoder) and stops the MCU. The loops go off first (one session, in order: before
    // the drivers), as for homing, and get no targets while their drivers are off.
    for (int j = 0; j < kJoints; ++j) {
      if (!((joint_mask >> j) & 1u) || !loop_link_.enabled(j)) continue;
      drivers::McuSession& s =
          *mcus_[static_cast<size_t>(joint_mcu_[static_cast<size_t>(j)])]->session;
      loop_link_.disable(
          j, s, static_cast<int64_t>(std::llround(tick_map(j).ticks(last_service_s_ + epoch_s_))));
    }
    motors_off_ |= joint_mask;
  } else if ((motors_off_ & joint_mask) != 0) {
    // On again before a motion or a homing: the loops start with the next target (after M84
    // that is a G28's, which re-bases the frame).
    motors_off_ &= ~joint_mask;
    loops_configured_ = false;
  }
  for (size_t i = 0; i < mcus_.size(); ++i) {
    bool drives = false;
    for (size_t j = 0; j < kJoints; ++j)
      drives = drives || ((joint_mask >> j) & 1u && joint_mcu_[j] == static_cast<int>(i));
    if (drives) mcus_[i]->session->set_enabled(on);
  }
}

void McuBridge::inject_lost_steps(int joint, int64_t steps) {
  if (joint < 0 || joint >= kJoints || !ports_[static_cast<size_t>(joint)]) return;
  ports_[static_cast<size_t>(joint)]->swallow += steps;
}

void McuBridge::inject_encoder_offset(int joint, double offset_mm) {
  if (joint < 0 || joint >= kJoints || !ports_[static_cast<size_t>(joint)]) return;
  const double per_count = encoder_mm_per_count_[static_cast<size_t>(joint)];
  if (!(per_count > 0.0) || !std::isfinite(offset_mm)) return;
  ports_[static_cast<size_t>(joint)]->encoder_offset_counts += std::llround(offset_mm / per_count);
}

double McuBridge::encoder_time_s(int joint) const {
  return encoder_time_s_[static_cast<size_t>(joint)].load(std::memory_order_relaxed);
}

unsigned long long McuBridge::encoder_reports(int joint) const {
  return encoder_reports_[static_cast<size_t>(joint)].load(std::memory_order_relaxed);
}

double McuBridge::encoder_sample_time_s(int joint, int64_t mcu_clock) const {
  if (joint < 0 || joint >= static_cast<int>(kJoints)) return NAN;
  const stepgen::TickMap map = tick_map(joint);
  if (!(map.ticks_per_s > 0.0)) return NAN;
  return (static_cast<double>(mcu_clock) - map.offset_ticks) / map.ticks_per_s -
         encoder_delay_s_[static_cast<size_t>(joint)];
}

double McuBridge::encoder_mm(int joint) const {
  return encoder_mm_[static_cast<size_t>(joint)].load(std::memory_order_relaxed);
}

void McuBridge::collect(double) {
  for (auto& m : mcus_) {
    drivers::McuSession& s = *m->session;
    std::vector<drivers::EncoderSample>& samples = sample_buffer_;
    s.take_encoder_samples(samples);  // swaps buffers: no allocation in steady state
    if (!samples.empty()) {
      for (size_t j = 0; j < kJoints; ++j) {
        if (joint_mcu_[j] < 0 || mcus_[static_cast<size_t>(joint_mcu_[j])].get() != m.get()) continue;
        // Every sample to the recorder (take_encoder_samples); the latest is the joint's reading.
        const drivers::EncoderSample* latest = nullptr;
        for (const drivers::EncoderSample& e : samples) {
          if (e.axis != joint_motor_[j]) continue;
          latest = &e;
          if (encoder_reading_count_ == encoder_readings_.size()) {
            ++encoder_readings_dropped_;
            continue;
          }
          encoder_readings_[encoder_reading_count_++] = {
              static_cast<int>(j), e.clock,
              static_cast<double>(e.counts) * encoder_mm_per_count_[j]};
        }
        if (latest == nullptr) continue;
        encoder_mm_[j].store(static_cast<double>(latest->counts) * encoder_mm_per_count_[j],
                             std::memory_order_relaxed);
        encoder_reports_[j].fetch_add(1, std::memory_order_relaxed);
        // When it was sampled, on the host clock (the clock sync's map, inverted), less the
        // encoder's delay: the instant whose carriage position it shows.
        const double t_s = encoder_sample_time_s(static_cast<int>(j), latest->clock);
        if (std::isfinite(t_s)) encoder_time_s_[j].store(t_s, std::memory_order_relaxed);
      }
      encoder_samples_.fetch_add(samples.size(), std::memory_order_relaxed);
    }
    for (std::string& e : s.take_events()) log(std::move(e));
    if (loop_link_.any_enabled()) {
      DeviceLoopLink::JointEvent ev[32];
      const int mi = static_cast<int>(&m - &mcus_[0]);
      const size_t first_report = device_report_count_;
      const size_t n = loop_link_.collect(s, mi, joint_mcu_, joint_motor_, ev, 32, device_reports_.data(),
                                          device_reports_.size(), &device_report_count_);
      if (device_report_count_ > first_report || n > 0) {
        for (size_t i = first_report; i < device_report_count_; ++i) {  // their host time
          DeviceLoopReport& r = device_reports_[i];
          const stepgen::TickMap map = tick_map(r.joint);
          r.host_time_s = map.ticks_per_s > 0.0 ? (static_cast<double>(r.clock) - map.offset_ticks) / map.ticks_per_s : NAN;
        }
        publish_loop_telemetry();
      }
      for (size_t i = 0; i < n; ++i) {
        const device::LoopEvent& e = ev[i].event;
        if (e.kind == device::LoopEventKind::kSlip) device_slips_.fetch_add(1, std::memory_order_relaxed);
        ServoEvent se;
        se.joint = ev[i].joint;
        bool record = true;
        switch (e.kind) {
          case device::LoopEventKind::kSlip:
            se.kind = ServoEventKind::kLostSteps;
            se.size_mm = static_cast<double>(e.b) * 1e-6;
            break;
          case device::LoopEventKind::kEncoderFault:
            se.kind = ServoEventKind::kEncoderFault;
            se.size_mm = static_cast<double>(e.a) * 1e-6;
            break;
          case device::LoopEventKind::kFollowingError:
            se.kind = ServoEventKind::kFollowingError;
            se.size_mm = static_cast<double>(e.a) * 1e-6;
            break;
          default: record = false;
        }
        if (record && device_event_count_ < device_events_.size()) {
          const stepgen::TickMap map = tick_map(se.joint);
          se.print_time_s = map.ticks_per_s > 0.0 ? (static_cast<double>(e.clock) - map.offset_ticks) / map.ticks_per_s : NAN;
          device_events_[device_event_count_++] = se;
        }
        if (e.kind == device::LoopEventKind::kActivated || e.kind == device::LoopEventKind::kStopDone) continue;
        log(describe_loop_event(joint_names_[static_cast<size_t>(ev[i].joint)], e));  // rare: allocates
      }
    }
  }
}

// CONFIGURE_LOOP for every joint with a device loop, active 10 ms from now on its MCU's clock
// (after every (re)identification: the MCU forgot its loop).
void McuBridge::configure_device_loops(double host_s) {
  for (int j = 0; j < kJoints; ++j) {
    if (!loop_link_.enabled(j) || ((motors_off_ >> j) & 1u) != 0) continue;
    drivers::McuSession& s = *mcus_[static_cast<size_t>(joint_mcu_[static_cast<size_t>(j)])]->session;
    const auto clock = static_cast<int64_t>(std::llround(tick_map(j).ticks(host_s + 0.01)));
    loop_link_.configure(j, s, clock);
  }
}

void McuBridge::queue_target(int joint, int64_t mcu_clock, double r_mm) {
  if (phase_ != Phase::kRunning || !loop_link_.enabled(joint) || ((motors_off_ >> joint) & 1u) != 0)
    return;
  if (!loops_configured_) {  // the loops start with the first motion that streams r(t)
    configure_device_loops(last_service_s_ + epoch_s_);
    loops_configured_ = true;
  }
  drivers::McuSession& s = *mcus_[static_cast<size_t>(joint_mcu_[static_cast<size_t>(joint)])]->session;
  // The loop compares r(t) with the reading that shows the carriage at t: the one sampled the
  // encoder's delay later. (Before the first knot the loop holds the first knot's position.)
  const double delay_ticks =
      encoder_delay_s_[static_cast<size_t>(joint)] * tick_map(joint).ticks_per_s;
  loop_link_.push_target(joint, s, mcu_clock + static_cast<int64_t>(std::llround(delay_ticks)),
                         r_mm);
}

size_t McuBridge::take_device_reports(DeviceLoopReport* out, size_t cap) {
  const size_t n = std::min(cap, device_report_count_);
  for (size_t i = 0; i < n; ++i) out[i] = device_reports_[i];
  // Whatever did not fit stays for the next call, in order.
  for (size_t i = n; i < device_report_count_; ++i) device_reports_[i - n] = device_reports_[i];
  device_report_count_ -= n;
  return n;
}

size_t McuBridge::take_encoder_samples(EncoderReading* out, size_t cap) {
  const size_t n = std::min(cap, encoder_reading_count_);
  for (size_t i = 0; i < n; ++i) out[i] = encoder_readings_[i];
  for (size_t i = n; i < encoder_reading_count_; ++i)
    encoder_readings_[i - n] = encoder_readings_[i];
  encoder_reading_count_ -= n;
  return n;
}

void McuBridge::publish_loop_telemetry() {
  DeviceLoopTelemetrySet set{};
  for (int j = 0; j < kJoints && j < kDeviceLoopJoints; ++j) set[static_cast<size_t>(j)] = loop_link_.telemetry(j);
  loop_telemetry_.store(set);
}

size_t McuBridge::take_device_events(ServoEvent* out, size_t cap) {
  const size_t n = std::min(cap, device_event_count_);
  for (size_t i = 0; i < n; ++i) out[i] = device_events_[i];
  device_event_count_ = 0;
  return n;
}

void McuBridge::flush_targets(bool end_of_motion) {
  if (phase_ != Phase::kRunning) return;
  for (int j = 0; j < kJoints; ++j) {
    if (!loop_link_.enabled(j)) continue;
    loop_link_.flush(j, *mcus_[static_cast<size_t>(joint_mcu_[static_cast<size_t>(j)])]->session, end_of_motion);
  }
}

namespace {
const char* state_name(drivers::McuState s) {
  switch (s) {
    case drivers::McuState::kIdle: return "idle";
    case drivers::McuState::kIdentifying: return "identifying";
    case drivers::McuState::kReady: return "ready";
    case drivers::McuState::kDisconnected: return "disconnected";
    case drivers::McuState::kFailed: return "failed";
  }
  return "?";
}
}  // namespace

// The links' figures for the API (servo thread, RT-safe: fixed arrays and a seqlock), every 10 ms.
void McuBridge::publish_links(double now_s) {
  if (now_s < next_links_s_) return;
  next_links_s_ = now_s + 0.01;
  LinkTelemetrySet& set = links_scratch_;
  set.count = static_cast<int>(std::min<size_t>(mcus_.size(), LinkTelemetrySet::kMaxLinks));
  for (int i = 0; i < set.count; ++i) {
    const Mcu& m = *mcus_[static_cast<size_t>(i)];
    const drivers::McuSession& s = *m.session;
    LinkTelemetry& l = set.links[i];
    std::snprintf(l.name, sizeof l.name, "%s", m.name.c_str());
    std::snprintf(l.state, sizeof l.state, "%s", state_name(s.state()));
    const protocol::LinkStats& ls = s.link_stats();
    l.frames_sent = ls.sent;
    l.retransmitted = ls.retransmitted;
    l.delivered = ls.delivered;
    l.duplicates_dropped = ls.duplicates_dropped;
    l.out_of_order_dropped = ls.out_of_order_dropped;
    l.resets = ls.resets;
    l.crc_errors = s.decoder_stats().crc_errors;
    l.bytes_written = s.bytes_written();
    l.in_flight = s.frames_in_flight();
    const drivers::TransportStats io = m.transport->io_stats();
    l.tx_queue_full = io.tx_full;
    l.tx_blocked = io.tx_blocked;
    l.rx_queue_full = io.rx_queue_full;
    l.io_errors = io.io_errors;
    l.clock_fit_async = s.clock_fit_async();
    const drivers::ClockEstimate& c = s.clock();
    l.clock_samples = c.samples();
    l.rtt_last_us = c.last_rtt_s() * 1e6;
    l.rtt_min_us = c.min_rtt_s() * 1e6;
    l.rtt_mean_us = c.mean_rtt_s() * 1e6;
    const double nominal_hz = static_cast<double>(s.mcu_clock_hz());
    l.clock_rate_ppm = c.ready() && nominal_hz > 0.0 ? (c.freq_hz() / nominal_hz - 1.0) * 1e6 : 0.0;
  }
  links_.store(set);
}

void McuBridge::service(double host_s) {
  if (!started_) {
    (void)start(host_s);  // a failure latches fault(); retried like any other fault
    return;
  }
  const double now_s = sim_time(host_s);
  // Virtual MCUs: the host reads their replies at slice boundaries, not once per servo period.
  // A clock reply read up to a period late would bias the clock estimate by half a period
  // (the midpoint of the round trip, drivers/clock_sync.hpp); slices also keep a delta plant's
  // three ports called in time order across its MCUs.
  if (simulated_ && options_.io_slice_s > 0) {
    for (double t = last_service_s_ + options_.io_slice_s; t < now_s; t += options_.io_slice_s) poll_all(t);
  }
  poll_all(now_s);
  last_service_s_ = now_s;
  if (plant_) {
    plant_->advance_to(now_s);
    // An external plant that failed is gone for good: the machine stops and does not restart.
    if (const char* why = plant_->fault()) {
      latch_fault(why);
      return;
    }
  }
  collect(now_s);
  service_heater_ports(host_s);
  publish_links(now_s);

  auto describe_down = [&]() -> std::string {
    for (auto& m : mcus_) {
      const drivers::McuSession& s = *m->session;
      if (s.state() == drivers::McuState::kFailed)
        return s.error() ? s.error()->message : "MCU '" + m->name + "' failed";
      if (s.state() == drivers::McuState::kDisconnected)
        return "MCU '" + m->name + "' (" + m->transport->describe() + ") disconnected";
    }
    return {};
  };
  switch (phase_) {
    case Phase::kStarting: {
      bool all_ready = true;
      for (auto& m : mcus_) all_ready = all_ready && m->session->ready();
      if (!all_ready) {
        ready_since_s_ = -1.0;
        if (std::string why = describe_down(); !why.empty()) latch_fault(why);
        return;
      }
      if (ready_since_s_ < 0) {
        ready_since_s_ = now_s;
        for (auto& m : mcus_) m->session->set_enabled(true);
      }
      if (now_s - ready_since_s_ >= options_.sync_settle_s) {
        phase_ = Phase::kRunning;
        loops_configured_ = false;  // the MCUs forgot their loops: configured with the first target
        if (fault_.load()) {
          ++recoveries_;
          log("recovered: every MCU re-identified and its clock re-synchronised; position was lost, home before printing");
        }
        fault_.store(false, std::memory_order_release);
        ready_.store(true, std::memory_order_release);
      }
      return;
    }
    case Phase::kRunning:
      if (std::string why = describe_down(); !why.empty()) {
        latch_fault(why + "; motion stopped");
        return;
      }
      if (homing_state_ == HomingState::kRunning) poll_homing(now_s);
      poll_endstops(now_s);
      return;
    case Phase::kFaulted: {
      // Recover once every link is back and every MCU has stopped (queues flushed).
      bool all_stopped = true;
      for (auto& m : mcus_) {
        drivers::McuSession& s = *m->session;
        if (s.state() == drivers::McuState::kDisconnected || !m->transport->connected()) {
          all_stopped = false;
        } else if (s.state() == drivers::McuState::kReady) {
          if (!m->estop_sent) {
            s.emergency_stop();
            m->estop_sent = true;
          }
          all_stopped = false;
        } else if (s.state() != drivers::McuState::kFailed) {
          all_stopped = false;
        }
      }
      if (!all_stopped || now_s < next_restart_s_) return;
      next_restart_s_ = now_s + options_.restart_period_s;
      phase_ = Phase::kStarting;
      ready_since_s_ = -1.0;
      for (auto& p : ports_)  // the steps in flight were flushed by the stops
        if (p) p->head = p->count = 0;
      for (auto& m : mcus_) {
        m->estop_sent = false;
        if (Status s = m->session->start(now_s); !s) {
          phase_ = Phase::kFaulted;
          log(s.error().message);
          return;
        }
      }
      return;
    }
  }
}

void McuBridge::on_batch(const stepgen::StepBatch& b) {
  const size_t joint = b.axis;
  if (joint >= kJoints || joint_mcu_[joint] < 0 || phase_ != Phase::kRunning) {
    ++batches_dropped_;
    return;
  }
  Mcu& m = *mcus_[static_cast<size_t>(joint_mcu_[joint])];
  // What the MCU must execute: counted and hashed (device::step_hash_update) for the checks, and
  // each step's intended host time through the clock estimate in use.
  JointTiming* t = ports_[joint] ? &ports_[joint]->timing : nullptr;
  stepgen::RunDecoder d;
  if (t != nullptr && d.begin(b.body, b.body_bytes)) {
    const drivers::ClockEstimate& clock = m.session->clock();
    int64_t p = d.first_clock();
    stepgen::StepRun r;
    while (!d.done() && d.next(r)) {
      for (uint32_t k = 1; k <= r.count; ++k) {
        const int64_t c = stepgen::run_step_clock(p, r, k);
        t->hash_sent = device::step_hash_update(t->hash_sent, c, r.direction);
        ++t->steps_sent;
        ports_[joint]->push(clock.host_time_at(static_cast<double>(c)));
      }
      p = stepgen::run_end_clock(p, r);
    }
  }
  stepgen::StepBatch out = b;
  out.axis = static_cast<uint8_t>(joint_motor_[joint]);
  m.session->queue_steps(out);
}

const std::string& McuBridge::mcu_name(int i) const { return mcus_[static_cast<size_t>(i)]->name; }
drivers::McuSession& McuBridge::session(int i) { return *mcus_[static_cast<size_t>(i)]->session; }
drivers::MockTransport* McuBridge::mock(int i) { return mcus_[static_cast<size_t>(i)]->mock; }
const device::VirtualMcu* McuBridge::virtual_mcu(int i) const { return mcus_[static_cast<size_t>(i)]->vmcu.get(); }

const JointTiming& McuBridge::timing(int joint) const {
  static const JointTiming kNone{};
  const auto& p = ports_[static_cast<size_t>(joint)];
  return p ? p->timing : kNone;
}

Result<std::shared_ptr<McuBridge>> make_mcu_bridge(const config::MachineConfig& cfg, const McuBridgeOptions& options) {
  auto b = McuBridge::create(cfg, options);
  if (!b.ok()) return b.error();
  return std::shared_ptr<McuBridge>(std::move(b.value()));
}

}  // namespace feedloop::engine
