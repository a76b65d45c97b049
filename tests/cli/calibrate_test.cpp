// `feedloop calibrate` against a running feedloopd in virtual time (issue 15): the calibration
// program runs as print jobs, each axis is identified from its recording, the overlay is
// installed and loaded, and the check pattern's e_t is measured before and after; on the
// project's simulator and on the second simulator (plant2/) as an external plant, with the LPV
// feedforward + PI the machines print with.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "config/calibration.hpp"
#include "config/config.hpp"
#include "tests/daemon/daemon_fixture.hpp"
#include "tests/daemon/line_client.hpp"
#include "tests/daemon/subprocess.hpp"

namespace feedloop::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// The embedded simulated printer with the LPV feedforward (the model the calibration changes is
// the one it inverts); `plant2_seed` >= 0: its X and Y on the second simulator, without switches.
std::string printer_yaml(int plant2_seed, const std::string& plant2_effect = "") {
  std::string y(config::default_config_yaml());
  y = std::regex_replace(y, std::regex("feedforward:\n  type: none"), "feedforward:\n  type: lpv");
  if (plant2_seed >= 0) {
    y = std::regex_replace(y, std::regex("simulator:\n  seed: 1"),
                           std::string("simulator:\n  seed: 1\n  external_plant: {command: \"") +
                               FEEDLOOP_PLANT2_PATH + " --seed " + std::to_string(plant2_seed) +
                               (plant2_effect.empty() ? "" : " --effect " + plant2_effect) +
                               "\", axes: [x, y], period_us: 100}");
    // An external plant's carriages have no simulated switches: G28 is a move (docs/homing.md).
    y = std::regex_replace(y, std::regex("\n    homing: \\{direction: min[^\n]*"), "");
  }
  return y;
}

class Calibrate : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("calibrate");
    ASSERT_FALSE(dir_.empty());
  }
  void TearDown() override {
    if (daemon_) {
      daemon_->signal(SIGTERM);
      EXPECT_EQ(daemon_->wait(20), 0);
    }
    daemon_.reset();
    fs::remove_all(dir_);
  }
  std::vector<std::string> env() { return {"RUNTIME_DIRECTORY=" + dir_, "STATE_DIRECTORY=" + dir_}; }
  void start_daemon(const std::string& yaml) {
    std::ofstream(dir_ + "/printer.yaml") << yaml;
    daemon_ = std::make_unique<Subprocess>(
        std::vector<std::string>{FEEDLOOPD_PATH, "--virtual-time", "--config", dir_ + "/printer.yaml"}, env(),
        dir_ + "/daemon.log");
    ASSERT_TRUE(daemon_->wait_for_output("ready", 20)) << daemon_->output();
  }
  int calibrate(std::vector<std::string> extra, std::string* out, double timeout_s = 600) {
    std::vector<std::string> argv{FEEDLOOP_PATH, "calibrate"};
    for (auto& a : extra) argv.push_back(a);
    Subprocess p(argv, env(), dir_ + "/calibrate.log");
    const int rc = p.wait(timeout_s);
    *out = p.output();
    return rc;
  }
  json api(const std::string& method) {
    LineClient c;
    if (!c.connect_unix(dir_ + "/api.sock", 200)) return json();
    c.send_line(json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", method}}.dump());
    auto line = c.read_line(5000);
    return line ? json::parse(*line)["result"] : json();
  }
  // Runs the whole calibration; the report.
  json run(int plant2_seed, const std::string& plant2_effect = "") {
    return run_yaml(printer_yaml(plant2_seed, plant2_effect));
  }
  // The same on a printer config of the test's own; *out_text (when given): what calibrate said.
  json run_yaml(const std::string& yaml, std::string* out_text = nullptr) {
    start_daemon(yaml);
    std::string out;
    const int rc = calibrate({"--out", dir_ + "/out"}, &out);
    EXPECT_EQ(rc, 0) << out << "\n--- daemon:\n" << daemon_->output();
    if (out_text != nullptr) *out_text = out;
    return json::parse(read_text(dir_ + "/out/report.json"), nullptr, false);
  }
  std::string dir_;
  std::unique_ptr<Subprocess> daemon_;
};

