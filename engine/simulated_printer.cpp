// The simulated transport's factory (see simulated_printer.hpp): the one file of engine/ that
// includes the plant simulator.
#include "engine/simulated_printer.hpp"

#include <cmath>    // NAN
#include <cstdio>   // snprintf
#include <limits>
#include <numbers>  // pi
#include <string>
#include <vector>

#include "drivers/device/heater_board.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/transport/mock_transport.hpp"
#include "engine/config_mapping.hpp"
#include "engine/thermal_config.hpp"
#include "planner/kinematics.hpp"
#include "sim/delta_plant.hpp"
#include "sim/endstop.hpp"
#include "sim/external_plant.hpp"
#include "sim/gantry_axis.hpp"
#include "sim/gantry_params.hpp"
#include "sim/thermal_plant.hpp"
#include "thermal/sensor.hpp"

namespace feedloop::engine {
namespace {

// The config's simulator effects on one gantry axis (config/machine_config.hpp -> sim/).
void apply_effects(const config::SimEffectsConfig& e, const std::string& axis,
                   sim::GantryEffects& g) {
  if (e.coulomb_friction && config::applies_to(*e.coulomb_friction, axis))
    g.coulomb_friction = {true, e.coulomb_friction->force_n};
  if (e.backlash && config::applies_to(*e.backlash, axis))
    g.backlash = {true, e.backlash->width_um};
  if (e.periodic_position && config::applies_to(*e.periodic_position, axis)) {
    g.periodic_position.enabled = true;
    g.periodic_position.period_mm = e.periodic_position->period_mm;
    g.periodic_position.amplitude_um = e.periodic_position->amplitude_um;
  }
  if (e.extra_resonance && config::applies_to(*e.extra_resonance, axis)) {
    g.extra_resonance.enabled = true;
    g.extra_resonance.freq_hz = e.extra_resonance->freq_hz;
    g.extra_resonance.damping = e.extra_resonance->damping;
  }
  if (e.time_delay && config::applies_to(*e.time_delay, axis))
    g.time_delay = {true, e.time_delay->delay_ms};
  if (e.scale_error && config::applies_to(*e.scale_error, axis))
    g.scale_error = {true, e.scale_error->scale};
}

// A delta carriage's motor port with the endstop switch at the top of its tower (Klipper's delta:
// every carriage homes up to its own switch): the plant's port, and the switch read on the
// carriage's true height.
class DeltaEndstopPort final : public device::MotorPort {
 public:
  DeltaEndstopPort(sim::DeltaPlant& plant, int carriage, sim::EndstopSwitch& sw)
      : plant_(&plant), port_(&plant.carriage_port(carriage)), carriage_(carriage), sw_(&sw) {}
  void step(double t_s, int direction) override { port_->step(t_s, direction); }
  void set_enabled(double t_s, bool enabled) override { port_->set_enabled(t_s, enabled); }
  void set_step_fraction(double t_s, float f) override { port_->set_step_fraction(t_s, f); }
  int64_t read_encoder_counts(double t_s) override { return port_->read_encoder_counts(t_s); }
  bool read_encoder_index(double t_s) override { return port_->read_encoder_index(t_s); }
  bool read_endstop(double t_s) override {
    plant_->advance_to(t_s);
    return sw_->sample(plant_->carriage_mm(carriage_));
  }

