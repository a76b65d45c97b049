// `feedloop ident excite|fit` and `feedloop model frf` end to end: files written, report.json and
// the FRF CSV accepted by the contract checker (when ../shared/tools is present), errors reported.
#include <gtest/gtest.h>
#include <unistd.h>  // getpid

#include <algorithm>
#include <cmath>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cli/ident_command.hpp"
#include "cli/model_command.hpp"
#include "ident/trace.hpp"
#include "model/frf_csv.hpp"

namespace feedloop::cli {
namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::filesystem::path temp_dir(const std::string& name) {
  auto d = std::filesystem::temp_directory_path() / ("feedloop_ident_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

// Runs the contract checker if it exists; returns -1 when it does not (the test then skips that part).
int check_contract(const std::string& kind, const std::filesystem::path& file) {
  const std::string tool = std::string(FEEDLOOP_SHARED_DIR) + "/tools/check_contracts.py";
  if (!std::filesystem::exists(tool) || std::system("python3 --version > /dev/null 2>&1") != 0) return -1;
  const std::string cmd = "python3 " + tool + " " + kind + " " + file.string() + " > /dev/null";
  return std::system(cmd.c_str());
}

TEST(IdentCli, ExciteThenFitFindsThePeriodicEffectAndWritesTheContract) {
  const auto dir = temp_dir("fit");
  const auto trace = dir / "trace.csv";
  ASSERT_EQ(ident_command({"excite", "--axis", "y", "--effect", "periodic_position:period_mm=20,amplitude_um=10",
                           "--duration", "12", "--out", trace.string()}),
            0);
  auto t = ident::read_trace_csv(trace.string());
  ASSERT_TRUE(t.ok()) << t.error().to_string();
  EXPECT_EQ(t.value().samples(), 12000u);
  EXPECT_EQ(check_contract("trace", trace) > 0, false);
  ASSERT_EQ(ident_command({"fit", "--trace", trace.string(), "--out", (dir / "out").string()}), 0);
  const std::string json = slurp(dir / "out" / "report.json");
  EXPECT_NE(json.find("\"axis\": \"y\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"name\": \"periodic_position\""), std::string::npos) << json;
  EXPECT_EQ(json.find("backlash"), std::string::npos) << json;
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "report.md"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "residual.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "frf.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "evidence_periodic_position.csv"));
  const std::string md = slurp(dir / "out" / "report.md");
  EXPECT_NE(md.find("## Measured frequency response"), std::string::npos) << md;
  EXPECT_NE(md.find("## Plots"), std::string::npos) << md;
  if (std::system("gnuplot --version > /dev/null 2>&1") == 0) {
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / "bode.png"));
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / "evidence_periodic_position.png"));
    EXPECT_NE(md.find("[`evidence_periodic_position.png`]"), std::string::npos) << md;
  }
  const int rc = check_contract("report", dir / "out" / "report.json");
  if (rc >= 0) {
    EXPECT_EQ(rc, 0) << json;
  }
  // --max-effects 0: the baseline alone, nothing added.
  ASSERT_EQ(ident_command({"fit", "--trace", trace.string(), "--out", (dir / "base").string(), "--max-effects", "0",
                           "--no-plots"}),
            0);
  const std::string base = slurp(dir / "base" / "report.json");
  EXPECT_EQ(base.find("\"name\": \"periodic_position\""), std::string::npos) << base;
  EXPECT_NE(base.find("m2=1.07 kg"), std::string::npos) << base;  // the thesis's Y carriage
  // --carriage-mass-kg: the weighed carriage is the model's m2.
  ASSERT_EQ(ident_command({"fit", "--trace", trace.string(), "--out", (dir / "mass").string(),
                           "--max-effects", "0", "--no-plots", "--carriage-mass-kg", "2.14"}),
            0);
  const std::string mass = slurp(dir / "mass" / "report.json");
  EXPECT_NE(mass.find("m2=2.14 kg"), std::string::npos) << mass;
  std::filesystem::remove_all(dir);
}