// The first simulator's belt is the config's own model (Eq. 6 with its L and k_hat, stiffer
// towards the ends and by direction), which the overlay cannot write: it writes a uniform belt with
// a direction ratio and a slope along the travel. Calibrated, the axes are found and the model
// tracks the check pattern over 90 % better than open loop, but 2x worse than the config's exact
// model (0.0054 against 0.0027 mm), so calibrate keeps the config's model and says so.
TEST_F(Calibrate, TheFirstSimulatorsAxesAreFoundAndItsExactModelIsKept) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "two minutes of simulated motion and four fits: optimized build only";
#endif
  start_daemon(printer_yaml(-1));
  std::string out;
  EXPECT_EQ(calibrate({"--out", dir_ + "/out"}, &out), 1) << out << "\n--- daemon:\n"
                                                          << daemon_->output();
  const json report = json::parse(read_text(dir_ + "/out/report.json"), nullptr, false);
  ASSERT_TRUE(report.is_object());
  ASSERT_EQ(report["axes"].size(), 2u);
  for (const json& a : report["axes"]) {
    // The held-out part is predicted at least as well as by the baseline, and to a few um.
    EXPECT_LE(a["held_out_after_um"].get<double>(), a["held_out_before_um"].get<double>() + 1e-9) << a.dump();
    EXPECT_LT(a["held_out_after_um"].get<double>(), 15.0) << a.dump();
  }
  // The simulator's belt (Eq. 6, L = 350 mm, k_hat = 38424 N on X) as the identification sees it
  // over the excitation's positions: the directions' mean k2 (uniform) and their ratio, which
  // Eq. 6 puts at (L + x) / (L - x) = 1.5-2.1 over x = 70-125 mm (measured k2 117 kN/m, 1.97).
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), dir_ + "/out/calibration.yaml");
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  const config::GantryModelConfig* x = applied.value().config.model.gantry_for("x");
  std::printf("first simulator's X belt as calibrated: k2 %.0f N/m, direction ratio %.3f\n",
              x->k2_n_per_m, x->belt_direction_ratio);
  EXPECT_EQ(x->stepper.belt_unit_stiffness_n, 0.0);
  EXPECT_GT(x->belt_direction_ratio, 1.3);
  EXPECT_LT(x->belt_direction_ratio, 2.5);
  bool direction_in_model = false;
  for (const json& e : report["axes"][0]["effects"])
    direction_in_model |= e["name"] == "direction_dependent_stiffness" && e["in_model"].get<bool>();
  EXPECT_TRUE(direction_in_model) << report["axes"][0].dump();
  // Open loop the thesis's circle and small star at 90 mm/s read 0.40 and 0.37 mm (Sect. 5.2);
  // LPV feedforward + PI on the calibrated model remove over 90 % of it (measured 97 %), on the
  // config's exact model more (99 %): that one stays.
  const double before = report["e_t_mm"]["before"].get<double>(), after = report["e_t_mm"]["after"].get<double>();
  const double open_loop = report["e_t_mm"]["open_loop"].get<double>();
  std::printf("first simulator: check pattern e_t %.4f -> %.4f mm, open loop %.4f mm\n", before,
              after, open_loop);
  EXPECT_GT(open_loop, 0.2);
  EXPECT_LT(after, 0.1 * open_loop);
  EXPECT_LT(before, after);
  EXPECT_EQ(report["installed"], "");
  EXPECT_NE(report["rolled_back"].get<std::string>().find("check pattern's e_t"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(dir_ + "/calibration.yaml"));
  const json info = api("info");
  EXPECT_EQ(info["calibration"], "");
  EXPECT_EQ(info["control"], "pi");  // the excitation's open loop (no feedforward) is over
  EXPECT_EQ(info["feedforward"], "lpv");
  EXPECT_NE(read_text(dir_ + "/out/report.md").find("| before |"), std::string::npos);
  EXPECT_NE(read_text(dir_ + "/out/report.md").find("**Not kept:**"), std::string::npos);
}

// The first simulator with its encoders 8.31 ms late on X and Y (calibrate_seeds.py --simulator
// sim --effect time_delay, seed 1). Both axes name the delay (on X only beside the belt's
// direction, docs/calibration.md "The first simulator's delay"), the model carries it as the
// encoders' delay, and the loops then track the check pattern 98 % better than open loop (before
// the delay was named: 91 %).
TEST_F(Calibrate, TheFirstSimulatorsEncoderDelayIsNamedAndTheModelCarriesIt) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "two minutes of simulated motion and four fits: optimized build only";
#endif
  std::string y = printer_yaml(-1);
  const std::string with_delay =
      std::regex_replace(y, std::regex("\n  effects: \\{\\}"),
                         "\n  effects: {time_delay: {delay_ms: 8.31, axes: [x, y]}}");
  ASSERT_NE(with_delay, y);
  const json report = run_yaml(with_delay);
  ASSERT_TRUE(report.is_object());
  ASSERT_EQ(report["axes"].size(), 2u);
  std::printf("start trial %s\n", report.value("start_trial", json()).dump().c_str());
  for (const json& a : report["axes"]) {
    double delay_ms = -1.0;
    for (const json& e : a["effects"])
      if (e["name"] == "time_delay" && e["in_model"].get<bool>())
        delay_ms = e["params"]["delay_ms"].get<double>();
    // The trace's own timing adds about a quarter sample (8.56 ms found on X).
    EXPECT_NEAR(delay_ms, 8.31, 0.1 * 8.31) << a.dump();
  }
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), dir_ + "/calibration.yaml");
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  EXPECT_NEAR(applied.value().config.model.gantry_for("y")->encoder_delay_ms, 8.31, 0.1 * 8.31);
  const double after = report["e_t_mm"]["after"].get<double>();
  const double open_loop = report["e_t_mm"]["open_loop"].get<double>();
  std::printf(
      "first simulator, 8.31 ms encoder delay: check pattern e_t %.4f mm, open loop %.4f mm\n",
      after, open_loop);
  EXPECT_LT(after, 0.05 * open_loop);
}

