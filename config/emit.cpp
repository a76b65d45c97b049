// MachineConfig -> YAML with every key written out (to_yaml). Numbers use the shortest text that
// reads back exactly, so to_yaml followed by load_config_text gives an equal MachineConfig.
#include <cmath>  // isfinite
#include <cstdio>  // snprintf

#include "config/config.hpp"
#include "config/enum_names.hpp"
#include "config/map_reader.hpp"

namespace feedloop::config {
namespace {

class Writer {
 public:
  Writer() { out_ << YAML::BeginMap; }
  std::string finish() {
    out_ << YAML::EndMap;
    return std::string(out_.c_str()) + "\n";
  }
  void num(const char* key, double v) { out_ << YAML::Key << key << YAML::Value << format_number(v); }
  void integer(const char* key, long long v) { out_ << YAML::Key << key << YAML::Value << v; }
  void boolean(const char* key, bool v) {
    out_ << YAML::Key << key << YAML::Value << (v ? "true" : "false");
  }
  void str(const char* key, const std::string& v) {
    out_ << YAML::Key << key << YAML::Value << YAML::DoubleQuoted << v;
  }
  void word(const char* key, const std::string& v) { out_ << YAML::Key << key << YAML::Value << v; }
  void list(const char* key, const std::vector<std::string>& v) {
    out_ << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const std::string& s : v) out_ << s;
    out_ << YAML::EndSeq;
  }
  void begin(const std::string& key) { out_ << YAML::Key << key << YAML::Value << YAML::BeginMap; }
  void end() { out_ << YAML::EndMap; }
  YAML::Emitter& raw() { return out_; }

