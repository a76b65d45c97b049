// Config sections `simulator` (plant simulator and its optional unmodelled effects), `sockets`,
// `recorder` and `logging`.
#include <boost/asio/ip/address.hpp>
#include <boost/asio/ip/network_v4.hpp>
#include <boost/asio/ip/network_v6.hpp>

#include "config/enum_names.hpp"
#include "config/config.hpp"
#include "config/sections.hpp"

namespace feedloop::config::detail {
namespace {

// "a.b.c.d/n", "x::y/n" or a single address (web.trusted_clients).
bool valid_cidr(const std::string& text) {
  boost::system::error_code ec;
  if (text.find('/') == std::string::npos) {
    boost::asio::ip::make_address(text, ec);
    return !ec;
  }
  if (text.find(':') != std::string::npos) {
    boost::asio::ip::make_network_v6(text, ec);
    return !ec;
  }
  boost::asio::ip::make_network_v4(text, ec);
  return !ec;
}

// An effect section: absent = off; present = on unless `enabled: false`. Its parameters are
// checked either way, so a disabled effect with a typo still reports it.
template <class T, class ReadParams>
void read_effect(MapReader& effects, const char* key, const MachineConfig& cfg,
                 std::optional<T>& out, Diagnostics& diag, ReadParams read_params) {
  if (!effects.has(key)) {
    effects.sub(key);  // known key
    return;
  }
  MapReader e = effects.sub(key);
  T value;
  bool enabled = true;
  e.boolean("enabled", enabled);
  read_params(e, value);
  read_axis_refs(e, "axes", cfg, value.axes, diag);
  e.finish();
  if (enabled) out = value;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  while (!s.empty() && s.back() == ' ') s.remove_suffix(1);
  return s;
}

// Unix permission bits written the usual way: 0660 (octal; "0o660" is accepted too).
void read_mode(MapReader& s, unsigned& out, Diagnostics& diag) {
  std::string text;
  if (!s.string("mode", text)) return;
  std::string_view t = trim(text);
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'o' || t[1] == 'O')) t.remove_prefix(2);
  unsigned v = 0;
  bool ok = !t.empty() && t.size() <= 4;
  for (const char c : t) {
    if (c < '0' || c > '7') ok = false;
    v = v * 8 + static_cast<unsigned>(c - '0');
  }
  if (!ok || v > 0777) {
    diag.add(s.get("mode").Mark(), s.key_path("mode") +
                                       " must be octal permission bits such as 0660, got '" +
                                       text + "'");
    return;
  }
  out = v;
}

void read_path(MapReader& m, const char* key, std::string& out, Diagnostics& diag) {
  std::string p;
  if (!m.string(key, p)) return;
  if (p.empty()) {
    diag.add(m.key_mark(key), m.key_path(key) + " must not be empty");
    return;
  }
  const Result<std::string> expanded = expand_path(p, PathVars{"/r", "/s"});
  if (!expanded) {
    diag.add(m.get(key).Mark(), m.key_path(key) + ": " + expanded.error().message);
    return;
  }
  out = p;
}

}  // namespace

void read_simulator(MapReader& root, MachineConfig& cfg, Diagnostics& diag) {
  MapReader s = root.sub("simulator");
  SimulatorConfig& sim = cfg.simulator;
  s.integer_as("seed", sim.seed, 0, 9007199254740991);
  s.number("encoder_noise_um", sim.encoder_noise_um, Range::non_negative());
  s.number("sample_delay_us", sim.sample_delay_us, Range::closed(0.0, 1e6));
  {  // the simulated endstop switches (sim/endstop.hpp), on every axis with a homing section
    MapReader es = s.sub("endstops");
    es.number("sigma_um", sim.endstops.sigma_um, Range::closed(0.0, 1000.0));
    es.number("hysteresis_um", sim.endstops.hysteresis_um, Range::closed(0.0, 10000.0));
    es.number("start_distance_mm", sim.endstops.start_distance_mm, Range::closed(0.0, 10000.0));
    es.finish();
  }
  MapReader e = s.sub("effects");
  SimEffectsConfig& fx = sim.effects;
  read_effect(e, "coulomb_friction", cfg, fx.coulomb_friction, diag,
              [](MapReader& m, CoulombFrictionConfig& v) {
                m.number("force_n", v.force_n, Range::non_negative(), Need::required);
              });
  read_effect(e, "backlash", cfg, fx.backlash, diag, [](MapReader& m, BacklashConfig& v) {
    m.number("width_um", v.width_um, Range::non_negative(), Need::required);
  });
  read_effect(e, "periodic_position", cfg, fx.periodic_position, diag,
              [](MapReader& m, PeriodicPositionConfig& v) {
                m.number("period_mm", v.period_mm, Range::positive(), Need::required);
                m.number("amplitude_um", v.amplitude_um, Range::non_negative(), Need::required);
                m.number("phase_deg", v.phase_deg, Range::closed(-360.0, 360.0));
              });
  read_effect(e, "direction_dependent_stiffness", cfg, fx.direction_dependent_stiffness, diag,
              [](MapReader& m, DirectionStiffnessConfig& v) {
                m.number("ratio", v.ratio, Range::positive(), Need::required);
              });
  read_effect(e, "extra_resonance", cfg, fx.extra_resonance, diag,
              [](MapReader& m, ExtraResonanceConfig& v) {
                m.number("freq_hz", v.freq_hz, Range::positive(), Need::required);
                m.number("damping", v.damping, Range::open(0.0, 1.0), Need::required);
              });
  read_effect(e, "time_delay", cfg, fx.time_delay, diag, [](MapReader& m, TimeDelayConfig& v) {
    m.number("delay_ms", v.delay_ms, Range::non_negative(), Need::required);
  });
  read_effect(e, "scale_error", cfg, fx.scale_error, diag, [](MapReader& m, ScaleErrorConfig& v) {
    m.number("scale", v.scale, Range::open(0.5, 2.0), Need::required);
  });
  e.finish();
  if (s.has("external_plant")) {
    MapReader x = s.sub("external_plant");
    ExternalPlantConfig plant;
    if (x.string("command", plant.command, Need::required) && plant.command.empty())
      diag.add(x.key_mark("command"), x.key_path("command") + " must not be empty");
    if (!x.has("axes")) diag.add(x.mark(), x.path() + ".axes is required (the axes the plant drives)");
    read_axis_refs(x, "axes", cfg, plant.axes, diag);
    if (x.has("axes") && plant.axes.empty() && x.get("axes").IsSequence() && x.get("axes").size() == 0)
      diag.add(x.key_mark("axes"), x.key_path("axes") + " must name at least one axis");
    x.number("period_us", plant.period_us, Range::closed(10.0, 100000.0));
    for (const std::string& a : plant.axes)
      for (const McuConfig& m : cfg.mcus)
        for (const std::string& ma : m.axes)
          if (ma == a && m.transport != TransportType::mock)
            diag.add(x.key_mark("axes"), x.key_path("axes") + ": axis '" + a + "' is driven by MCU '" + m.name +
                                             "', which is not simulated (transport: mock): an external plant "
                                             "drives simulated axes only");
    x.finish();
    sim.external_plant = plant;
  } else {
    s.sub("external_plant");  // known key
  }
  s.finish();
}