TEST_F(Calibrate, OnTheSecondSimulatorTheCalibratedModelCutsTheTrackingError) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  const json report = run(7);
  ASSERT_TRUE(report.is_object());
  ASSERT_EQ(report["axes"].size(), 2u);
  const double before = report["e_t_mm"]["before"].get<double>(), after = report["e_t_mm"]["after"].get<double>();
  const double open_loop = report["e_t_mm"]["open_loop"].get<double>();
  std::printf("second simulator (seed 7): check pattern e_t %.4f -> %.4f mm, open loop %.4f mm\n",
              before, after, open_loop);
  // Measured 0.3513 -> 0.0054 mm: the config's thesis model against a machine it does not describe
  // made the feedforward 6x worse than open loop (0.060 mm); calibrated, 91 % better than it
  // (78 %, 0.0131 mm, while the overlay kept the config's belt geometry).
  EXPECT_LT(after, 0.3 * before);
  EXPECT_LT(after, 0.12 * open_loop);
  EXPECT_FALSE(report.contains("warning")) << report["warning"];
  // The carriages keep the config's masses (X 0.45 kg, Y 1.07 kg): identification reads the
  // forces through them. This machine's axes are fitted best from the other axis's start, so
  // before the config's masses were passed the overlay swapped them (X 1.07 kg, Y 0.45).
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), dir_ + "/calibration.yaml");
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  for (const char* axis : {"x", "y"}) {
    const config::GantryModelConfig* configured = cfg.value().model.gantry_for(axis);
    const config::GantryModelConfig* calibrated = applied.value().config.model.gantry_for(axis);
    ASSERT_NE(configured, nullptr);
    ASSERT_NE(calibrated, nullptr);
    EXPECT_DOUBLE_EQ(calibrated->m2_kg, configured->m2_kg) << axis;
    // No direction-dependent stiffness is named on this machine: the belt is uniform at the
    // fitted k2, not the config's Eq. 6 belt (L 350 mm) that the data did not bear out.
    EXPECT_GT(configured->stepper.belt_unit_stiffness_n, 0.0) << axis;
    EXPECT_EQ(calibrated->stepper.belt_unit_stiffness_n, 0.0) << axis;
  }
}

// Second simulator, seed 2: its motors are damped on their load angle (plant2/: c_em against the
// field, which follows the command through the driver's lag), Eq. 13's against the frame. On
// calibrate's excitation (moves up to 300 mm/s) Eq. 13's fit drives k1 off its range with c1 of a
// few N s/m (Y: 3.99e6 N/m, 1 N s/m); the baseline takes a field lag on Y (0.22 ms, k1 289 kN/m,
// c1 462 N s/m; the drawn c_em / r^2 is of that size) and predicts the held-out part 26 % better
// (15.87 -> 11.70 um), and with it the belt's slope pays too (9.16 um). The overlay carries the
// lag, and the model tracks the check pattern at 0.0037 mm (the PI at 1/4 of the config's gains)
// where Eq. 13's tracked 0.0060.
TEST_F(Calibrate, TheSecondSimulatorsMotorIsDampedOnItsLoadAngle) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  const json report = run(2);
  ASSERT_TRUE(report.is_object());
  const json y = json::parse(read_text(dir_ + "/out/y/report.json"), nullptr, false);
  ASSERT_TRUE(y.is_object() && y.contains("motor_field")) << y.dump();
  const json& m = y["motor_field"];
  std::printf(
      "second simulator (seed 2), Y: field lag %.3f ms, held out %.3f um with it, %.3f with "
      "Eq. 13's motor; check pattern e_t %.4f mm\n",
      m["field_lag_ms"].get<double>(), m["with_field_lag_held_out_rms_um"].get<double>(),
      m["eq13_motor_held_out_rms_um"].get<double>(), report["e_t_mm"]["after"].get<double>());
  EXPECT_GT(m["field_lag_ms"].get<double>(), 0.05);
  EXPECT_LT(m["field_lag_ms"].get<double>(), 1.0);
  EXPECT_LT(m["with_field_lag_held_out_rms_um"].get<double>(),
            0.9 * m["eq13_motor_held_out_rms_um"].get<double>());
  // Damped against the field, not the frame: c1 / k1 well apart from the lag.
  EXPECT_GT(m["c1_n_s_m"].get<double>() / m["k1_n_m"].get<double>(),
            2e-3 * m["field_lag_ms"].get<double>());
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), dir_ + "/calibration.yaml");
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  EXPECT_NEAR(applied.value().config.model.gantry_for("y")->field_lag_ms,
              m["field_lag_ms"].get<double>(), 1e-4);
  // Eq. 13's calibration of this machine tracked the check pattern at 0.0060 mm (open loop 0.0476).
  EXPECT_LT(report["e_t_mm"]["after"].get<double>(), 0.0054);
}

