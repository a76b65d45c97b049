// Waypoints of the extruding path of selected layers of a G-code program (gcode_path.hpp).
#include "maneuver/gcode_path.hpp"

#include <fstream>
#include <sstream>

#include "gcode/parser.hpp"

namespace feedloop::maneuver {

Result<std::vector<Vec3>> extrusion_path_from_gcode(std::string_view text, const std::string& source,
                                                   const GcodePathOptions& opt) {
  if (opt.layers == 0 || opt.layer_stride == 0)
    return Error{"G-code path: layers and layer_stride must be positive", {source}};
  bool abs_xyz = true, abs_e = true;
  Vec3 pos = Vec3::Zero();
  double e = 0.0;
  std::string feature;
  std::vector<Vec3> out;
  long layer = -1;              // index of the layer of the last extruding move
  double layer_z = -1e300;
  bool loop_open = false;       // collecting the current layer's loop
  bool loop_done = false;       // this layer's loop has ended
  size_t taken = 0;
  gcode::Command cmd;
  SourceLocation where{source, 0, 0};
  size_t begin = 0;
  while (begin <= text.size() && taken < opt.layers) {
    size_t end = text.find('\n', begin);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(begin, end - begin);
    begin = end + 1;
    ++where.line;
    if (line.rfind(";TYPE:", 0) == 0) {
      feature = std::string(line.substr(6));
      while (!feature.empty() && (feature.back() == '\r' || feature.back() == ' ')) feature.pop_back();
      continue;
    }
    const Status st = gcode::parse_line(line, where, cmd);
    if (!st.ok()) return st.error();
    if (cmd.empty() || (cmd.letter != 'G' && cmd.letter != 'M')) continue;
    if (cmd.is('G', 90)) { abs_xyz = true; abs_e = true; continue; }
    if (cmd.is('G', 91)) { abs_xyz = false; abs_e = false; continue; }
    if (cmd.is('M', 82)) { abs_e = true; continue; }
    if (cmd.is('M', 83)) { abs_e = false; continue; }
    if (cmd.is('G', 92)) {
      for (int i = 0; i < 3; ++i)
        if (cmd.has_value("XYZ"[i])) pos[i] = cmd.get("XYZ"[i]);
      if (cmd.has_value('E')) e = cmd.get('E');
      continue;
    }
    const bool move = cmd.is('G', 0) || cmd.is('G', 1) || cmd.is('G', 2) || cmd.is('G', 3);
    if (!move) continue;
    const Vec3 from = pos;
    for (int i = 0; i < 3; ++i)
      if (cmd.has_value("XYZ"[i])) pos[i] = abs_xyz ? cmd.get("XYZ"[i]) : pos[i] + cmd.get("XYZ"[i]);
    double de = 0.0;
    if (cmd.has_value('E')) {
      const double ne = abs_e ? cmd.get('E') : e + cmd.get('E');
      de = ne - e;
      e = ne;
    }
    const bool xy_move = pos.x() != from.x() || pos.y() != from.y();
    const bool extruding = de > 0.0 && xy_move;
    if (extruding && pos.z() > layer_z + 1e-9) {  // a new layer
      if (loop_open) ++taken;
      loop_open = false;
      loop_done = false;
      layer_z = pos.z();
      ++layer;
    }
    if (taken >= opt.layers) break;
    const bool wanted_layer = layer >= static_cast<long>(opt.first_layer) &&
                              (static_cast<size_t>(layer) - opt.first_layer) % opt.layer_stride == 0;
    const bool wanted = extruding && wanted_layer && (opt.feature.empty() || feature == opt.feature);
    if (wanted && !loop_done) {
      if (!loop_open) out.push_back(from);
      out.push_back(pos);
      loop_open = true;
    } else if (loop_open && !loop_done) {
      loop_done = true;  // the first loop of this layer ended (travel or another feature)
    }
  }
  if (loop_open && taken < opt.layers) ++taken;
  if (taken < opt.layers)
    return Error{"G-code path: found " + std::to_string(taken) + " of the " + std::to_string(opt.layers) +
                     " layers asked for" + (opt.feature.empty() ? "" : " with feature '" + opt.feature + "'"),
                 {source}};
  return out;
}

Result<std::vector<Vec3>> extrusion_path_from_gcode_file(const std::string& file, const GcodePathOptions& opt) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return Error{"cannot open G-code file", {file}};
  std::ostringstream ss;
  ss << in.rdbuf();
  return extrusion_path_from_gcode(ss.str(), file, opt);
}

}  // namespace feedloop::maneuver
