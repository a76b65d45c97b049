// The identification report's data files and plots (ident/report.hpp, ident/plots.hpp) and the
// `feedloop ident frf` command, without a fit (fast: also in the sanitizer build).
#include <gtest/gtest.h>
#include <unistd.h>  // getpid

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cli/ident_command.hpp"
#include "ident/axis_model.hpp"
#include "ident/excitation.hpp"
#include "ident/plots.hpp"
#include "ident/report.hpp"
#include "ident/trace.hpp"

namespace feedloop::ident {
namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::filesystem::path temp_dir(const std::string& name) {
  auto d = std::filesystem::temp_directory_path() / ("feedloop_ident_report_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

int count_lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n' ? 1 : 0;
  return n;
}

// A result as identify_axis would give it for a trace with a 15 um runout of 20 mm period: the
// "measurement" is the augmented model's own output, so the residual after is exactly zero.
struct Fixture {
  std::vector<double> time_s, cmd_mm, meas_mm;
  IdentResult r;
};
Fixture make_fixture() {
  Fixture f;
  RandomMovesOptions ro;
  ro.duration_s = 8.0;
  ro.travel_mm = 60.0;
  f.cmd_mm = random_moves(ro);
  for (size_t k = 0; k < f.cmd_mm.size(); ++k) f.time_s.push_back(static_cast<double>(k) * 1e-3);
  f.r.axis = "x";
  f.r.baseline = preset_axis_model("x");
  f.r.augmented = f.r.baseline;
  f.r.augmented.set(Effect::kPeriodicPosition, true);
  f.r.augmented.period_mm = 20.0;
  f.r.augmented.periodic_sin_um = 15.0;
  f.r.effects = {Effect::kPeriodicPosition};
  std::vector<double> yb, ya;
  EXPECT_TRUE(simulate_axis(f.r.baseline, f.cmd_mm, 1e-3, &yb).ok());
  EXPECT_TRUE(simulate_axis(f.r.augmented, f.cmd_mm, 1e-3, &ya).ok());
  f.meas_mm = ya;
  for (size_t k = 0; k < ya.size(); ++k) {
    f.r.baseline_residual_mm.push_back(ya[k] - yb[k]);
    f.r.augmented_residual_mm.push_back(0.0);
  }
  f.r.baseline_rms_um = residual_rms_um(yb, ya, 0, ya.size());
  return f;
}

TEST(IdentReport, WritesFrfResidualAndEvidenceDataAndListsThePlots) {
  const auto dir = temp_dir("plots");
  const Fixture f = make_fixture();
  EXPECT_GT(f.r.baseline_rms_um, 5.0);
  ReportExtras extras;
  ASSERT_TRUE(write_report(dir.string(), f.r, f.time_s, f.cmd_mm, f.meas_mm, 1e-3, "fixture", {}, &extras).ok());
  // frf.csv: header + 397 grid points (2-200 Hz at 1 kHz, the identification's grid); the
  // measurement is the model, so H1 of a runout-free stretch matches the baseline closely at low
  // frequency.
  const std::string frf = slurp(dir / "frf.csv");
  EXPECT_EQ(count_lines(frf), 398);
  EXPECT_EQ(frf.rfind("freq_hz,h1_mag,h1_phase_deg,coherence,baseline_mag", 0), 0u);
  EXPECT_EQ(count_lines(slurp(dir / "residual.csv")), 8001);
  EXPECT_GT(count_lines(slurp(dir / "residual_psd.csv")), 400);  // 0.5-250 Hz in 0.5 Hz steps
  // Evidence for the runout, against position: the effect accounts for the residual without it
  // exactly (the data are the augmented model's output).
  const std::string ev = slurp(dir / "evidence_periodic_position.csv");
  ASSERT_GT(count_lines(ev), 1000);
  std::istringstream in(ev);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "cmd_mm,residual_without_um,effect_um,residual_after_um");
  double worst = 0.0, peak = 0.0;
  while (std::getline(in, line)) {
    double x = 0, without = 0, effect = 0, after = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &x, &without, &effect, &after), 4) << line;
    worst = std::max(worst, std::abs(without - effect));
    peak = std::max(peak, std::abs(effect));
  }
  EXPECT_LT(worst, 0.001);  // um (file precision)
  EXPECT_GT(peak, 12.0);    // the 15 um runout, seen through the belt
  const std::string md = slurp(dir / "report.md");
  EXPECT_NE(md.find("## Measured frequency response"), std::string::npos);
  EXPECT_NE(md.find("Coherence > 0.9 at"), std::string::npos) << md;
  if (find_gnuplot().empty()) {
    EXPECT_NE(extras.plot_note.find("gnuplot was not found"), std::string::npos);
    GTEST_SKIP() << "gnuplot not installed: data files checked, plots not";
  }
  EXPECT_EQ(extras.plot_note, "");
  const char* expected[] = {"bode.png", "residual_psd.png", "residual_time.png", "residual_position.png",
                            "evidence_periodic_position.png"};
  ASSERT_EQ(extras.plots.size(), 5u);
  for (const char* png : expected) {
    const std::string img = slurp(dir / png);
    ASSERT_GT(img.size(), 2000u) << png;
    EXPECT_EQ(img.substr(1, 3), "PNG") << png;
    EXPECT_NE(md.find(std::string("[`") + png + "`]"), std::string::npos) << png;
  }
  std::filesystem::remove_all(dir);
}