// Second simulator, seed 1, with a backlash drawn on both axes (34 and 49 um): identification
// names both right and nothing else (until the model's belt was simulated in the regime each
// substep begins in, ident/axis_model.cpp, it also named on Y a periodic error that no part of
// that machine has); each axis's other start gives another model that predicts the recording
// about as well, and both are tried on the check pattern: an other start's model is kept when it
// tracks 5 % better (measured: X's 0.0107 mm against 0.0173: kept; Y's 0.0121 against 0.0107:
// not); each dead band is then tried at x 1/2 and x 3/2 on the check pattern (none kept), and the
// PI gains are chosen from the e_t of the model kept (x 1/2: 0.0100 mm, open loop 0.0890). The
// trial of a named mode or periodic error runs in
// ANamedCarriageModeIsKeptWhenTheMachineTracksBetterWithIt.
TEST_F(Calibrate, TheOtherStartsModelIsTriedOnTheMachine) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  const json report = run(1, "backlash");
  ASSERT_TRUE(report.is_object());
  std::printf("start trial %s\nPI %s\ne_t %s\n", report.value("start_trial", json()).dump().c_str(),
              report["pi_gains"]["tried"].dump().c_str(), report["e_t_mm"].dump().c_str());
  for (const json& a : report["axes"]) {
    ASSERT_EQ(a["effects"].size(), 1u) << a.dump();
    EXPECT_EQ(a["effects"][0]["name"], "backlash") << a.dump();
  }
  EXPECT_FALSE(report.contains("mode_trial")) << report.dump(1);
  ASSERT_TRUE(report.contains("start_trial")) << report.dump(1);
  EXPECT_EQ(report["start_trial"].size(), 2u);
  double e_t_after_trials = NAN;  // the e_t of the overlay the start trials left installed
  for (const json& t : report["start_trial"]) {
    ASSERT_TRUE(t["e_t_other_mm"].is_number()) << t.dump();
    EXPECT_GT(t["held_out_other_um"].get<double>(), 0.0);
    // Kept only when at least 5 % better (kOtherStartMinGain); each against the best so far.
    const bool better = t["e_t_other_mm"].get<double>() < 0.95 * t["e_t_chosen_mm"].get<double>();
    EXPECT_EQ(t["kept"].get<bool>(), better) << t.dump();
    if (!std::isnan(e_t_after_trials)) {
      EXPECT_DOUBLE_EQ(t["e_t_chosen_mm"].get<double>(), e_t_after_trials);
    }
    e_t_after_trials = better ? t["e_t_other_mm"].get<double>() : t["e_t_chosen_mm"].get<double>();
  }
  // Then each axis's dead band at x 1/2 and x 3/2 (measured: X 0.0167 and 0.0156 mm, Y 0.0129
  // and 0.0143, against 0.0129: none kept), each scale kept only when 5 % better than the best so
  // far (kSizeTrialMinGain).
  ASSERT_TRUE(report.contains("size_trial")) << report.dump(1);
  EXPECT_EQ(report["size_trial"].size(), 2u);
  for (const json& t : report["size_trial"]) {
    EXPECT_EQ(t["size"], "backlash_mm") << t.dump();
    EXPECT_GT(t["identified"].get<double>(), 0.02) << t.dump();  // 34 and 49 um drawn
    const json& tried = t["tried"];
    ASSERT_GE(tried.size(), 3u) << t.dump();
    EXPECT_DOUBLE_EQ(tried[0]["e_t_mm"].get<double>(), e_t_after_trials);
    double best = e_t_after_trials, kept_scale = 1.0;
    for (size_t i = 1; i < tried.size(); ++i) {
      ASSERT_TRUE(tried[i]["e_t_mm"].is_number()) << t.dump();
      if (tried[i]["e_t_mm"].get<double>() < 0.95 * best) {
        best = tried[i]["e_t_mm"].get<double>();
        kept_scale = tried[i]["scale"].get<double>();
      }
    }
    EXPECT_EQ(t["scale"].get<double>(), kept_scale) << t.dump();
    e_t_after_trials = best;
  }
  // The PI gains start from the model kept: x 1's e_t is the trials' last.
  EXPECT_DOUBLE_EQ(report["pi_gains"]["tried"][0]["e_t_mm"].get<double>(), e_t_after_trials);
  EXPECT_LT(report["e_t_mm"]["after"].get<double>(),
            0.15 * report["e_t_mm"]["open_loop"].get<double>());
  const std::string md = read_text(dir_ + "/out/report.md");
  EXPECT_NE(md.find("## The other start's model on the machine"), std::string::npos) << md;
  EXPECT_NE(md.find("## The friction forces and dead bands on the machine"), std::string::npos)
      << md;
}

