// Inputs that are no input of the kind asked for (a path that never ends, a line without an end,
// a rate that would need terabytes): the `feedloop` tool ends each with a message naming it and a
// status, in bounded memory, where it used to read until memory ran out or abort.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/daemon/subprocess.hpp"

namespace fs = std::filesystem;

namespace {

class BoundedInput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("feedloop-bounded-input-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Runs `feedloop ARGS...`; returns its exit status and its output (stdout and stderr).
  int feedloop(const std::vector<std::string>& args, std::string* out) {
    std::vector<std::string> argv{FEEDLOOP_PATH};
    argv.insert(argv.end(), args.begin(), args.end());
    feedloop::testing::Subprocess p(argv, {}, (dir_ / "out.log").string());
    const int rc = p.wait(120);
    *out = p.output();
    return rc;
  }
  fs::path dir_;
};

TEST_F(BoundedInput, ARecordOfAFileWithALineWithoutAnEndIsRefused) {
  const std::string gcode = (dir_ / "long.gcode").string();
  std::ofstream(gcode) << "G28\n;" << std::string(300000, 'x') << "\nG1 X5 F3000\n";
  std::string out;
  EXPECT_EQ(feedloop({"record", gcode, "--dir", (dir_ / "rec").string()}, &out), 2);
  EXPECT_NE(out.find("long.gcode:2: line longer than 262144 bytes"), std::string::npos) << out;
}

TEST_F(BoundedInput, ConfigAndTraceFilesThatNeverEndAreRefused) {
  std::string out;
  EXPECT_EQ(feedloop({"batch", (dir_ / "x.gcode").string(), "--config", "/dev/zero"}, &out), 1);
  EXPECT_NE(out.find("/dev/zero: config file is larger than 16 MiB"), std::string::npos) << out;
  EXPECT_EQ(feedloop({"ident", "fit", "--trace", "/dev/zero", "--out", (dir_ / "fit").string()}, &out), 1);
  EXPECT_NE(out.find("/dev/zero: trace file is larger than 256 MiB"), std::string::npos) << out;
}

TEST_F(BoundedInput, AnExportRateBeyondTheEncodersIsRefused) {
  const std::string gcode = (dir_ / "square.gcode").string();
  std::ofstream(gcode) << "G28\nG1 X10 Y10 F3000\nG1 X20 F3000\n";
  std::string out;
  ASSERT_EQ(feedloop({"record", gcode, "--dir", (dir_ / "rec").string()}, &out), 0) << out;
  std::string log;
  for (const auto& e : fs::directory_iterator(dir_ / "rec"))
    if (e.path().extension() == ".flrec") log = e.path().string();
  ASSERT_FALSE(log.empty());
  const std::string csv = (dir_ / "t.csv").string();
  EXPECT_EQ(feedloop({"log", "export", log, "--csv", csv, "--rate-hz", "1e12"}, &out), 1);  // aborted before
  EXPECT_NE(out.find("sample rate 1e+12 Hz: must be 1 Hz to 100 kHz"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(csv));
  EXPECT_EQ(feedloop({"log", "export", log, "--csv", csv, "--rate-hz", "2000"}, &out), 0) << out;
  EXPECT_TRUE(fs::exists(csv));
}

}  // namespace

// A directory opens like a file and reads as nothing: it was a batch of 0 lines, exit 0. A pipe
// cannot seek: batch read 0 of its lines (the size probe left the stream failed), exit 0.
TEST_F(BoundedInput, ADirectoryIsRefusedAndAPipeIsReadToItsEnd) {
  std::string out;
  EXPECT_EQ(feedloop({"batch", dir_.string()}, &out), 1);
  EXPECT_NE(out.find("cannot read G-code file: Is a directory"), std::string::npos) << out;
  EXPECT_EQ(feedloop({"print", dir_.string()}, &out), 1);
  EXPECT_NE(out.find("is a directory, not a G-code file"), std::string::npos) << out;

  const std::string fifo = (dir_ / "in.fifo").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::thread writer([&] {
    const int fd = ::open(fifo.c_str(), O_WRONLY);
    if (fd < 0) return;
    const std::string text = "G28\nG1 X10 Y10 F3000\nG1 X20 F3000\n";
    EXPECT_EQ(::write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
    ::close(fd);
  });
  const int rc = feedloop({"batch", fifo}, &out);
  // Releases the writer if feedloop never opened the pipe.
  const int unblock = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  writer.join();
  if (unblock >= 0) ::close(unblock);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("lines             3 (3 commands, 0 rejected"), std::string::npos) << out;
}

// The overlay a fit merges into was read whole with no bound, and as empty when unreadable: an
// endless device was read until the kernel killed the tool, and a directory (or a file without
// read permission) was taken for no overlay, so the other axes in it would have been written
// over. Both are refused before the fit.
TEST_F(BoundedInput, AnOverlayThatCannotBeReadWholeIsRefusedBeforeTheFit) {
  const std::string trace = (dir_ / "t.csv").string();
  std::string out;
  ASSERT_EQ(feedloop({"ident", "excite", "--axis", "x", "--out", trace, "--duration", "5"}, &out),
            0)
      << out;
  EXPECT_EQ(feedloop({"ident", "fit", "--trace", trace, "--out", (dir_ / "f1").string(),
                      "--no-plots", "--overlay", "/dev/zero"},
                     &out),
            1);
  EXPECT_NE(out.find("--overlay /dev/zero: larger than 16 MiB"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir_ / "f1" / "report.json"));
  EXPECT_EQ(feedloop({"ident", "fit", "--trace", trace, "--out", (dir_ / "f2").string(),
                      "--no-plots", "--overlay", dir_.string()},
                     &out),
            1);
  EXPECT_NE(out.find("cannot read: Is a directory"), std::string::npos) << out;
  // A new overlay (no file yet) is written.
  const std::string fresh = (dir_ / "cal.yaml").string();
  ASSERT_EQ(feedloop({"ident", "fit", "--trace", trace, "--out", (dir_ / "f3").string(),
                      "--no-plots", "--overlay", fresh},
                     &out),
            0)
      << out;
  EXPECT_TRUE(fs::exists(fresh));
}
