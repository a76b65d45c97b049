// The step-time error bound on the whole corpus: every step of every file of ../shared/gcode is
// decoded from the QUEUE_STEPS bodies and compared with its exact time from the joint segments
// (step_check.hpp). Cartesian files with the embedded default config, benchy_delta with
// config/examples/delta_sim.yaml. Prints the max error and bytes per step of each file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "tests/engine/batch_support.hpp"

namespace feedloop::engine::testing {
namespace {

namespace fs = std::filesystem;

TEST(StepErrorCorpus, EveryStepOfEveryFileWithinTheBound) {
  const fs::path dir = fs::path(FEEDLOOP_SHARED_DIR) / "gcode";
  if (!fs::is_directory(dir)) GTEST_SKIP() << "G-code corpus absent: " << dir.string();
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".gcode") files.push_back(e.path());
  // FEEDLOOP_CORPUS_FILTER=substring runs only the matching files (debugging).
  if (const char* only = std::getenv("FEEDLOOP_CORPUS_FILTER"))
    std::erase_if(files, [only](const fs::path& p) { return p.filename().string().find(only) == std::string::npos; });
  std::sort(files.begin(), files.end());
  ASSERT_FALSE(files.empty());
  const config::MachineConfig delta = delta_config();
  ASSERT_EQ(delta.kinematics, config::Kinematics::delta);
  for (const fs::path& f : files) {
    const bool is_delta = f.stem().string().find("delta") != std::string::npos;
    const config::MachineConfig& cfg = is_delta ? delta : config::default_config();
    auto r = run_checked(f.string(), cfg);
    ASSERT_TRUE(r.ok()) << f << ": " << r.error().to_string();
    const BatchSummary& s = r->summary;
    std::printf("%-40s %10llu steps  max error %.6f us (bound %.1f)  %.3f B/step  check failures %llu\n",
                f.filename().string().c_str(), static_cast<unsigned long long>(s.total_steps), r->max_error_us,
                cfg.stepgen.max_step_error_us, s.wire_bytes_per_step,
                static_cast<unsigned long long>(s.check_failures));
    EXPECT_GT(s.total_steps, 100000u) << f;
    EXPECT_EQ(s.check_failures, 0u) << f;
    EXPECT_EQ(r->not_found, 0u) << f;
    // + 1e-5 us: the resolution of absolute print times in double (0.45 ps ulp at 3600 s; an
    // error is the difference of two such times, measured 5.0000008 us at most on the corpus).
    EXPECT_LE(r->max_error_us, cfg.stepgen.max_step_error_us + 1e-5) << f;
    EXPECT_LE(s.wire_bytes_per_step, 1.0) << f;  // the target at the 5 us bound
    for (int j = 0; j < kJoints; ++j)
      EXPECT_EQ(r->joints[static_cast<size_t>(j)].steps, s.joints[static_cast<size_t>(j)].steps) << f << " joint " << j;
  }
}

}  // namespace
}  // namespace feedloop::engine::testing