// Second simulator, seed 1, with a LuGre friction drawn on both axes (X 2.99 N, Y 4.73 N, breaking
// away at 1.1-1.4 times that): identification's Dahl friction finds 1.50 N on X and 5.36 on Y,
// and X's force pushes the motor too hard through the check pattern's reversals. Each carried
// force is tried on the check pattern at x 1/2 (then 0), or x 3/2: X's half is kept (measured:
// 0.0270 mm against 0.0290 with the force identified; none 0.0282), Y's identified force is (its
// half 0.0260: 4 %, under the 5 % margin; x 3/2 0.0327). The overlay carries X's half; the
// effect reports the force found.
TEST_F(Calibrate, AFrictionForceTheMachineTracksBetterHalvedIsHalved) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  const json report = run(1, "coulomb_friction");
  ASSERT_TRUE(report.is_object());
  ASSERT_TRUE(report.contains("size_trial")) << report.dump(1);
  std::printf("size trial %s\ne_t %s\n", report["size_trial"].dump().c_str(),
              report["e_t_mm"].dump().c_str());
  const json* x = nullptr;
  const json* y = nullptr;
  for (const json& t : report["size_trial"])
    if (t["size"] == "coulomb_friction_n") (t["axis"] == "x" ? x : y) = &t;
  ASSERT_TRUE(x != nullptr && y != nullptr) << report["size_trial"].dump(1);
  EXPECT_EQ((*x)["scale"].get<double>(), 0.5) << x->dump();
  EXPECT_EQ((*y)["scale"].get<double>(), 1.0) << y->dump();
  // X's half tracked at least 5 % better than the identified force.
  const json& tried = (*x)["tried"];
  ASSERT_GE(tried.size(), 2u);
  EXPECT_EQ(tried[1]["scale"].get<double>(), 0.5);
  EXPECT_LT(tried[1]["e_t_mm"].get<double>(), 0.95 * tried[0]["e_t_mm"].get<double>());
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), dir_ + "/calibration.yaml");
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  EXPECT_NEAR(applied.value().config.model.gantry_for("x")->coulomb_friction_n,
              0.5 * (*x)["identified"].get<double>(), 1e-6);
  EXPECT_NEAR(applied.value().config.model.gantry_for("y")->coulomb_friction_n,
              (*y)["identified"].get<double>(), 1e-6);
  for (const config::CalibrationEffect& e : applied.value().effects) {
    if (e.axis == "x" && e.name == "coulomb_friction") {
      EXPECT_NEAR(e.params.at("force_n"), (*x)["identified"].get<double>(), 1e-3);
    }
  }
  EXPECT_LT(report["e_t_mm"]["after"].get<double>(),
            0.25 * report["e_t_mm"]["open_loop"].get<double>());
  const std::string md = read_text(dir_ + "/out/report.md");
  EXPECT_NE(md.find("| x | `coulomb_friction_n` | 1.4"), std::string::npos) << md;
}

// Second simulator, seed 1, with a mode drawn on both carriages (a mass of 15-35 % of the carriage
// on a spring-damper at 40-150 Hz, plant2/draw.cpp): identification names it on both axes, the
// overlay is installed without it first (the model fitted without the mode), the PI gains are
// chosen on it, and the model with the mode (a mass on the carriage in every feedforward design)
// is tried on the check pattern with those gains and kept because it tracks better. Measured:
// 0.0064 mm without, 0.0052 with (-92 % against open loop). On the clean machines whose
// distributed belt identification reads as a mode (seeds 5 and 6) the trial keeps the model
// without it (0.0078 against 0.0090, 0.0065 against 0.0090: docs/calibration.md).
TEST_F(Calibrate, ANamedCarriageModeIsKeptWhenTheMachineTracksBetterWithIt) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  const json report = run(1, "extra_resonance");
  ASSERT_TRUE(report.is_object());
  ASSERT_TRUE(report.contains("mode_trial")) << report.dump(1);
  const json& t = report["mode_trial"];
  std::printf(
      "second simulator (seed 1, extra_resonance): without the mode %.4f mm, with it %s mm\n",
      t["e_t_without_mm"].get<double>(), t["e_t_with_mm"].dump().c_str());
  EXPECT_EQ(t["axes"].size(), 2u);
  ASSERT_TRUE(t["e_t_with_mm"].is_number());
  EXPECT_TRUE(t["kept"].get<bool>());
  EXPECT_LT(t["e_t_with_mm"].get<double>(), 0.95 * t["e_t_without_mm"].get<double>());
  EXPECT_DOUBLE_EQ(report["e_t_mm"]["after"].get<double>(), t["e_t_with_mm"].get<double>());
  EXPECT_LT(report["e_t_mm"]["after"].get<double>(),
            0.1 * report["e_t_mm"]["open_loop"].get<double>());
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), dir_ + "/calibration.yaml");
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  for (const char* axis : {"x", "y"}) {
    const config::GantryModelConfig* g = applied.value().config.model.gantry_for(axis);
    ASSERT_NE(g, nullptr);
    EXPECT_GT(g->extra_resonance_mass_kg, 0.0) << axis;
    EXPECT_GE(g->extra_resonance_hz, 30.0) << axis;
    EXPECT_LE(g->extra_resonance_hz, 200.0) << axis;
  }
  const std::string md = read_text(dir_ + "/out/report.md");
  EXPECT_NE(md.find("## The named mode or periodic error on the machine"), std::string::npos) << md;
  EXPECT_NE(md.find("extra_resonance on x"), std::string::npos) << md;
}