 private:
  sim::DeltaPlant* plant_;
  device::MotorPort* port_;
  int carriage_;
  sim::EndstopSwitch* sw_;
};

// A CoreXY motor's port with the switch of the Cartesian carriage it homes (motor A: the X
// switch, B: the Y switch, as the bridge reads them): the switch sees the carriage where both
// belts put it, x = (A + B) / 2, y = (A - B) / 2 (planner/linear_kinematics.hpp).
class CoreXyEndstopPort final : public device::MotorPort {
 public:
  CoreXyEndstopPort(sim::GantryAxis& own, sim::GantryAxis& a, sim::GantryAxis& b, int b_sign,
                    sim::EndstopSwitch& sw)
      : own_(&own), a_(&a), b_(&b), b_sign_(b_sign), sw_(&sw) {}
  void step(double t_s, int direction) override { own_->step(t_s, direction); }
  void set_enabled(double t_s, bool enabled) override { own_->set_enabled(t_s, enabled); }
  void set_step_fraction(double t_s, float f) override { own_->set_step_fraction(t_s, f); }
  int64_t read_encoder_counts(double t_s) override { return own_->read_encoder_counts(t_s); }
  bool read_encoder_index(double t_s) override { return own_->read_encoder_index(t_s); }
  bool read_endstop(double t_s) override {
    a_->advance_to(t_s);
    b_->advance_to(t_s);
    return sw_->sample(0.5 * (a_->carriage_mm() + b_sign_ * b_->carriage_mm()));
  }

 private:
  sim::GantryAxis* own_;
  sim::GantryAxis* a_;
  sim::GantryAxis* b_;
  int b_sign_;
  sim::EndstopSwitch* sw_;
};

// The plants of one machine: a GantryAxis per Cartesian joint, or one DeltaPlant.
class SimulatedPrinter final : public SimulatedPlant {
 public:
  device::MotorPort* motor(int joint) override {
    if (joint < 0 || joint >= kJoints) return nullptr;
    if (external_port_[static_cast<size_t>(joint)]) return external_port_[static_cast<size_t>(joint)];
    if (delta_endstop_ports_[static_cast<size_t>(joint)])
      return delta_endstop_ports_[static_cast<size_t>(joint)].get();
    if (delta_) return joint < 3 ? &delta_->carriage_port(joint) : nullptr;
    if (endstop_ports_[static_cast<size_t>(joint)])
      return endstop_ports_[static_cast<size_t>(joint)].get();
    if (joint < 2 && corexy_ports_[static_cast<size_t>(joint)])
      return corexy_ports_[static_cast<size_t>(joint)].get();
    return gantries_[static_cast<size_t>(joint)].get();
  }
  double encoder_mm_per_count(int joint) const override {
    return joint < 0 || joint >= kJoints ? 0.0 : encoder_mm_per_count_[static_cast<size_t>(joint)];
  }
  void advance_to(double t_s) override {
    for (auto& g : gantries_)
      if (g) g->advance_to(t_s);
    if (delta_) delta_->advance_to(t_s);
    if (external_) external_->advance_to(t_s);
  }
  double carriage_mm(int joint) const override {
    if (joint < 0 || joint >= kJoints) return NAN;
    if (const sim::ExternalAxisPort* e = external_port_[static_cast<size_t>(joint)]) return e->carriage_mm();
    if (delta_) return joint < 3 ? delta_->carriage_mm(joint) : NAN;
    const auto& g = gantries_[static_cast<size_t>(joint)];
    return g ? g->carriage_mm() : NAN;
  }
  const char* fault() const override {
    return external_ && external_->faulted() ? external_->fault().c_str() : nullptr;
  }
  std::array<double, 3> nozzle_mm() const override {
    if (delta_ && external_) return {NAN, NAN, NAN};  // the carriages are the external plant's
    if (delta_) {
      const Eigen::Vector3d n = delta_->nozzle_mm();
      return {n[0], n[1], n[2]};
    }
    if (corexy_) {
      // The belts' ends are the motors' A = x + y and B = x - y (planner/linear_kinematics.hpp):
      // the Cartesian carriage is their half sum and half difference.
      const double a = carriage_mm(0), b = carriage_mm(1);
      return {0.5 * (a + b), 0.5 * (a - b), carriage_mm(2)};
    }
    return {carriage_mm(0), carriage_mm(1), carriage_mm(2)};
  }
  int64_t lost_full_steps(int joint) const override {
    const sim::GantryAxis* g = gantry(joint);
    return g ? g->lost_full_steps() : 0;
  }
  int64_t slip_events(int joint) const override {
    const sim::GantryAxis* g = gantry(joint);
    return g ? g->slip_events() : 0;
  }
  bool motor_enabled(int joint) const override {
    if (delta_ && joint >= 0 && joint < 3) return delta_->motor_enabled(joint);
    const sim::GantryAxis* g = gantry(joint);
    return g ? g->enabled() : true;
  }

