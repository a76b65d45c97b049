// The YAML spelling of every enumerated config value, shared by the loader and the emitter so the
// two can never disagree.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "config/machine_config.hpp"

namespace feedloop::config {

template <class E>
using EnumNames = std::vector<std::pair<std::string, E>>;

inline const EnumNames<HeaterKind>& heater_kind_names() {
  static const EnumNames<HeaterKind> n = {
      {"extruder", HeaterKind::extruder}, {"bed", HeaterKind::bed}, {"chamber", HeaterKind::chamber}};
  return n;
}
inline const EnumNames<FanKind>& fan_kind_names() {
  static const EnumNames<FanKind> n = {{"part", FanKind::part}, {"heater", FanKind::heater}};
  return n;
}
inline const EnumNames<ThermistorConfig::Form>& thermistor_form_names() {
  static const EnumNames<ThermistorConfig::Form> n = {{"beta", ThermistorConfig::Form::beta},
                                                      {"steinhart_hart", ThermistorConfig::Form::steinhart_hart}};
  return n;
}
inline const EnumNames<Kinematics>& kinematics_names() {
  static const EnumNames<Kinematics> n = {{"cartesian", Kinematics::cartesian},
                                          {"corexy", Kinematics::corexy},
                                          {"delta", Kinematics::delta}};
  return n;
}
inline const EnumNames<EndstopSide>& endstop_side_names() {
  static const EnumNames<EndstopSide> n = {{"min", EndstopSide::min}, {"max", EndstopSide::max}};
  return n;
}
inline const EnumNames<Drive>& drive_names() {
  static const EnumNames<Drive> n = {{"stepper", Drive::stepper}, {"dc_servo", Drive::dc_servo}};
  return n;
}
inline const EnumNames<ManeuverSpeed>& maneuver_speed_names() {
  static const EnumNames<ManeuverSpeed> n = {{"constant", ManeuverSpeed::constant},
                                             {"every_transition", ManeuverSpeed::every_transition},
                                             {"sharp_corner", ManeuverSpeed::sharp_corner},
                                             {"sharp_corner_arc", ManeuverSpeed::sharp_corner_arc}};
  return n;
}
inline const EnumNames<ManeuverParameterization>& maneuver_parameterization_names() {
  static const EnumNames<ManeuverParameterization> n = {{"unit", ManeuverParameterization::unit},
                                                        {"arc_length", ManeuverParameterization::arc_length}};
  return n;
}
inline const EnumNames<Cornering>& cornering_names() {
  static const EnumNames<Cornering> n = {{"junction_deviation", Cornering::junction_deviation},
                                         {"sharp_corner", Cornering::sharp_corner},
                                         {"speed_change", Cornering::speed_change}};
  return n;
}
inline const EnumNames<Profile>& profile_names() {
  static const EnumNames<Profile> n = {{"trapezoid", Profile::trapezoid},
                                       {"scurve", Profile::scurve}};
  return n;
}
inline const EnumNames<ControlLoop>& control_loop_names() {
  static const EnumNames<ControlLoop> n = {{"device", ControlLoop::device}, {"host", ControlLoop::host}};
  return n;
}

inline const EnumNames<ControlMode>& control_mode_names() {
  static const EnumNames<ControlMode> n = {{"open_loop", ControlMode::open_loop},
                                           {"pi", ControlMode::pi},
                                           {"maneuver", ControlMode::maneuver}};
  return n;
}
inline const EnumNames<FeedforwardType>& feedforward_names() {
  static const EnumNames<FeedforwardType> n = {{"none", FeedforwardType::none},
                                               {"shaper", FeedforwardType::shaper},
                                               {"lpv", FeedforwardType::lpv}};
  return n;
}
inline const EnumNames<ShaperType>& shaper_names() {
  static const EnumNames<ShaperType> n = {
      {"zv", ShaperType::zv}, {"mzv", ShaperType::mzv}, {"ei", ShaperType::ei}};
  return n;
}
inline const EnumNames<ForceTransform>& force_transform_names() {
  static const EnumNames<ForceTransform> n = {{"paper", ForceTransform::paper},
                                              {"virtual_work", ForceTransform::virtual_work}};
  return n;
}
inline const EnumNames<TransportType>& transport_names() {
  static const EnumNames<TransportType> n = {{"mock", TransportType::mock},
                                             {"serial", TransportType::serial},
                                             {"usb", TransportType::usb}};
  return n;
}
inline const EnumNames<LogLevel>& log_level_names() {
  static const EnumNames<LogLevel> n = {
      {"trace", LogLevel::trace}, {"debug", LogLevel::debug},       {"info", LogLevel::info},
      {"warn", LogLevel::warn},   {"error", LogLevel::error},       {"critical", LogLevel::critical},
      {"off", LogLevel::off}};
  return n;
}

template <class E>
std::string enum_name(const EnumNames<E>& names, E value) {
  for (const auto& [name, v] : names)
    if (v == value) return name;
  return "?";
}

}  // namespace feedloop::config