// Second simulator, seed 1 (X: drawn machine 1, a clean machine whose carriage mode is at 34 Hz):
// from the thesis's presets the baseline fit stopped at 135 Hz with k1 on its bound (34.7 um held
// out, 86 % off the measured FRF), the screening named a 226 Hz resonance and an 8.2 N friction
// the machine does not have, and the calibrated model tracked 0.0238 mm (-62 % against open loop).
// A baseline that far off its FRF is fitted again from a start read off the FRF (docs/ident.md):
// measured 8.39 um held out, nothing named on either axis, 0.0055 mm (-91 %).
TEST_F(Calibrate, OnTheSecondSimulatorABaselineFarFromThePresetsIsStartedFromTheFrf) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  const json report = run(1);
  ASSERT_TRUE(report.is_object());
  ASSERT_EQ(report["axes"].size(), 2u);
  const json& x = report["axes"][0];
  EXPECT_EQ(x["axis"], "x");
  EXPECT_LT(x["baseline_rms_um"].get<double>(), 15.0) << x.dump();  // was 33.1
  for (const json& a : report["axes"]) EXPECT_TRUE(a["effects"].empty()) << a.dump();
  const double after = report["e_t_mm"]["after"].get<double>();
  const double open_loop = report["e_t_mm"]["open_loop"].get<double>();
  std::printf("second simulator (seed 1): check pattern e_t %.4f mm, open loop %.4f mm\n", after,
              open_loop);
  EXPECT_LT(after, 0.12 * open_loop);
}

// Second simulator, seed 4 (X and Y of drawn machines 4 and 5): with the config's PI gains (the
// thesis's kp 0.5, ki 20 /s) the calibrated model tracks the check pattern at 0.0249 mm (open
// loop 0.0451), scaled by 1/2 at 0.0050: calibrate keeps 1/2 in the overlay's control.axes.
// (Before the motor's field lag, 2026-12-07, those gains made the loop ring on drawn machine 5
// with any model: 0.3843 mm calibrated, and the feedforward alone tracked best, 0.0044.)
TEST_F(Calibrate, ThePiGainsAreChosenOnTheCalibratedModel) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  const json report = run(4);
  ASSERT_TRUE(report.is_object());
  ASSERT_TRUE(report.contains("pi_gains")) << report.dump();
  const json& g = report["pi_gains"];
  const double before = report["e_t_mm"]["before"].get<double>(),
               after = report["e_t_mm"]["after"].get<double>(),
               open_loop = report["e_t_mm"]["open_loop"].get<double>();
  const double configured = g["tried"][0]["e_t_mm"].get<double>();
  std::printf(
      "second simulator (seed 4): e_t before %.4f, calibrated with the config's gains %.4f, "
      "with x %.2g of them %.4f mm, open loop %.4f mm\n",
      before, configured, g["scale"].get<double>(), after, open_loop);
  EXPECT_EQ(g["tried"][0]["scale"].get<double>(), 1.0);
  EXPECT_LT(g["scale"].get<double>(), 1.0);
  EXPECT_GE(g["scale"].get<double>(), 0.25);  // the loop stays closed
  EXPECT_LT(after, 0.35 * open_loop);
  EXPECT_LT(after, 0.25 * configured);
  // Every scale tried is in the report, and the one kept is the best of them.
  for (const json& t : g["tried"])
    if (t["e_t_mm"].is_number()) {
      EXPECT_GE(t["e_t_mm"].get<double>(), after);
    }
  // The overlay carries the gains, and the daemon runs with them.
  const std::string installed = dir_ + "/calibration.yaml";
  EXPECT_EQ(report["installed"], installed);
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), installed);
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  for (const char* axis : {"x", "y"}) {
    EXPECT_DOUBLE_EQ(applied.value().config.control.gains_for(axis).kp,
                     g["scale"].get<double>() * cfg.value().control.gains_for(axis).kp)
        << axis;
  }
  EXPECT_NE(read_text(dir_ + "/out/report.md").find("## PI gains on the calibrated model"),
            std::string::npos);
}