 private:
  YAML::Emitter out_;
};

void write_axes(Writer& w, const MachineConfig& c) {
  w.begin("axes");
  for (const AxisConfig& a : c.axes) {
    w.begin(a.name);
    w.num("steps_per_mm", a.steps_per_mm);
    w.boolean("invert_direction", a.invert_direction);
    if (a.encoder) {
      w.begin("encoder");
      w.num("resolution_um", a.encoder->resolution_um);
      if (a.encoder->index_period_mm > 0.0) w.num("index_period_mm", a.encoder->index_period_mm);
      w.end();
    }
    if (std::isfinite(a.min_mm)) w.num("min_mm", a.min_mm);
    if (std::isfinite(a.max_mm)) w.num("max_mm", a.max_mm);
    w.num("max_velocity_mm_s", a.max_velocity_mm_s);
    w.num("max_accel_mm_s2", a.max_accel_mm_s2);
    if (a.homing) {
      const HomingConfig& h = *a.homing;
      w.begin("homing");
      w.word("direction", enum_name(endstop_side_names(), h.direction));
      w.num("position_endstop_mm", h.position_endstop_mm);
      w.num("homing_speed_mm_s", h.homing_speed_mm_s);
      w.num("second_homing_speed_mm_s", h.second_homing_speed_mm_s);
      w.num("retract_dist_mm", h.retract_dist_mm);
      w.num("max_travel_mm", h.max_travel_mm);
      if (h.index) w.boolean("index", true);
      if (h.index_position_mm) w.num("index_position_mm", *h.index_position_mm);
      if (h.stall) {
        w.boolean("stall", true);
        w.num("stall_threshold_mm", h.stall_threshold_mm);
      }
      w.end();
    }
    w.end();
  }
  w.end();
  if (c.delta) {
    const DeltaGeometryConfig& g = *c.delta;
    w.begin("delta");
    w.num("radius_mm", g.radius_mm);
    w.num("arm_length_mm", g.arm_length_mm);
    w.num("nozzle_offset_mm", g.nozzle_offset_mm);
    w.num("angle_a_deg", g.angle_a_deg);
    w.num("angle_b_deg", g.angle_b_deg);
    w.num("angle_c_deg", g.angle_c_deg);
    w.num("print_radius_mm", g.print_radius_mm);
    w.num("z_min_mm", g.z_min_mm);
    w.num("z_max_mm", g.z_max_mm);
    w.end();
  }
}

void write_motion(Writer& w, const MachineConfig& c) {
  const PlannerConfig& p = c.planner;
  w.begin("planner");
  w.num("max_velocity_mm_s", p.max_velocity_mm_s);
  w.num("max_accel_mm_s2", p.max_accel_mm_s2);
  w.num("junction_deviation_mm", p.junction_deviation_mm);
  w.num("square_corner_velocity_mm_s", p.square_corner_velocity_mm_s);
  w.num("min_cruise_ratio", p.min_cruise_ratio);
  w.boolean("allow_moves_before_homing", p.allow_moves_before_homing);
  w.word("cornering", enum_name(cornering_names(), p.cornering));
  w.num("max_speed_change_mm_s", p.max_speed_change_mm_s);
  w.begin("sharp_corner");
  w.num("alpha_a_deg", p.sharp_corner.alpha_a_deg);
  w.num("alpha_b_deg", p.sharp_corner.alpha_b_deg);
  w.num("a1", p.sharp_corner.a1);
  w.num("a2", p.sharp_corner.a2);
  w.end();
  w.word("profile", enum_name(profile_names(), p.profile));
  w.num("max_jerk_mm_s3", p.max_jerk_mm_s3);
  w.integer("lookahead_moves", p.lookahead_moves);
  w.num("arc_tolerance_mm", p.arc_tolerance_mm);
  w.end();

  w.begin("extruder");
  w.num("pressure_advance", c.extruder.pressure_advance);
  w.num("pressure_advance_smooth_time", c.extruder.pressure_advance_smooth_time);
  w.num("min_extrude_temp", c.extruder.min_extrude_temp);
  w.num("max_extrude_only_distance", c.extruder.max_extrude_only_distance);
  w.num("nozzle_diameter", c.extruder.nozzle_diameter);
  w.num("filament_diameter", c.extruder.filament_diameter);
  w.num("max_extrude_cross_section", c.extruder.max_extrude_cross_section);
  w.end();

  w.begin("servo");
  w.num("rate_hz", c.servo.rate_hz);
  w.integer("realtime_priority", c.servo.realtime_priority);
  w.integer("cpu", c.servo.cpu);
  w.boolean("lock_memory", c.servo.lock_memory);
  w.end();

  const ControlConfig& k = c.control;
  w.begin("control");
  w.word("mode", enum_name(control_mode_names(), k.mode));
  w.word("loop", enum_name(control_loop_names(), k.loop));
  w.num("device_rate_hz", k.device_rate_hz);
  w.boolean("sub_step_trim", k.sub_step_trim);
  w.num("kp", k.kp);
  w.num("ki_per_s", k.ki_per_s);
  w.num("max_correction_mm_s", k.max_correction_mm_s);
  w.num("skipped_step_threshold_mm", k.skipped_step_threshold_mm);
  w.num("max_following_error_mm", k.max_following_error_mm);
  w.num("max_encoder_jump_mm", k.max_encoder_jump_mm);
  w.num("command_lead_ms", k.command_lead_ms);
  if (!k.axes.empty()) {
    w.begin("axes");
    for (const AxisGainsConfig& a : k.axes) {
      w.begin(a.axis);
      w.num("kp", a.kp);
      w.num("ki_per_s", a.ki_per_s);
      w.end();
    }
    w.end();
  }
  const ManeuverControlConfig& m = k.maneuver;
  w.begin("maneuver");
  w.num("k_p_per_s", m.k_p_per_s);
  w.num("k_d_per_s", m.k_d_per_s);
  w.num("q1", m.q1);
  w.num("q2", m.q2);
  w.num("lambda_per_s", m.lambda_per_s);
  w.num("mu", m.mu);
  w.num("path_speed_mm_s", m.path_speed_mm_s);
  w.word("speed_assignment", enum_name(maneuver_speed_names(), m.speed_assignment));
  w.word("parameterization", enum_name(maneuver_parameterization_names(), m.parameterization));
  w.num("arc_a1_mm", m.arc_a1_mm);
  w.num("arc_a2_mm", m.arc_a2_mm);
  w.num("arc_reach_mm", m.arc_reach_mm);
  w.end();
  w.end();

  const FeedforwardConfig& f = c.feedforward;
  w.begin("feedforward");
  w.word("type", enum_name(feedforward_names(), f.type));
  w.begin("shaper");
  w.word("type", enum_name(shaper_names(), f.shaper.type));
  w.num("freq_hz", f.shaper.freq_hz);
  w.num("damping", f.shaper.damping);
  if (!f.shaper.axes.empty()) {
    w.begin("axes");
    for (const AxisShaperConfig& a : f.shaper.axes) {
      w.begin(a.axis);
      w.word("type", enum_name(shaper_names(), a.type));
      w.num("freq_hz", a.freq_hz);
      w.num("damping", a.damping);
      w.end();
    }
    w.end();
  }
  w.end();
  w.begin("lpv");
  w.num("preview_ms", f.lpv.preview_ms);
  w.boolean("freeze_at_centre", f.lpv.freeze_at_centre);
  w.num("jump_accel_mm_s2", f.lpv.jump_accel_mm_s2);
  w.num("jump_window_ms", f.lpv.jump_window_ms);
  w.end();
  w.end();
}

void write_model(Writer& w, const MachineConfig& c) {
  w.begin("model");
  if (!c.model.gantry.empty()) {
    w.begin("gantry");
    for (const GantryModelConfig& g : c.model.gantry) {
      w.begin(g.axis);
      w.num("m1_kg", g.m1_kg);
      w.num("m2_kg", g.m2_kg);
      w.num("k1_n_per_m", g.k1_n_per_m);
      w.num("k2_n_per_m", g.k2_n_per_m);
      w.num("c1_ns_per_m", g.c1_ns_per_m);
      w.num("c2_ns_per_m", g.c2_ns_per_m);
      w.num("coulomb_friction_n", g.coulomb_friction_n);
      w.num("friction_bristle_mm", g.friction_bristle_mm);
      w.num("backlash_mm", g.backlash_mm);
      w.num("belt_direction_ratio", g.belt_direction_ratio);
      w.num("belt_compliance_slope_per_m", g.belt_compliance_slope_per_m);
      w.num("belt_stiffness_reference_mm", g.belt_stiffness_reference_mm);
      w.num("runout_period_mm", g.runout_period_mm);
      w.num("runout_sin_um", g.runout_sin_um);
      w.num("runout_cos_um", g.runout_cos_um);
      w.num("runout_reference_mm", g.runout_reference_mm);
      w.num("travel_scale", g.travel_scale);
      w.num("extra_resonance_hz", g.extra_resonance_hz);
      w.num("extra_resonance_damping", g.extra_resonance_damping);
      w.num("extra_resonance_mass_kg", g.extra_resonance_mass_kg);
      w.num("encoder_delay_ms", g.encoder_delay_ms);
      w.num("field_lag_ms", g.field_lag_ms);
      const StepperConfig& s = g.stepper;
      w.begin("stepper");
      w.num("holding_torque_nm", s.holding_torque_nm);
      w.num("rated_current_a", s.rated_current_a);
      w.num("drive_current_a", s.drive_current_a);
      w.integer("rotor_teeth", s.rotor_teeth);
      w.num("rotor_inertia_kg_m2", s.rotor_inertia_kg_m2);
      w.num("pulley_radius_mm", s.pulley_radius_mm);
      w.num("belt_unit_stiffness_n", s.belt_unit_stiffness_n);
      w.num("pulley_distance_mm", s.pulley_distance_mm);
      w.num("belt_efficiency", s.belt_efficiency);
      w.end();
      w.end();
    }
    w.end();
  }
  if (c.model.delta_lpv) {
    const DeltaLpvConfig& d = *c.model.delta_lpv;
    w.begin("delta_lpv");
    w.num("m_c_kg", d.m_c_kg);
    w.num("m_f_kg", d.m_f_kg);
    w.num("c_ns_per_m", d.c_ns_per_m);
    w.num("b_ns_per_m", d.b_ns_per_m);
    w.num("k_n_per_m", d.k_n_per_m);
    w.num("d0_per_s2", d.d0_per_s2);
    w.num("d1_per_s", d.d1_per_s);
    w.num("d2_per_s", d.d2_per_s);
    w.num("m1_kg", d.m1_kg);
    w.num("m2_kg", d.m2_kg);
    w.num("b_x_ns_per_m", d.b_x_ns_per_m);
    w.num("b_y_ns_per_m", d.b_y_ns_per_m);
    w.num("b_z_ns_per_m", d.b_z_ns_per_m);
    w.num("k_x_n_per_m", d.k_x_n_per_m);
    w.num("k_y_n_per_m", d.k_y_n_per_m);
    w.num("k_z_n_per_m", d.k_z_n_per_m);
    w.num("delta_x_mm", d.delta_x_mm);
    w.num("delta_y_mm", d.delta_y_mm);
    w.num("delta_z_mm", d.delta_z_mm);
    w.num("d_e_mm", d.d_e_mm);
    w.num("gravity_m_s2", d.gravity_m_s2);
    w.word("force_transform", enum_name(force_transform_names(), d.force_transform));
    w.end();
  }
  if (c.drive == Drive::dc_servo) {
    const CartesianDcConfig& d = c.model.cartesian_dc;
    w.begin("cartesian_dc");
    w.num("m_n_kg", d.m_n_kg);
    w.num("m_x_kg", d.m_x_kg);
    w.num("m_ps_kg", d.m_ps_kg);
    w.num("j_m_kg_m2", d.j_m_kg_m2);
    w.num("b_nm_s", d.b_nm_s);
    w.num("r_a_ohm", d.r_a_ohm);
    w.num("k_m_nm_per_a", d.k_m_nm_per_a);
    w.num("pulley_radius_mm", d.pulley_radius_mm);
    w.end();
  }
  w.end();
}

// One list of MCU entries (mcus with their axes; heater_mcus without).
void write_mcu_list(Writer& w, const char* key, const std::vector<McuConfig>& list,
                    bool with_axes) {
  YAML::Emitter& out = w.raw();
  out << YAML::Key << key << YAML::Value << YAML::BeginSeq;
  for (const McuConfig& m : list) {
    out << YAML::BeginMap;
    w.str("name", m.name);
    if (with_axes) w.list("axes", m.axes);
    w.word("transport", enum_name(transport_names(), m.transport));
    if (m.transport == TransportType::serial) {
      w.begin("serial");
      w.str("device", m.serial.device);
      w.integer("baud", m.serial.baud);
      w.end();
    }
    if (m.transport == TransportType::usb) {
      char buf[16];
      w.begin("usb");
      std::snprintf(buf, sizeof buf, "0x%04x", static_cast<unsigned>(m.usb.vid));
      w.word("vid", buf);
      std::snprintf(buf, sizeof buf, "0x%04x", static_cast<unsigned>(m.usb.pid));
      w.word("pid", buf);
      w.str("serial", m.usb.serial);
      w.end();
    }
    w.integer("clock_hz", m.clock_hz);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
}

void write_hardware(Writer& w, const MachineConfig& c) {
  w.begin("stepgen");
  w.num("max_step_error_us", c.stepgen.max_step_error_us);
  w.integer("mcu_clock_hz", c.stepgen.mcu_clock_hz);
  w.num("queue_ahead_ms", c.stepgen.queue_ahead_ms);
  w.end();
  if (c.drive == Drive::dc_servo) return;  // no MCUs
  write_mcu_list(w, "mcus", c.mcus, true);
}

template <class T, class WriteParams>
void write_effect(Writer& w, const char* key, const std::optional<T>& e, WriteParams params) {
  if (!e) return;
  w.begin(key);
  params(*e);
  if (!e->axes.empty()) w.list("axes", e->axes);
  w.end();
}

void write_runtime(Writer& w, const MachineConfig& c) {
  const SimulatorConfig& s = c.simulator;
  w.begin("simulator");
  w.integer("seed", static_cast<long long>(s.seed));
  w.num("encoder_noise_um", s.encoder_noise_um);
  w.num("sample_delay_us", s.sample_delay_us);
  w.begin("endstops");
  w.num("sigma_um", s.endstops.sigma_um);
  w.num("hysteresis_um", s.endstops.hysteresis_um);
  w.num("start_distance_mm", s.endstops.start_distance_mm);
  w.end();
  w.begin("effects");
  const SimEffectsConfig& fx = s.effects;
  write_effect(w, "coulomb_friction", fx.coulomb_friction,
               [&](const CoulombFrictionConfig& v) { w.num("force_n", v.force_n); });
  write_effect(w, "backlash", fx.backlash,
               [&](const BacklashConfig& v) { w.num("width_um", v.width_um); });
  write_effect(w, "periodic_position", fx.periodic_position, [&](const PeriodicPositionConfig& v) {
    w.num("period_mm", v.period_mm);
    w.num("amplitude_um", v.amplitude_um);
    w.num("phase_deg", v.phase_deg);
  });
  write_effect(w, "direction_dependent_stiffness", fx.direction_dependent_stiffness,
               [&](const DirectionStiffnessConfig& v) { w.num("ratio", v.ratio); });
  write_effect(w, "extra_resonance", fx.extra_resonance, [&](const ExtraResonanceConfig& v) {
    w.num("freq_hz", v.freq_hz);
    w.num("damping", v.damping);
  });
  write_effect(w, "time_delay", fx.time_delay,
               [&](const TimeDelayConfig& v) { w.num("delay_ms", v.delay_ms); });
  write_effect(w, "scale_error", fx.scale_error,
               [&](const ScaleErrorConfig& v) { w.num("scale", v.scale); });
  w.end();
  if (s.external_plant) {
    w.begin("external_plant");
    w.str("command", s.external_plant->command);
    w.list("axes", s.external_plant->axes);
    w.num("period_us", s.external_plant->period_us);
    w.end();
  }
  w.end();

  char mode[8];
  std::snprintf(mode, sizeof mode, "0%o", c.sockets.mode);
  w.begin("sockets");
  w.str("unix_socket", c.sockets.unix_socket);
  w.str("mode", mode);
  w.str("api_socket", c.sockets.api_socket);
  w.str("pty_link", c.sockets.pty_link);
  w.end();

  w.begin("web");
  w.boolean("enabled", c.web.enabled);
  w.str("address", c.web.address);
  w.integer("port", c.web.port);
  w.list("trusted_clients", c.web.trusted_clients);
  w.str("api_key", c.web.api_key);
  w.str("ui_dir", c.web.ui_dir);
  w.str("page_dir", c.web.page_dir);
  w.str("uplot_dir", c.web.uplot_dir);
  w.str("files_dir", c.web.files_dir);
  w.str("database", c.web.database);
  w.str("calibration_dir", c.web.calibration_dir);
  w.end();

  w.begin("recorder");
  w.boolean("enabled", c.recorder.enabled);
  w.str("directory", c.recorder.directory);
  w.num("max_file_size_mb", c.recorder.max_file_size_mb);
  w.integer("keep_files", c.recorder.keep_files);
  w.end();

  w.begin("jobs");
  w.str("directory", c.jobs.directory);
  w.num("max_file_size_mb", c.jobs.max_file_size_mb);
  w.num("pause_retract_mm", c.jobs.pause_retract_mm);
  w.num("retract_speed_mm_s", c.jobs.retract_speed_mm_s);
  w.num("prime_extra_mm", c.jobs.prime_extra_mm);
  w.num("lift_mm", c.jobs.lift_mm);
  w.num("z_speed_mm_s", c.jobs.z_speed_mm_s);
  if (c.jobs.park_x_mm) w.num("park_x_mm", *c.jobs.park_x_mm);
  if (c.jobs.park_y_mm) w.num("park_y_mm", *c.jobs.park_y_mm);
  w.num("travel_speed_mm_s", c.jobs.travel_speed_mm_s);
  w.num("settle_ms", c.jobs.settle_ms);
  w.end();

  w.begin("logging");
  w.word("level", enum_name(log_level_names(), c.logging.level));
  w.str("file", c.logging.file);
  w.end();
}

void write_thermal(Writer& w, const MachineConfig& c) {
  if (!c.heater_mcus.empty()) write_mcu_list(w, "heater_mcus", c.heater_mcus, false);
  if (!c.heaters.empty()) {
    w.begin("heaters");
    for (const HeaterConfig& h : c.heaters) {
      w.begin(h.name);
      w.word("kind", enum_name(heater_kind_names(), h.kind));
      w.str("sensor", h.sensor);
      if (h.thermistor) {
        const ThermistorConfig& t = *h.thermistor;
        w.begin("thermistor");
        w.word("form", enum_name(thermistor_form_names(), t.form));
        w.num("t1_c", t.t1_c);
        w.num("r1_ohm", t.r1_ohm);
        if (t.form == ThermistorConfig::Form::beta) {
          w.num("beta", t.beta);
        } else {
          w.num("t2_c", t.t2_c);
          w.num("r2_ohm", t.r2_ohm);
          w.num("t3_c", t.t3_c);
          w.num("r3_ohm", t.r3_ohm);
        }
        w.end();
      }
      w.num("pullup_ohm", h.pullup_ohm);
      w.num("min_temp_c", h.min_temp_c);
      w.num("max_temp_c", h.max_temp_c);
      w.num("max_power", h.max_power);
      w.num("residency_s", h.residency_s);
      w.begin("pid");
      w.num("kp", h.pid_kp);
      w.num("ki", h.pid_ki);
      w.num("kd", h.pid_kd);
      w.end();
      const HeaterProtectionConfig& p = h.protection;
      w.begin("protection");
      w.num("watch_period_s", p.watch_period_s);
      w.num("watch_increase_c", p.watch_increase_c);
      w.num("runaway_period_s", p.runaway_period_s);
      w.num("runaway_hysteresis_c", p.runaway_hysteresis_c);
      w.num("verify_max_error", p.verify_max_error);
      w.num("verify_gain_time_s", p.verify_gain_time_s);
      w.num("verify_hysteresis_c", p.verify_hysteresis_c);
      w.num("verify_heating_gain_c", p.verify_heating_gain_c);
      w.num("stuck_period_s", p.stuck_period_s);
      w.end();
      w.begin("plant");
      w.num("power_w", h.plant.power_w);
      w.num("heat_capacity_j_k", h.plant.heat_capacity_j_k);
      w.num("loss_w_k", h.plant.loss_w_k);
      w.num("fan_loss_w_k", h.plant.fan_loss_w_k);
      w.num("delay_s", h.plant.delay_s);
      w.num("sensor_tau_s", h.plant.sensor_tau_s);
      w.num("ambient_c", h.plant.ambient_c);
      w.end();
      if (!h.mcu.empty()) w.str("mcu", h.mcu);
      w.end();
    }
    w.end();
  }
  if (!c.fans.empty()) {
    w.begin("fans");
    for (const FanConfig& f : c.fans) {
      w.begin(f.name);
      w.word("kind", enum_name(fan_kind_names(), f.kind));
      if (f.kind == FanKind::heater) {
        w.str("heater", f.heater);
        w.num("heater_temp_c", f.heater_temp_c);
      }
      w.num("kick_start_s", f.kick_start_s);
      w.num("off_below", f.off_below);
      w.num("max_power", f.max_power);
      if (!f.mcu.empty()) w.str("mcu", f.mcu);
      w.end();
    }
    w.end();
  }
}

}  // namespace

std::string to_yaml(const MachineConfig& c) {
  Writer w;
  w.integer("config_version", 1);
  w.str("name", c.name);
  w.word("kinematics", enum_name(kinematics_names(), c.kinematics));
  w.word("drive", enum_name(drive_names(), c.drive));
  write_axes(w, c);
  write_motion(w, c);
  write_model(w, c);
  write_hardware(w, c);
  write_runtime(w, c);
  write_thermal(w, c);
  return w.finish();
}

}  // namespace feedloop::config