  sim::GantryAxis* gantry(int joint) const {
    return joint < 0 || joint >= kJoints ? nullptr : gantries_[static_cast<size_t>(joint)].get();
  }
  sim::DeltaPlant* delta() const { return delta_.get(); }

  std::array<std::unique_ptr<sim::GantryAxis>, kJoints> gantries_;  // by joint (nullptr: none)
  // The endstop switch on a gantry joint with a homing section, and the port that reads it.
  std::array<std::unique_ptr<sim::EndstopSwitch>, kJoints> switches_;
  std::array<std::unique_ptr<sim::EndstopAxis>, kJoints> endstop_ports_;
  std::array<std::unique_ptr<DeltaEndstopPort>, kJoints> delta_endstop_ports_;
  std::array<std::unique_ptr<CoreXyEndstopPort>, 2> corexy_ports_;  // motors A, B (CoreXY)
  std::unique_ptr<sim::DeltaPlant> delta_;
  bool corexy_ = false;  // joints 0, 1 are the CoreXY motors A, B (nozzle_mm mixes them)
  std::unique_ptr<sim::ExternalPlant> external_;                       // simulator.external_plant
  std::array<sim::ExternalAxisPort*, kJoints> external_port_{};       // by joint (nullptr: built-in)
  std::array<double, kJoints> encoder_mm_per_count_{};
};

// The simulated printer's heater MCU: the device code (a VirtualMcu without motors hosting a
// HeaterBoard) driving a thermal plant per heater and the part fans, behind a mock transport. The
// thermal loop reaches it only through its McuSession and frames (McuHeaterLink).
// The thermal plants and fans one simulated heater board drives (its channels 0, 1, ..: the
// config's heaters and fans of those indices), and the board. Hosted by a heater-only VirtualMcu
// (SimulatedHeaterMcu) or by a motion MCU's (McuBridge, heaters named on a motion MCU).
class SimulatedHeaterRig final : public SimulatedHeaterBoard {
 public:
  SimulatedHeaterRig(const config::MachineConfig& cfg, const std::vector<int>& heaters,
                     const std::vector<int>& fans, double clock_hz) {
    for (size_t i = 0; i < heaters.size() && i < 4; ++i) {
      const config::HeaterConfig& h = cfg.heaters[static_cast<size_t>(heaters[i])];
      sim::ThermalPlantParams p;
      p.power_w = h.plant.power_w;
      p.heat_capacity_j_k = h.plant.heat_capacity_j_k;
      p.loss_w_k = h.plant.loss_w_k;
      p.fan_loss_w_k = h.plant.fan_loss_w_k;
      p.delay_s = h.plant.delay_s;
      p.sensor_tau_s = h.plant.sensor_tau_s;
      p.ambient_c = h.plant.ambient_c;
      p.seed = cfg.simulator.seed + 9000 + 31 * static_cast<uint64_t>(heaters[i]);
      p.sensor = heater_sensor(h);
      plants_.push_back(std::make_unique<sim::ThermalPlant>(p));
      heater_ports_[i] = plants_.back().get();
    }
    for (size_t i = 0; i < fans.size() && i < 4; ++i) {
      fans_.push_back(std::make_unique<sim::PartFan>());
      if (cfg.fans[static_cast<size_t>(fans[i])].kind == config::FanKind::part)  // part fans blow on the extruders' blocks
        for (size_t k = 0; k < heaters.size() && k < 4; ++k)
          if (cfg.heaters[static_cast<size_t>(heaters[k])].kind == config::HeaterKind::extruder)
            fans_.back()->attach(plants_[k].get());
      fan_ports_[i] = fans_.back().get();
    }
    // The board's ports take clock / clock_hz as time.
    board_ =
        std::make_unique<device::HeaterBoard>(heater_ports_, static_cast<int>(plants_.size()),
                                              fan_ports_, static_cast<int>(fans_.size()), clock_hz);
  }
  device::HeaterBoard& board() override { return *board_; }
  sim::ThermalPlant* plant(int i) override {
    return i >= 0 && i < static_cast<int>(plants_.size()) ? plants_[static_cast<size_t>(i)].get() : nullptr;
  }
  sim::PartFan* fan(int i) override {
    return i >= 0 && i < static_cast<int>(fans_.size()) ? fans_[static_cast<size_t>(i)].get() : nullptr;
  }