// Second simulator, seed 4 (X and Y of drawn machines 4 and 5) with PI gains twice the thesis's
// (kp 1, ki 40 /s) kept (--keep-pi-gains): the loop rings with the config's model and with the
// calibrated one (0.5732 and 0.5840 mm, open loop 0.0451; with --max-worse-pct 0 the calibrated
// one is then rolled back by its 2 %). Whichever model the machine goes on printing with, it
// tracks over 10x worse than open loop, and the user is told that no feedforward prints better.
// (The rollback itself: TheFirstSimulatorsAxesAreFoundAndItsExactModelIsKept.)
TEST_F(Calibrate, TheUserIsToldWhenTheMachinePrintsWorseThanOpenLoop) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "the external plant in lock-step for two minutes of motion: optimized build only";
#endif
  std::string yaml = printer_yaml(4);
  yaml = std::regex_replace(yaml, std::regex("\n  kp: 0\\.5 "), "\n  kp: 1.0 ");
  yaml = std::regex_replace(yaml, std::regex("\n  ki_per_s: 20\n"), "\n  ki_per_s: 40\n");
  ASSERT_NE(yaml.find("\n  kp: 1.0 "), std::string::npos);
  ASSERT_NE(yaml.find("\n  ki_per_s: 40\n"), std::string::npos);
  start_daemon(yaml);
  std::string out;
  const int rc =
      calibrate({"--out", dir_ + "/out", "--max-worse-pct", "0", "--keep-pi-gains"}, &out);
  EXPECT_TRUE(rc == 0 || rc == 1) << out;
  const json report = json::parse(read_text(dir_ + "/out/report.json"), nullptr, false);
  ASSERT_TRUE(report.is_object());
  ASSERT_TRUE(report["e_t_mm"]["after"].is_number()) << report.dump(2) << "\n--- calibrate:\n"
                                                     << out << "\n--- daemon:\n"
                                                     << daemon_->output();
  const double before = report["e_t_mm"]["before"].get<double>(),
               after = report["e_t_mm"]["after"].get<double>();
  std::printf("second simulator (seed 4), gains x2 kept: check pattern e_t %.4f -> %.4f mm (%s)\n",
              before, after, rc == 1 ? "rolled back" : "kept");
  const double kept = rc == 1 ? before : after;
  EXPECT_GT(kept, 5.0 * report["e_t_mm"]["open_loop"].get<double>());
  ASSERT_TRUE(report.contains("warning")) << report.dump();
  EXPECT_NE(report["warning"].get<std::string>().find("worse than open loop"), std::string::npos);
  EXPECT_NE(out.find("warning: the model the machine now prints with tracks the check pattern "
                     "worse than open loop"),
            std::string::npos)
      << out;
  EXPECT_NE(read_text(dir_ + "/out/report.md").find("**Warning:**"), std::string::npos);
}

// The first simulator with all seven of its effects drawn big (calibrate_seeds.py --simulator sim
// --effect all, seed 2): its Y carriage (1.07 kg, 3.9 N of friction, a 78 Hz mode) loses steps
// in the excitation, and no model of the axis describes that recording (2.2 mm RMS held out; the
// fit put a scale of 0.9 on it). That fit is refused and Y is excited again at half the
// acceleration and speed, where it keeps its steps and is calibrated; X is calibrated at once,
// with its 0.82 % scale error as the feedforward's travel_scale.
TEST_F(Calibrate, AnAxisWhoseRecordingNoModelDescribesIsExcitedAgainGentler) {
#ifdef FEEDLOOP_SANITIZED
  GTEST_SKIP() << "two minutes of simulated motion and four fits: optimized build only";
#endif
  std::string y = printer_yaml(-1);
  y = std::regex_replace(y, std::regex("simulator:\n  seed: 1\n"), "simulator:\n  seed: 2\n");
  y = std::regex_replace(
      y, std::regex("\n  effects: \\{\\}"),
      "\n  effects: {coulomb_friction: {force_n: 3.859, axes: [x, y]}, backlash: {width_um: 22.1, "
      "axes: [x, y]}, periodic_position: {period_mm: 27.28, amplitude_um: 28.5, axes: [x, y]}, "
      "direction_dependent_stiffness: {ratio: 2.199, axes: [x, y]}, extra_resonance: {freq_hz: "
      "77.9, damping: 0.041, axes: [x, y]}, time_delay: {delay_ms: 9.23, axes: [x, y]}, "
      "scale_error: {scale: 1.00818, axes: [x, y]}}");
  ASSERT_NE(y.find("seed: 2"), std::string::npos);
  ASSERT_NE(y.find("scale: 1.00818"), std::string::npos);
  std::string out;
  const json report = run_yaml(y, &out);
  ASSERT_TRUE(report.is_object());
  ASSERT_EQ(report["axes"].size(), 2u);
  const json& ax = report["axes"][0];
  const json& ay = report["axes"][1];
  std::printf("all effects, seed 2: held out x %.1f um, y %.1f um\n",
              ax["held_out_after_um"].get<double>(), ay["held_out_after_um"].get<double>());
  EXPECT_FALSE(ax.contains("not_calibrated")) << ax.dump();
  EXPECT_FALSE(ay.contains("not_calibrated")) << ay.dump();
  EXPECT_FALSE(ax.contains("gentle"));
  EXPECT_TRUE(ay.contains("gentle")) << ay.dump();
  ASSERT_TRUE(report.contains("first_attempts")) << report.dump();
  ASSERT_EQ(report["first_attempts"].size(), 1u);
  EXPECT_EQ(report["first_attempts"][0]["axis"], "y");
  EXPECT_GT(report["first_attempts"][0]["held_out_after_um"].get<double>(), 200.0);
  EXPECT_NE(report["first_attempts"][0]["not_calibrated"].get<std::string>().find("lost steps"),
            std::string::npos);
  EXPECT_LT(ay["held_out_after_um"].get<double>(), 200.0);
  EXPECT_NE(out.find("exciting it again at half the acceleration and speed"), std::string::npos)
      << out;
  EXPECT_NE(read_text(dir_ + "/out/report.md").find("**Excited again"), std::string::npos);
  auto cfg = config::load_config_file(dir_ + "/printer.yaml");
  ASSERT_TRUE(cfg.ok());
  auto applied = config::apply_calibration_file(cfg.value(), dir_ + "/out/calibration.yaml");
  ASSERT_TRUE(applied.ok()) << applied.error().to_string();
  EXPECT_EQ(applied.value().axes.size(), 2u);
  const double scale = applied.value().config.model.gantry_for("x")->travel_scale;
  std::printf("x travel_scale %.5f (drawn 1.00818)\n", scale);
  EXPECT_NEAR(scale - 1.0, 0.00818, 0.1 * 0.00818);
}

