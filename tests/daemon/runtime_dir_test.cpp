// The channels' paths: world-writable runtime directories without the sticky bit and paths
// outside the runtime directory are refused; wide modes and relative paths are warned about.
#include "daemon/runtime_dir.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>

#include "tests/daemon/daemon_fixture.hpp"

namespace feedloop::daemon {
namespace {

namespace fs = std::filesystem;

class RuntimeDir : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::make_temp_dir("rtdir"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string dir_;
};

TEST_F(RuntimeDir, AWorldWritableDirectoryWithoutTheStickyBitIsRefused) {
  std::vector<std::string> w;
  const std::string run = dir_ + "/run";
  fs::create_directories(run);
  ASSERT_EQ(::chmod(run.c_str(), 0777), 0);
  Status s = check_channel_path("sockets.unix_socket", run + "/feedloop.sock", run, 0660, &w);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("writable by every user (mode 0777) and has no sticky bit"), std::string::npos)
      << s.error().message;
  // With the sticky bit (like /tmp) it is accepted.
  ASSERT_EQ(::chmod(run.c_str(), 01777), 0);
  EXPECT_TRUE(check_channel_path("sockets.unix_socket", run + "/feedloop.sock", run, 0660, &w).ok());
  // A parent that anyone may write is refused as well: the runtime directory could be replaced.
  ASSERT_EQ(::chmod(run.c_str(), 0700), 0);
  ASSERT_EQ(::chmod(dir_.c_str(), 0777), 0);
  EXPECT_FALSE(check_channel_path("sockets.unix_socket", run + "/feedloop.sock", run, 0660, &w).ok());
  ASSERT_EQ(::chmod(dir_.c_str(), 0700), 0);
  EXPECT_TRUE(w.empty());
}

TEST_F(RuntimeDir, APathOutsideTheRuntimeDirectoryIsRefused) {
  std::vector<std::string> w;
  fs::create_directories(dir_ + "/run");
  fs::create_directories(dir_ + "/other");
  Status s = check_channel_path("sockets.api_socket", dir_ + "/other/api.sock", dir_ + "/run", 0660, &w);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("outside the runtime directory"), std::string::npos) << s.error().message;
  // A sibling whose name starts like the directory is outside too.
  EXPECT_FALSE(check_channel_path("sockets.api_socket", dir_ + "/run2/api.sock", dir_ + "/run", 0660, &w).ok());
  EXPECT_FALSE(check_channel_path("sockets.api_socket", dir_ + "/run/../other/api.sock", dir_ + "/run", 0660, &w).ok());
  EXPECT_TRUE(check_channel_path("sockets.api_socket", dir_ + "/run/sub/api.sock", dir_ + "/run", 0660, &w).ok());
}

TEST_F(RuntimeDir, WideModesAndRelativePathsAreWarnedAbout) {
  std::vector<std::string> w;
  EXPECT_TRUE(check_channel_path("sockets.unix_socket", dir_ + "/a.sock", dir_, 0777, &w).ok());
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("mode 0777 is wider than 0660"), std::string::npos) << w[0];
  w.clear();
  EXPECT_TRUE(check_channel_path("sockets.unix_socket", dir_ + "/a.sock", dir_, 0660, &w).ok());
  EXPECT_TRUE(check_channel_path("sockets.unix_socket", dir_ + "/a.sock", dir_, 0600, &w).ok());
  EXPECT_TRUE(w.empty());
  const fs::path cwd = fs::current_path();
  fs::current_path(dir_);
  Status s = check_channel_path("sockets.unix_socket", "feedloop.sock", dir_, 0660, &w);
  fs::current_path(cwd);
  EXPECT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("is relative"), std::string::npos) << w[0];
}

}  // namespace
}  // namespace feedloop::daemon