 private:
  std::vector<std::unique_ptr<sim::ThermalPlant>> plants_;
  std::vector<std::unique_ptr<sim::PartFan>> fans_;
  device::HeaterPort* heater_ports_[4] = {};
  device::FanPort* fan_ports_[4] = {};
  std::unique_ptr<device::HeaterBoard> board_;
};

// A heater-only MCU: the rig on a VirtualMcu without motors.
class SimulatedHeaterMcu final : public SimulatedHeaterDevice {
 public:
  SimulatedHeaterMcu(const config::MachineConfig& cfg, const std::vector<int>& heaters,
                     const std::vector<int>& fans, double clock_hz, const std::string& name)
      : rig_(cfg, heaters, fans, clock_hz) {
    device::VirtualMcuParams vp;
    vp.clock_hz = clock_hz;  // no drift, no offset
    std::snprintf(vp.name, sizeof vp.name, "%s", name.c_str());
    device::MotorPort* none = nullptr;
    vmcu_ = std::make_unique<device::VirtualMcu>(vp, &none, 1, &rig_.board());
  }
  sim::ThermalPlant* plant(int i) { return rig_.plant(i); }
  sim::PartFan* fan(int i) { return rig_.fan(i); }
  device::VirtualMcu& vmcu() override { return *vmcu_; }
  const device::HeaterBoard& board() const override {
    return const_cast<SimulatedHeaterRig&>(rig_).board();
  }

