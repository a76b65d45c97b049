// `feedloop model frf` (see model_command.hpp).
#include "cli/model_command.hpp"

#include <cstdio>
#include <cstdlib>

#include "config/config.hpp"
#include "engine/control_config.hpp"
#include "model/delta_lpv.hpp"
#include "model/frf_csv.hpp"

namespace feedloop::cli {
namespace {

void usage(std::FILE* out) {
  std::fputs("usage: feedloop model frf [--config FILE] --pos X,Y,Z --out FILE.csv [--virtual-work]\n", out);
}

bool parse_pos(const std::string& s, Eigen::Vector3d* pos) {
  double v[3];
  size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const size_t comma = s.find(',', start);
    if ((i < 2) != (comma != std::string::npos)) return false;
    const std::string item = s.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    char* end = nullptr;
    v[i] = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size()) return false;
    start = comma + 1;
  }
  *pos = Eigen::Vector3d(v[0], v[1], v[2]);
  return true;
}

int frf(const std::vector<std::string>& args) {
  std::string config_path, out;
  Eigen::Vector3d pos(0.0, 0.0, 30.0);
  bool have_pos = false, virtual_work = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    const bool has_value = i + 1 < args.size();
    if (a == "--config" && has_value) {
      config_path = args[++i];
    } else if (a == "--out" && has_value) {
      out = args[++i];
    } else if (a == "--pos" && has_value) {
      if (!parse_pos(args[++i], &pos)) {
        std::fprintf(stderr, "feedloop model frf: --pos wants X,Y,Z in mm, got '%s'\n", args[i].c_str());
        return 2;
      }
      have_pos = true;
    } else if (a == "--virtual-work") {
      virtual_work = true;
    } else if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "feedloop model frf: bad argument '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  if (out.empty() || !have_pos) {
    usage(stderr);
    return 2;
  }
  config::DeltaLpvConfig lpv;
  config::DeltaGeometryConfig geo;
  if (!config_path.empty()) {
    auto cfg = config::load_config_file(config_path);
    if (!cfg) {
      std::fprintf(stderr, "feedloop model frf: %s\n", cfg.error().to_string().c_str());
      return 1;
    }
    if (cfg.value().model.delta_lpv) lpv = *cfg.value().model.delta_lpv;
    if (cfg.value().delta) geo = *cfg.value().delta;
  }
  const model::ForceTransform form =
      virtual_work || lpv.force_transform == config::ForceTransform::virtual_work ? model::ForceTransform::VirtualWork
                                                                                  : model::ForceTransform::Paper;
  auto m = model::DeltaLpvModel::create(engine::delta_params_from_config(lpv, geo), form);
  if (!m) {
    std::fprintf(stderr, "feedloop model frf: %s\n", m.error().to_string().c_str());
    return 1;
  }
  if (auto s = model::write_frf_csv(out, m.value(), pos); !s) {
    std::fprintf(stderr, "feedloop model frf: %s\n", s.error().to_string().c_str());
    return 1;
  }
  std::printf("wrote %s (%s form, position %.3f,%.3f,%.3f mm)\n", out.c_str(), model::to_string(form), pos.x(),
              pos.y(), pos.z());
  return 0;
}

}  // namespace

int model_command(const std::vector<std::string>& args) {
  if (!args.empty() && args[0] == "frf") return frf(std::vector<std::string>(args.begin() + 1, args.end()));
  if (!args.empty() && (args[0] == "--help" || args[0] == "-h")) {
    usage(stdout);
    return 0;
  }
  usage(stderr);
  return 2;
}

}  // namespace feedloop::cli
