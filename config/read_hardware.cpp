// Config sections `stepgen` and `mcus` (one entry per microcontroller and its transport).
#include <map>

#include "config/enum_names.hpp"
#include "config/sections.hpp"

namespace feedloop::config::detail {
namespace {

struct Driven {
  std::string mcu;
  int line;
};

}  // namespace

void read_transport(MapReader& m, McuConfig& mcu, Diagnostics& diag) {
  m.choice("transport", mcu.transport, transport_names(), Need::required);
  const bool serial = mcu.transport == TransportType::serial;
  const bool usb = mcu.transport == TransportType::usb;
  if (m.has("serial") && !serial)
    diag.add(m.key_mark("serial"), m.path() + ": section 'serial' is only used with transport: serial");
  if (m.has("usb") && !usb)
    diag.add(m.key_mark("usb"), m.path() + ": section 'usb' is only used with transport: usb");
  MapReader s = m.sub("serial", serial ? Need::required : Need::optional);
  if (serial) {
    s.string("device", mcu.serial.device, Need::required);
    s.integer_as("baud", mcu.serial.baud, 1200, 20000000);
    if (s.present() && s.has("device") && mcu.serial.device.empty())
      diag.add(s.key_mark("device"), s.path() + ".device must not be empty");
  }
  s.finish();
  MapReader u = m.sub("usb", usb ? Need::required : Need::optional);
  if (usb) {
    u.integer_as("vid", mcu.usb.vid, 0, 0xFFFF, Need::required);
    u.integer_as("pid", mcu.usb.pid, 0, 0xFFFF, Need::required);
    u.string("serial", mcu.usb.serial);
  }
  u.finish();
}

void read_axis_refs(MapReader& m, const char* key, const MachineConfig& cfg,
                    std::vector<std::string>& out, Diagnostics& diag) {
  std::vector<std::string> names;
  if (!m.string_list(key, names)) return;
  std::vector<std::string> known;
  for (const AxisConfig& a : cfg.axes) known.push_back(a.name);
  const YAML::Node list = m.get(key);
  std::vector<std::string> valid;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const YAML::Mark where = list.IsSequence() ? list[i].Mark() : list.Mark();
    bool exists = false;
    for (const std::string& k : known) exists = exists || k == names[i];
    if (!exists) {
      std::string msg = m.key_path(key) + ": '" + names[i] + "' is not an axis in axes";
      if (const std::string s = closest_match(names[i], known); !s.empty())
        msg += " (did you mean '" + s + "'?)";
      diag.add(where, msg);
      continue;
    }
    bool repeated = false;
    for (std::size_t j = 0; j < i; ++j) repeated = repeated || names[j] == names[i];
    if (repeated) {
      diag.add(where, m.key_path(key) + ": axis '" + names[i] + "' is listed twice");
      continue;
    }
    valid.push_back(names[i]);
  }
  // Only the valid names: a config with errors is never returned, but later checks (every axis
  // driven by an mcu) then do not repeat the same problem.
  out = valid;
}

void read_stepgen_mcus(MapReader& root, MachineConfig& cfg, Marks& marks, Diagnostics& diag) {
  MapReader sg = root.sub("stepgen");
  sg.number("max_step_error_us", cfg.stepgen.max_step_error_us, Range::open_closed(0.0, 1000.0));
  sg.integer("mcu_clock_hz", cfg.stepgen.mcu_clock_hz, 1000000, 2000000000);
  sg.number("queue_ahead_ms", cfg.stepgen.queue_ahead_ms, Range::closed(1.0, 10000.0));
  sg.finish();

  marks.mcus = root.key_mark("mcus");
  if (cfg.drive == Drive::dc_servo) {  // the DC-motor plant is simulated in-process: no MCUs
    if (root.has("mcus"))
      diag.add(marks.mcus, "drive: dc_servo runs the simulated DC-motor printer in the servo thread; it has "
                           "no mcus (remove the mcus list)");
    root.get("mcus");
    return;
  }
  if (!root.has("mcus")) {
    root.get("mcus");
    diag.add(root.mark(), "missing required key 'mcus' (a list of microcontrollers)");
    return;
  }
  const YAML::Node list = root.get("mcus");
  if (!list.IsSequence() || list.size() == 0) {
    diag.add(list.IsNull() ? marks.mcus : list.Mark(),
             "mcus must be a non-empty list of microcontrollers, got " + node_kind(list));
    return;
  }
  std::map<std::string, int> name_line;
  std::map<std::string, Driven> driven;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node item = list[i];
    MapReader m(item, "mcus[" + std::to_string(i) + "]", diag, item.Mark());
    if (!m.present()) continue;
    McuConfig mcu;
    mcu.clock_hz = cfg.stepgen.mcu_clock_hz;
    if (m.string("name", mcu.name, Need::required)) {
      if (mcu.name.empty()) {
        diag.add(m.key_mark("name"), m.path() + ".name must not be empty");
      } else if (const auto it = name_line.find(mcu.name); it != name_line.end()) {
        diag.add(m.key_mark("name"), "duplicate mcu name '" + mcu.name + "' (first at line " +
                                         std::to_string(it->second) + ")");
      } else {
        name_line[mcu.name] = m.key_mark("name").line + 1;
      }
    }
    if (!m.has("axes")) m.string_list("axes", mcu.axes, Need::required);
    read_axis_refs(m, "axes", cfg, mcu.axes, diag);
    if (m.has("axes") && mcu.axes.empty() && m.get("axes").IsSequence() && m.get("axes").size() == 0)
      diag.add(m.key_mark("axes"), m.path() + ".axes must name at least one axis");
    const YAML::Node axes_node = m.get("axes");
    for (std::size_t j = 0; j < mcu.axes.size(); ++j) {
      const std::string& a = mcu.axes[j];
      YAML::Mark where = axes_node.Mark();
      if (axes_node.IsSequence())
        for (const YAML::Node& ref : axes_node)
          if (ref.IsScalar() && ref.Scalar() == a) {
            where = ref.Mark();
            break;
          }
      if (const auto it = driven.find(a); it != driven.end()) {
        diag.add(where, "axis '" + a + "' is already driven by mcu '" + it->second.mcu +
                            "' (line " + std::to_string(it->second.line) +
                            "); every axis needs exactly one mcu");
      } else {
        driven[a] = Driven{mcu.name, where.line + 1};
      }
    }
    read_transport(m, mcu, diag);
    m.integer("clock_hz", mcu.clock_hz, 1000000, 2000000000);
    m.finish();
    cfg.mcus.push_back(mcu);
  }
}

}  // namespace feedloop::config::detail