// The number after "key: " in a YAML text (NaN when absent).
double yaml_number(const std::string& text, const std::string& key) {
  const size_t at = text.find(key + ": ");
  if (at == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + at + key.size() + 2, nullptr);
}

// --start-mm puts the trace in the machine's frame, as `feedloop calibrate` does with a
// recording: the same fit, the runout's phase reference moved by exactly the offset.
TEST(IdentCli, StartMmPlacesTheOverlaysRunoutInTheMachinesFrame) {
  const auto dir = temp_dir("start");
  const auto trace = dir / "trace.csv";
  ASSERT_EQ(ident_command({"excite", "--axis", "y", "--effect",
                           "periodic_position:period_mm=20,amplitude_um=10", "--duration", "12",
                           "--out", trace.string()}),
            0);
  auto t = ident::read_trace_csv(trace.string());
  ASSERT_TRUE(t.ok()) << t.error().to_string();
  const double first_cmd_mm = t.value().axes.front().cmd_mm.front();
  ASSERT_EQ(ident_command({"fit", "--trace", trace.string(), "--out", (dir / "a").string(),
                           "--no-plots", "--overlay", (dir / "a.yaml").string()}),
            0);
  ASSERT_EQ(
      ident_command({"fit", "--trace", trace.string(), "--out", (dir / "b").string(), "--no-plots",
                     "--overlay", (dir / "b.yaml").string(), "--start-mm", "87.5"}),
      0);
  const std::string a = slurp(dir / "a.yaml"), b = slurp(dir / "b.yaml");
  const double ref_a = yaml_number(a, "runout_reference_mm"),
               ref_b = yaml_number(b, "runout_reference_mm");
  ASSERT_TRUE(std::isfinite(ref_a)) << a;
  ASSERT_TRUE(std::isfinite(ref_b)) << b;
  EXPECT_NEAR(ref_a, first_cmd_mm, 1e-9);
  EXPECT_NEAR(ref_b, 87.5, 1e-9);
  // The same runout found either way (the fit sees the same motion).
  for (const char* key : {"runout_period_mm", "runout_sin_um", "runout_cos_um"}) {
    const double va = yaml_number(a, key), vb = yaml_number(b, key);
    ASSERT_TRUE(std::isfinite(va) && std::isfinite(vb)) << key << "\n" << a;
    EXPECT_NEAR(va, vb, 0.02 * std::max(1.0, std::abs(va))) << key;
  }
  EXPECT_EQ(
      ident_command({"fit", "--trace", trace.string(), "--out", dir.string(), "--start-mm", "nan"}),
      2);
  std::filesystem::remove_all(dir);
}

