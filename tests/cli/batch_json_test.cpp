// `feedloop batch --json`: the summary file is written for every drive (steppers and the
// DC-servo machine of the maneuvering paper), with figures taken from the run, and a file that
// cannot be written is an error, not a silent success.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/daemon/subprocess.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

class BatchJson : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("feedloop-batch-json-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    gcode_ = (dir_ / "square.gcode").string();
    std::ofstream(gcode_) << "G21\nG90\nG28\nG1 X10 Y10 F3000\nG1 X30 Y10\nG1 X30 Y30\nG1 X10 Y30\nG1 X10 Y10\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Runs `feedloop batch` and returns its exit code.
  int batch(const std::vector<std::string>& extra, std::string* out) {
    std::vector<std::string> argv{FEEDLOOP_PATH, "batch", gcode_, "--quiet"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    feedloop::testing::Subprocess p(argv, {}, (dir_ / "batch.log").string());
    const int rc = p.wait(300);
    *out = p.output();
    return rc;
  }
  fs::path dir_;
  std::string gcode_;
};

TEST_F(BatchJson, SteppersWriteTheStepFigures) {
  const std::string out_json = (dir_ / "steppers.json").string();
  std::string out;
  ASSERT_EQ(batch({"--json", out_json}, &out), 0) << out;
  const json j = json::parse(std::ifstream(out_json));
  EXPECT_EQ(j["rejected"], 0);
  EXPECT_EQ(j["moves"], 5);
  EXPECT_GT(j["total_steps"].get<uint64_t>(), 1000u);  // 80 mm of XY travel at 80+ steps/mm
  EXPECT_GT(j["wire_bytes_per_step"].get<double>(), 0.0);
}

TEST_F(BatchJson, DcServoWritesThePathFollowingFigures) {
  const std::string out_json = (dir_ / "dc_servo.json").string();
  std::string out;
  ASSERT_EQ(batch({"--config", FEEDLOOP_SOURCE_DIR "/config/examples/dc_servo_sim.yaml", "--json", out_json}, &out), 0)
      << out;
  const json j = json::parse(std::ifstream(out_json));
  EXPECT_EQ(j["drive"], "dc_servo");
  EXPECT_EQ(j["rejected"], 0);
  EXPECT_EQ(j["moves"], 5);
  // The path: 14.1 mm from the origin, then the 20 mm square (80 mm).
  EXPECT_NEAR(j["path_mm"].get<double>(), 80.0 + std::hypot(10.0, 10.0), 1.0);
  EXPECT_GT(j["max_cross_track_mm"].get<double>(), 0.0);
  EXPECT_LT(j["max_cross_track_mm"].get<double>(), 1.0);
  EXPECT_NEAR(j["end_mm"][0].get<double>(), 10.0, 0.05);
  EXPECT_NEAR(j["end_mm"][1].get<double>(), 10.0, 0.05);
  EXPECT_FALSE(j["faulted"].get<bool>());
}

// --threads auto (the default) takes one or two; 1 and 2 are what they say; the output is the same.
TEST_F(BatchJson, ThreadsAreReportedAndDoNotChangeTheOutput) {
  json runs[3];
  const char* settings[] = {"1", "2", "auto"};
  for (int i = 0; i < 3; ++i) {
    const std::string out_json = (dir_ / ("threads" + std::to_string(i) + ".json")).string();
    std::string out;
    ASSERT_EQ(batch({"--threads", settings[i], "--json", out_json}, &out), 0) << out;
    runs[i] = json::parse(std::ifstream(out_json));
  }
  EXPECT_EQ(runs[0]["threads"], 1);
  EXPECT_EQ(runs[1]["threads"], 2);
  const int chosen = runs[2]["threads"].get<int>();
  EXPECT_TRUE(chosen == 1 || chosen == 2) << chosen;
  for (int i = 1; i < 3; ++i) {
    EXPECT_EQ(runs[i]["total_steps"], runs[0]["total_steps"]);
    EXPECT_EQ(runs[i]["wire_bytes"], runs[0]["wire_bytes"]);
  }
  std::string out;
  EXPECT_EQ(batch({"--threads", "3"}, &out), 2);
  EXPECT_NE(out.find("--threads must be auto, 1 or 2, not '3'"), std::string::npos) << out;
}

TEST_F(BatchJson, AnUnwritableFileIsAnError) {
  std::string out;
  EXPECT_EQ(batch({"--json", (dir_ / "no-such-dir" / "x.json").string()}, &out), 1);
  EXPECT_NE(out.find("cannot write"), std::string::npos) << out;
}

}  // namespace