void read_io(MapReader& root, MachineConfig& cfg, Diagnostics& diag) {
  MapReader so = root.sub("sockets");
  read_path(so, "unix_socket", cfg.sockets.unix_socket, diag);
  read_mode(so, cfg.sockets.mode, diag);
  read_path(so, "api_socket", cfg.sockets.api_socket, diag);
  read_path(so, "pty_link", cfg.sockets.pty_link, diag);
  so.finish();

  MapReader w = root.sub("web");
  w.boolean("enabled", cfg.web.enabled);
  if (w.string("address", cfg.web.address)) {
    boost::system::error_code ec;
    boost::asio::ip::make_address(cfg.web.address, ec);
    if (ec) diag.add(w.get("address").Mark(), w.key_path("address") + ": '" + cfg.web.address + "' is not an IP address");
  }
  w.integer_as("port", cfg.web.port, 1, 65535);
  if (w.string_list("trusted_clients", cfg.web.trusted_clients)) {
    for (const std::string& c : cfg.web.trusted_clients)
      if (!valid_cidr(c))
        diag.add(w.get("trusted_clients").Mark(),
                 w.key_path("trusted_clients") + ": '" + c + "' is not an address range (e.g. 192.168.1.0/24)");
  }
  w.string("api_key", cfg.web.api_key);
  for (auto [key, out] : {std::pair{"ui_dir", &cfg.web.ui_dir}, std::pair{"page_dir", &cfg.web.page_dir},
                          std::pair{"uplot_dir", &cfg.web.uplot_dir}})
    if (w.string(key, *out) && !out->empty()) read_path(w, key, *out, diag);  // "": none
  read_path(w, "files_dir", cfg.web.files_dir, diag);
  read_path(w, "database", cfg.web.database, diag);
  read_path(w, "calibration_dir", cfg.web.calibration_dir, diag);
  w.finish();

  MapReader r = root.sub("recorder");
  r.boolean("enabled", cfg.recorder.enabled);
  read_path(r, "directory", cfg.recorder.directory, diag);
  r.number("max_file_size_mb", cfg.recorder.max_file_size_mb, Range::closed(1.0, 1e6));
  r.integer_as("keep_files", cfg.recorder.keep_files, 1, 100000);
  r.finish();

  MapReader j = root.sub("jobs");
  read_path(j, "directory", cfg.jobs.directory, diag);
  j.number("max_file_size_mb", cfg.jobs.max_file_size_mb, Range::closed(0.001, 1e6));
  j.number("pause_retract_mm", cfg.jobs.pause_retract_mm, Range::closed(0.0, 50.0));
  j.number("retract_speed_mm_s", cfg.jobs.retract_speed_mm_s, Range::positive());
  j.number("prime_extra_mm", cfg.jobs.prime_extra_mm, Range::closed(0.0, 50.0));
  j.number("lift_mm", cfg.jobs.lift_mm, Range::closed(0.0, 1000.0));
  j.number("z_speed_mm_s", cfg.jobs.z_speed_mm_s, Range::positive());
  if (j.has("park_x_mm")) {
    double v = 0.0;
    if (j.number("park_x_mm", v, Range::any())) cfg.jobs.park_x_mm = v;
  }
  if (j.has("park_y_mm")) {
    double v = 0.0;
    if (j.number("park_y_mm", v, Range::any())) cfg.jobs.park_y_mm = v;
  }
  j.number("travel_speed_mm_s", cfg.jobs.travel_speed_mm_s, Range::positive());
  j.number("settle_ms", cfg.jobs.settle_ms, Range::closed(0.0, 10000.0));
  j.finish();

  MapReader l = root.sub("logging");
  l.choice("level", cfg.logging.level, log_level_names());
  l.string("file", cfg.logging.file);
  if (!cfg.logging.file.empty()) read_path(l, "file", cfg.logging.file, diag);
  l.finish();
}

}  // namespace feedloop::config::detail