TEST(IdentCli, UserErrorsAreReportedNotCrashes) {
  const auto dir = temp_dir("err");
  EXPECT_EQ(ident_command({"fit", "--trace", (dir / "missing.csv").string(), "--out", dir.string()}), 1);
  std::ofstream(dir / "bad.csv") << "time_s,x_cmd_mm,x_meas_mm\n0,0,0\n0.001,zz,0\n";
  EXPECT_EQ(ident_command({"fit", "--trace", (dir / "bad.csv").string(), "--out", dir.string()}), 1);
  // Rows missing from the middle of a trace: refused (fit and frf), nothing written.
  {
    std::ofstream gap(dir / "gap.csv");
    gap << "time_s,x_cmd_mm,x_meas_mm\n";
    for (int k = 0; k < 3000; ++k)
      if (k < 1500 || k >= 1520)
        gap << 0.001 * k << "," << std::sin(0.003 * k) << "," << std::sin(0.003 * k) << "\n";
  }
  EXPECT_EQ(ident_command({"fit", "--trace", (dir / "gap.csv").string(), "--out",
                           (dir / "gap_out").string()}),
            1);
  EXPECT_FALSE(std::filesystem::exists(dir / "gap_out" / "report.json"));
  EXPECT_EQ(ident_command({"frf", "--trace", (dir / "gap.csv").string(), "--out",
                           (dir / "gap_frf.csv").string()}),
            1);
  EXPECT_FALSE(std::filesystem::exists(dir / "gap_frf.csv"));
  EXPECT_EQ(ident_command(
                {"excite", "--axis", "x", "--duration", "1e9", "--out", (dir / "t.csv").string()}),
            2);
  EXPECT_FALSE(std::filesystem::exists(dir / "t.csv"));
  // An overlay that cannot be written is refused before the fit (the report is not written).
  {
    std::ofstream even(dir / "even.csv");
    even << "time_s,x_cmd_mm,x_meas_mm\n";
    for (int k = 0; k < 3000; ++k)
      even << 0.001 * k << "," << std::sin(0.003 * k) << "," << std::sin(0.003 * k) << "\n";
  }
  EXPECT_EQ(
      ident_command({"fit", "--trace", (dir / "even.csv").string(), "--out",
                     (dir / "ov_out").string(), "--overlay", (dir / "no" / "cal.yaml").string()}),
      1);
  EXPECT_FALSE(std::filesystem::exists(dir / "ov_out"));
  EXPECT_EQ(ident_command({"excite", "--axis", "x", "--effect", "wobble", "--out", (dir / "t.csv").string()}), 2);
  EXPECT_EQ(ident_command({"excite", "--axis", "x", "--effect", "backlash:depth=3", "--out", (dir / "t.csv").string()}), 2);
  EXPECT_EQ(ident_command({"frobnicate"}), 2);
  EXPECT_EQ(ident_command({"fit", "--trace", "t.csv", "--out", dir.string(), "--max-effects", "2.5"}), 2);
  EXPECT_EQ(ident_command({"fit", "--trace", "t.csv", "--out", dir.string(), "--max-effects", "-1"}), 2);
  for (const char* bad : {"0", "-1", "1e9", "nan", "heavy"})
    EXPECT_EQ(ident_command(
                  {"fit", "--trace", "t.csv", "--out", dir.string(), "--carriage-mass-kg", bad}),
              2)
        << bad;
  EXPECT_EQ(model_command({"frf", "--pos", "1,2", "--out", (dir / "f.csv").string()}), 2);
  std::filesystem::remove_all(dir);
}

TEST(ModelCli, FrfWritesThePredictedFrfContractAndTheFormSwitchMatters) {
  const auto dir = temp_dir("frf");
  const auto paper = dir / "paper.csv", vw = dir / "vw.csv";
  ASSERT_EQ(model_command({"frf", "--pos", "-80,0,30", "--out", paper.string()}), 0);
  ASSERT_EQ(model_command({"frf", "--pos", "-80,0,30", "--out", vw.string(), "--virtual-work"}), 0);
  auto a = model::read_frf_csv(paper.string());
  auto b = model::read_frf_csv(vw.string());
  ASSERT_TRUE(a.ok()) << a.error().to_string();
  ASSERT_TRUE(b.ok());
  ASSERT_EQ(a.value().freq_hz.size(), 247u);  // 2 .. 125 Hz in 0.5 Hz steps
  EXPECT_NEAR(a.value().freq_hz.front(), 2.0, 1e-12);
  EXPECT_NEAR(a.value().freq_hz.back(), 125.0, 1e-12);
  // Low frequency: position to position, G -> I.
  EXPECT_NEAR(std::abs(a.value().h.front()(0, 0)), 1.0, 0.05);
  // The two force transformations differ (m_e/9 vs m_e/3 per carriage): somewhere by > 10 %.
  double max_rel = 0.0;
  for (size_t k = 0; k < a.value().h.size(); ++k)
    max_rel = std::max(max_rel, std::abs(a.value().h[k](0, 0) - b.value().h[k](0, 0)) / std::abs(b.value().h[k](0, 0)));
  EXPECT_GT(max_rel, 0.1);
  const int rc = check_contract("frf", paper);
  if (rc >= 0) {
    EXPECT_EQ(rc, 0);
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace feedloop::cli