// A daemon whose answers have another shape (an older feedloopd, a broken reply): every request
// gets an empty result. calibrate says so and exits 1; it does not abort.
TEST_F(Calibrate, AnAnswerOfAnotherShapeIsAClearError) {
  const std::string path = dir_ + "/fake.sock";
  const int listener = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(listener, 1), 0);
  std::thread fake([listener] {
    const int c = ::accept(listener, nullptr, nullptr);
    if (c < 0) return;
    std::string buf;
    char tmp[4096];
    for (ssize_t n; (n = ::read(c, tmp, sizeof tmp)) > 0;) {
      buf.append(tmp, static_cast<size_t>(n));
      for (size_t nl; (nl = buf.find('\n')) != std::string::npos; buf.erase(0, nl + 1)) {
        const json req = json::parse(buf.substr(0, nl), nullptr, false);
        const std::string reply = json{{"jsonrpc", "2.0"},
                                       {"id", req.is_object() ? req.value("id", 0) : 0},
                                       {"result", json::object()}}
                                      .dump() +
                                  "\n";
        if (::write(c, reply.data(), reply.size()) < 0) break;
      }
    }
    ::close(c);
  });
  std::string out;
  EXPECT_EQ(calibrate({"--api", path, "--out", dir_ + "/out"}, &out, 30), 1);
  EXPECT_NE(out.find("the daemon's answer is not what this feedloop expects"), std::string::npos)
      << out;
  ::shutdown(listener, SHUT_RDWR);
  ::close(listener);
  fake.join();
}

TEST_F(Calibrate, WithoutADaemonOrWithBadArgumentsItSaysWhy) {
  std::string out;
  EXPECT_EQ(calibrate({"--out", dir_ + "/out"}, &out, 30), 1);
  EXPECT_NE(out.find("cannot connect to the daemon's API socket " + dir_ + "/api.sock"), std::string::npos) << out;
  EXPECT_EQ(calibrate({"--seed", "x1"}, &out, 30), 2);
  EXPECT_NE(out.find("--seed takes a whole number"), std::string::npos) << out;
  for (const char* bad : {"-1", "nan", "10%", ""}) {
    EXPECT_EQ(calibrate({"--max-worse-pct", bad}, &out, 30), 2) << bad;
    EXPECT_NE(out.find("--max-worse-pct takes a percentage >= 0, not '" + std::string(bad) + "'"),
              std::string::npos)
        << out;
  }
  EXPECT_EQ(calibrate({"--write-gcode", dir_ + "/g", "--axes", "x,z"}, &out, 30), 1);
  EXPECT_NE(out.find("--axes takes x and y (not 'z')"), std::string::npos) << out;
  // No axis ran an empty calibration and wrote an empty overlay; an axis twice ran it twice.
  EXPECT_EQ(calibrate({"--write-gcode", dir_ + "/g", "--axes", ""}, &out, 30), 1);
  EXPECT_NE(out.find("feedloop calibrate: --axes names no axis"), std::string::npos) << out;
  EXPECT_EQ(calibrate({"--write-gcode", dir_ + "/g", "--axes", "x,y,x"}, &out, 30), 1);
  EXPECT_NE(out.find("--axes names x twice"), std::string::npos) << out;
  // The programs alone: every line a move, a dwell or a comment, within the travel.
  EXPECT_EQ(calibrate({"--write-gcode", dir_ + "/g"}, &out, 30), 0) << out;
  const std::string x = read_text(dir_ + "/g/calibrate_x.gcode");
  std::istringstream lines(x);
  int moves = 0;
  for (std::string l; std::getline(lines, l);) {
    ASSERT_TRUE(l.rfind("G1 ", 0) == 0 || l.rfind("G4 P", 0) == 0 || l.rfind(";", 0) == 0 || l == "G90" ||
                l == "M400")
        << l;
    std::smatch m;
    if (std::regex_search(l, m, std::regex("X([-0-9.]+)"))) {
      const double pos = std::stod(m[1]);
      EXPECT_GE(pos, 0.0);
      EXPECT_LE(pos, 250.0);
      ++moves;
    }
  }
  EXPECT_GT(moves, 500);
  EXPECT_TRUE(fs::exists(dir_ + "/g/calibrate_check.gcode"));
}

}  // namespace
}  // namespace feedloop::testing
