// The like-for-like part of bench_maneuver (issue 19): Table III on one layer of a path of the
// paper's length, the nominal model beside a plant that is not the controller's model, the
// magnitude gap one cause at a time, and the arc-length variant tuned on generated parts and
// scored on the corpus's slicer files. See README.md, "Like for like".
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>

namespace feedloop::bench_maneuver {

struct StudyOptions {
  std::string gcode_dir = "../shared/gcode";  // held-out slicer files; missing: that table says so
  int draws = 5;                              // off-nominal machines per figure
  double servo_period_s = 5.0e-5;             // the servo on the off-nominal plant (20 kHz)
  // Gains on the off-nominal plant: Table II's K_d 1667/s, K_p 500/s make the belt's light pulley
  // side chatter against the drive limits (table B shows it); these are the largest of the ladder
  // K_d = 100, 200, 400, 800, 1667 (K_p = 0.3 K_d, Table II's ratio) that do not, on draw 1.
  double k_d_offnominal = 200.0;
  double k_p_offnominal = 60.0;
  bool quick = false;  // fewer draws, fewer held-out layers (tests, CI)
};

// Prints the three tables; sets their JSON as out["like_for_like"] (out: an object or null).
// Returns 0, or 1 on an error it printed.
int run_like_for_like(const StudyOptions& options, nlohmann::json& out);

}  // namespace feedloop::bench_maneuver