 private:
  SimulatedHeaterRig rig_;
  std::unique_ptr<device::VirtualMcu> vmcu_;
};

// The simulated endstop switch of joint js (its own seed), as the config's homing places it.
Result<std::unique_ptr<sim::EndstopSwitch>> simulated_switch(const config::MachineConfig& cfg,
                                                             const config::HomingConfig& h, size_t js,
                                                             const std::string& name) {
  sim::EndstopSwitchParams sp;
  sp.position_mm = h.position_endstop_mm;
  sp.at_min = h.direction == config::EndstopSide::min;
  sp.sigma_mm = cfg.simulator.endstops.sigma_um * 1e-3;
  sp.hysteresis_mm = cfg.simulator.endstops.hysteresis_um * 1e-3;
  sp.seed = cfg.simulator.seed + 5000 + 1000 * js;
  auto sw = sim::EndstopSwitch::create(sp);
  if (!sw.ok()) return Error{"simulated endstop of " + name + ": " + sw.error().message};
  return std::make_unique<sim::EndstopSwitch>(std::move(sw.value()));
}

}  // namespace

std::unique_ptr<SimulatedHeaterBoard> make_simulated_heater_board(const config::MachineConfig& cfg,
                                                                  const std::vector<int>& heaters,
                                                                  const std::vector<int>& fans,
                                                                  double clock_hz) {
  return std::make_unique<SimulatedHeaterRig>(cfg, heaters, fans, clock_hz);
}

std::unique_ptr<SimulatedHeaterDevice> make_simulated_heater_device(
    const config::MachineConfig& cfg, const std::vector<int>& heaters, const std::vector<int>& fans,
    double clock_hz, const std::string& name) {
  return std::make_unique<SimulatedHeaterMcu>(cfg, heaters, fans, clock_hz, name);
}

HeaterMcu simulated_heater_mcu(const config::MachineConfig& cfg, const std::vector<int>& heaters,
                               const std::vector<int>& fans, double clock_hz,
                               const std::string& name, uint64_t fault_seed) {
  HeaterMcu m;
  m.name = name;
  m.sim = make_simulated_heater_device(cfg, heaters, fans, clock_hz, name);
  drivers::MockFaults f;
  f.seed = fault_seed;
  auto t = std::make_unique<drivers::MockTransport>(m.sim->vmcu(), f, m.name);
  m.mock = t.get();
  m.transport = std::move(t);
  m.session = heater_session_params(name);
  return m;
}

std::unique_ptr<McuHeaterLink> make_simulated_heater_link(const config::MachineConfig& cfg,
                                                          double host_clock_hz) {
  // One heater MCU for every heater and fan (at most 4 of each, the board's limit), at the
  // configured MCU clock rate.
  std::vector<int> heaters, fans;
  std::vector<HeaterRoute> hr, fr;
  for (size_t i = 0; i < cfg.heaters.size() && i < 4; ++i) {
    heaters.push_back(static_cast<int>(i));
    hr.push_back({0, static_cast<uint8_t>(i)});
  }
  for (size_t i = 0; i < cfg.fans.size() && i < 4; ++i) {
    fans.push_back(static_cast<int>(i));
    fr.push_back({0, static_cast<uint8_t>(i)});
  }
  std::vector<HeaterMcu> mcus;
  mcus.push_back(simulated_heater_mcu(cfg, heaters, fans,
                                      static_cast<double>(cfg.stepgen.mcu_clock_hz), "heaters",
                                      cfg.simulator.seed + 9500));
  return std::make_unique<McuHeaterLink>(std::move(mcus), std::move(hr), std::move(fr), host_clock_hz);
}

sim::ThermalPlant* simulated_thermal_plant(HeaterLink& link, int heater) {
  auto* l = dynamic_cast<McuHeaterLink*>(&link);
  if (l == nullptr || heater < 0 || heater >= l->num_heaters()) return nullptr;
  const HeaterRoute& r = l->heater_route(heater);
  auto* device = dynamic_cast<SimulatedHeaterMcu*>(l->sim(r.mcu));
  return device != nullptr ? device->plant(r.local) : nullptr;
}
sim::PartFan* simulated_part_fan(HeaterLink& link, int fan) {
  auto* l = dynamic_cast<McuHeaterLink*>(&link);
  if (l == nullptr || fan < 0 || fan >= l->num_fans()) return nullptr;
  const HeaterRoute& r = l->fan_route(fan);
  auto* device = dynamic_cast<SimulatedHeaterMcu*>(l->sim(r.mcu));
  return device != nullptr ? device->fan(r.local) : nullptr;
}

Result<sim::GantryAxisParams> simulated_gantry_params(const config::MachineConfig& cfg, int joint) {
  const auto names = joint_names(cfg);
  const auto spm = steps_per_mm(cfg);
  const size_t js = static_cast<size_t>(joint);
  if (joint < 0 || joint > 2)
    return Error{"simulated gantry: joint " + std::to_string(joint) + " is not x, y or z"};
  sim::GantryAxisParams p = joint == 1 ? sim::thesis_y_axis() : sim::thesis_x_axis();
  if (!(spm[js] > 0)) return Error{"axis " + names[js] + ": steps_per_mm must be > 0"};
  // The pulley that gives the configured steps/mm (x, y: the thesis's 5.40 mm).
  p.pulley_radius_mm = p.full_steps_per_rev * p.microsteps / (2.0 * std::numbers::pi * spm[js]);
  p.encoder.noise_um = cfg.simulator.encoder_noise_um;
  p.encoder.sampling_delay_s = cfg.simulator.sample_delay_us * 1e-6;
  if (const config::AxisConfig* a = cfg.axis(names[js]); a && a->encoder) {
    p.encoder.resolution_um = a->encoder->resolution_um;
    p.encoder.index_period_mm = a->encoder->index_period_mm;
  }
  p.seed = cfg.simulator.seed + 1000 * js;
  apply_effects(cfg.simulator.effects, names[js], p.effects);
  // direction_dependent_stiffness: the belt anchor offset x0 of Eq. 6 that gives K2(pulling +) /
  // K2(pulling -) = ratio at x2 = 0, ratio = (L + x0) / (L - x0). The LPV feedforward's model has
  // x0 = 0, so its direction dependence is off by as much.
  if (const auto& d = cfg.simulator.effects.direction_dependent_stiffness;
      d && config::applies_to(*d, names[js]))
    p.belt_x0_mm = p.belt_span_mm * (d->ratio - 1.0) / (d->ratio + 1.0);
  return p;
}

Result<std::unique_ptr<SimulatedPlant>> make_simulated_printer(const config::MachineConfig& cfg) {
  const auto names = joint_names(cfg);
  const auto spm = steps_per_mm(cfg);
  auto out = std::make_unique<SimulatedPrinter>();
  if (cfg.kinematics == config::Kinematics::delta) {
    sim::DeltaPlantParams dp;
    dp.mm_per_step = 1.0 / spm[0];
    dp.initial_nozzle_mm = Eigen::Vector3d::Zero();  // where the planner starts
    bool switches = true;  // every tower has a homing section: a switch at its top
    for (int j = 0; j < 3; ++j) {
      const config::AxisConfig* a = cfg.axis(names[static_cast<size_t>(j)]);
      switches = switches && a != nullptr && a->homing;
    }
    if (switches && !cfg.planner.allow_moves_before_homing) {
      // The machine must home: the carriages start start_distance_mm below their switches (a
      // short G28), the nozzle where the planner's kinematics puts them.
      const auto kin = planner::make_kinematics(planner_config(cfg));
      planner::Joints q{};
      for (int j = 0; j < 3; ++j) {
        const config::HomingConfig& h = *cfg.axis(names[static_cast<size_t>(j)])->homing;
        const double d = cfg.simulator.endstops.start_distance_mm;
        q[static_cast<size_t>(j)] =
            h.position_endstop_mm + (h.direction == config::EndstopSide::min ? d : -d);
      }
      auto n = kin->forward(q);
      if (!n.ok())
        return Error{"simulated delta: no nozzle position below the endstops: " +
                     n.error().message};
      dp.initial_nozzle_mm = Eigen::Vector3d(n.value()[0], n.value()[1], n.value()[2]);
    }
    dp.seed = cfg.simulator.seed;
    dp.encoder.noise_um = cfg.simulator.encoder_noise_um;
    dp.encoder.sampling_delay_s = cfg.simulator.sample_delay_us * 1e-6;
    for (int j = 0; j < 3; ++j) {
      const config::AxisConfig* a = cfg.axis(names[static_cast<size_t>(j)]);
      if (a && a->encoder && a->encoder->index_period_mm > 0.0)
        dp.encoder.index_period_mm = a->encoder->index_period_mm;
      if (a && a->homing && a->homing->stall && a->homing->direction == config::EndstopSide::max)
        dp.hard_stop_max_mm[static_cast<size_t>(j)] = a->homing->position_endstop_mm;
    }
    auto d = sim::DeltaPlant::create(dp);
    if (!d.ok()) return Error{"simulated delta: " + d.error().message};
    out->delta_ = std::move(d.value());
    for (int j = 0; j < 3; ++j)
      out->encoder_mm_per_count_[static_cast<size_t>(j)] = dp.encoder.resolution_um * 1e-3;
    for (int j = 0; switches && j < 3; ++j) {
      const size_t js = static_cast<size_t>(j);
      const config::HomingConfig& h = *cfg.axis(names[js])->homing;
      auto sw = simulated_switch(cfg, h, js, names[js]);
      if (!sw.ok()) return sw.error();
      out->switches_[js] = std::move(sw.value());
      out->delta_endstop_ports_[js] =
          std::make_unique<DeltaEndstopPort>(*out->delta_, j, *out->switches_[js]);
    }
  } else {
    // CoreXY with switches on X and Y: on the Cartesian carriage, which starts start_distance_mm
    // from both (the motors where A = x + y, B = x - y put it) when the machine must home.
    const bool corexy = cfg.kinematics == config::Kinematics::corexy;
    out->corexy_ = corexy;
    const config::AxisConfig* cx = cfg.axis(names[0]);
    const config::AxisConfig* cy = cfg.axis(names[1]);
    const bool corexy_switches = corexy && cx && cx->homing && cy && cy->homing;
    std::array<double, 2> corexy_start_mm{};  // x, y
    for (size_t i = 0; corexy_switches && i < 2; ++i) {
      const config::HomingConfig& h = *(i == 0 ? cx : cy)->homing;
      const double d = cfg.simulator.endstops.start_distance_mm;
      corexy_start_mm[i] = h.position_endstop_mm + (h.direction == config::EndstopSide::min ? d : -d);
    }
    for (int j = 0; j < 3; ++j) {
      const size_t js = static_cast<size_t>(j);
      auto p = simulated_gantry_params(cfg, j);
      if (!p) return p.error();
      const config::AxisConfig* ac = cfg.axis(names[js]);
      const bool has_switch = ac != nullptr && ac->homing &&
                              (cfg.kinematics == config::Kinematics::cartesian || (corexy && j == 2));
      if (corexy_switches && j < 2 && !cfg.planner.allow_moves_before_homing)
        p.value().initial_pos_mm =
            corexy_start_mm[0] + (j == 0 ? 1.0 : -1.0) * corexy_start_mm[1];
      if (has_switch && !cfg.planner.allow_moves_before_homing) {
        // The machine must home: the carriage starts near its switch (a short G28), on the travel
        // side of it. With moves allowed before homing it starts at 0, where the planner does.
        const config::HomingConfig& h = *ac->homing;
        const double d = cfg.simulator.endstops.start_distance_mm;
        p.value().initial_pos_mm =
            h.position_endstop_mm + (h.direction == config::EndstopSide::min ? d : -d);
      }
      if (corexy_switches && j < 2 && (cx->homing->stall || cy->homing->stall))
        p.value().coupled_stops = true;       // the carriage's hard stops act on both belts (below)
      if (has_switch && ac->homing->stall) {  // stall homing: the frame's hard stop there
        const config::HomingConfig& h = *ac->homing;
        (h.direction == config::EndstopSide::min ? p.value().hard_stop_min_mm
                                                 : p.value().hard_stop_max_mm) =
            h.position_endstop_mm;
      }
      auto g = sim::GantryAxis::create(p.value());
      if (!g.ok()) return Error{"simulated axis " + names[js] + ": " + g.error().message};
      out->gantries_[js] = std::make_unique<sim::GantryAxis>(std::move(g.value()));
      out->encoder_mm_per_count_[js] = out->gantries_[js]->encoder_mm_per_count();
      if (has_switch) {
        auto sw = simulated_switch(cfg, *ac->homing, js, names[js]);
        if (!sw.ok()) return sw.error();
        out->switches_[js] = std::move(sw.value());
        out->endstop_ports_[js] =
            std::make_unique<sim::EndstopAxis>(*out->gantries_[js], *out->switches_[js]);
      }
    }
    // CoreXY stall homing: the frame's hard stop on the carriage's x (or y) at the endstop,
    // x = (A + B) / 2 and y = (A - B) / 2 of the belts' ends, felt by both belts.
    for (int i = 0; corexy_switches && i < 2; ++i) {
      const config::HomingConfig& h = *(i == 0 ? cx : cy)->homing;
      if (!h.stall) continue;
      const bool at_min = h.direction == config::EndstopSide::min;
      const double lo = at_min ? h.position_endstop_mm : -std::numeric_limits<double>::infinity();
      const double hi = at_min ? std::numeric_limits<double>::infinity() : h.position_endstop_mm;
      const double b = i == 0 ? 0.5 : -0.5;  // B's coefficient in x or y
      out->gantries_[0]->add_coupled_stop(*out->gantries_[1], 0.5, b, lo, hi);
      out->gantries_[1]->add_coupled_stop(*out->gantries_[0], b, 0.5, lo, hi);
    }
    for (int j = 0; corexy_switches && j < 2; ++j) {
      const size_t js = static_cast<size_t>(j);
      auto sw = simulated_switch(cfg, *cfg.axis(names[js])->homing, js, names[js]);
      if (!sw.ok()) return sw.error();
      out->switches_[js] = std::move(sw.value());
      out->corexy_ports_[js] = std::make_unique<CoreXyEndstopPort>(
          *out->gantries_[js], *out->gantries_[0], *out->gantries_[1], j == 0 ? 1 : -1,
          *out->switches_[js]);
    }
  }
  if (const auto& ext = cfg.simulator.external_plant) {
    // Where each joint starts: the planner's joint position at the origin (Cartesian: 0; delta:
    // the carriage heights with the nozzle at 0, 0, 0).
    const auto kin = planner::make_kinematics(planner_config(cfg));
    const planner::Joints start = kin->inverse(planner::Vec3{0.0, 0.0, 0.0});
    sim::ExternalPlantParams xp;
    xp.command = ext->command;
    xp.period_s = ext->period_us * 1e-6;
    std::array<int, kJoints> joint_of{};
    for (size_t i = 0; i < ext->axes.size(); ++i) {
      int j = -1;
      for (int k = 0; k < kJoints; ++k)
        if (names[static_cast<size_t>(k)] == ext->axes[i]) j = k;
      if (j < 0) return Error{"simulator.external_plant: axis '" + ext->axes[i] + "' is not a joint of this machine"};
      const size_t js = static_cast<size_t>(j);
      sim::ExternalAxisParams a;
      a.name = ext->axes[i];
      a.mm_per_step = 1.0 / spm[js];
      a.start_mm = j < 3 ? start[js] : 0.0;
      a.encoder.noise_um = cfg.simulator.encoder_noise_um;
      a.encoder.sampling_delay_s = cfg.simulator.sample_delay_us * 1e-6;
      if (const config::AxisConfig* ac = cfg.axis(names[js]); ac && ac->encoder)
        a.encoder.resolution_um = ac->encoder->resolution_um;
      a.seed = cfg.simulator.seed + 7000 + 1000 * js;
      xp.axes.push_back(a);
      joint_of[i] = j;
    }
    auto plant = sim::ExternalPlant::start(xp);
    if (!plant) return plant.error();
    out->external_ = std::move(plant.value());
    for (size_t i = 0; i < ext->axes.size(); ++i) {
      const size_t js = static_cast<size_t>(joint_of[i]);
      out->external_port_[js] = &out->external_->port(static_cast<int>(i));
      out->encoder_mm_per_count_[js] = out->external_port_[js]->encoder_mm_per_count();
    }
  }
  return std::unique_ptr<SimulatedPlant>(std::move(out));
}

sim::GantryAxis* simulated_gantry(SimulatedPlant& plant, int joint) {
  auto* p = dynamic_cast<SimulatedPrinter*>(&plant);
  return p ? p->gantry(joint) : nullptr;
}

sim::DeltaPlant* simulated_delta(SimulatedPlant& plant) {
  auto* p = dynamic_cast<SimulatedPrinter*>(&plant);
  return p ? p->delta() : nullptr;
}

}  // namespace feedloop::engine