TEST(IdentReport, WithoutGnuplotTheReportSaysSoAndStillSucceeds) {
  const auto dir = temp_dir("nognuplot");
  const Fixture f = make_fixture();
  ::setenv("FEEDLOOP_GNUPLOT", "feedloop-no-such-gnuplot", 1);
  ReportExtras extras;
  const Status s = write_report(dir.string(), f.r, f.time_s, f.cmd_mm, f.meas_mm, 1e-3, "fixture", {}, &extras);
  ::unsetenv("FEEDLOOP_GNUPLOT");
  ASSERT_TRUE(s.ok()) << s.error().to_string();
  EXPECT_TRUE(extras.plots.empty());
  EXPECT_FALSE(std::filesystem::exists(dir / "bode.png"));
  EXPECT_TRUE(std::filesystem::exists(dir / "bode.gp"));  // can be run later
  EXPECT_TRUE(std::filesystem::exists(dir / "frf.csv"));
  const std::string md = slurp(dir / "report.md");
  EXPECT_NE(md.find("**Note:** plots not drawn: gnuplot was not found (install gnuplot-nox)"), std::string::npos) << md;
  std::filesystem::remove_all(dir);
}

TEST(IdentReport, ATraceTooShortForTheFrfLeavesANote) {
  const auto dir = temp_dir("short");
  Fixture f = make_fixture();
  const size_t n = 1500;  // 1.5 s < one 2 s segment
  f.time_s.resize(n);
  f.cmd_mm.resize(n);
  f.meas_mm.resize(n);
  f.r.baseline_residual_mm.resize(n);
  f.r.augmented_residual_mm.resize(n);
  ReportOptions o;
  o.plots = false;
  ASSERT_TRUE(write_report(dir.string(), f.r, f.time_s, f.cmd_mm, f.meas_mm, 1e-3, "short", o).ok());
  const std::string md = slurp(dir / "report.md");
  EXPECT_NE(md.find("Not estimated: FRF: trace has 1500 samples, one 2 s segment needs 2000"), std::string::npos) << md;
  EXPECT_FALSE(std::filesystem::exists(dir / "frf.csv"));
  std::filesystem::remove_all(dir);
}

TEST(IdentFrfCommand, WritesH1AndCoherenceOfATrace) {
  const auto dir = temp_dir("frfcmd");
  const auto trace = dir / "sweep.csv";
  ASSERT_EQ(cli::ident_command({"excite", "--axis", "x", "--sweep", "--duration", "8", "--out", trace.string()}), 0);
  const auto out = dir / "frf.csv";
  ASSERT_EQ(cli::ident_command({"frf", "--trace", trace.string(), "--out", out.string()}), 0);
  const std::string csv = slurp(out);
  EXPECT_EQ(count_lines(csv), 248);
  EXPECT_EQ(csv.rfind("freq_hz,mag,phase_deg,re,im,coherence\n2.0000,", 0), 0u) << csv.substr(0, 80);
  // At 10 Hz (well inside the 2-120 Hz sweep) H1 matches
  // the model: |G(j 2 pi 10)| = 0.9486 (thesis X, Eq. 16), within 1 %, coherence near 1.
  const size_t row = csv.find("\n10.0000,");
  ASSERT_NE(row, std::string::npos);
  double f = 0, mag = 0, phase = 0, re = 0, im = 0, coh = 0;
  ASSERT_EQ(std::sscanf(csv.c_str() + row + 1, "%lf,%lf,%lf,%lf,%lf,%lf", &f, &mag, &phase, &re, &im, &coh), 6);
  EXPECT_NEAR(mag, 0.9486, 0.01);
  EXPECT_GT(coh, 0.99);
  // User errors: unknown option, a window name, a trace shorter than a segment.
  EXPECT_EQ(cli::ident_command({"frf", "--trace", trace.string(), "--out", out.string(), "--window", "kaiser"}), 2);
  EXPECT_EQ(cli::ident_command({"frf", "--trace", trace.string(), "--out", out.string(), "--segment", "20"}), 1);
  EXPECT_EQ(cli::ident_command({"frf", "--trace", (dir / "missing.csv").string(), "--out", out.string()}), 1);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace feedloop::ident
