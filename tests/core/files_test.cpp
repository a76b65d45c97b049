// core/bounded_file and core/atomic_file: the whole-file read with a bound and the atomic write.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/atomic_file.hpp"
#include "core/bounded_file.hpp"

namespace feedloop {
namespace {

namespace fs = std::filesystem;

class FilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("feedloop-files-test-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string read(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  fs::path dir_;
};

TEST_F(FilesTest, BoundedReadSaysWhichWayItFailed) {
  const fs::path f = dir_ / "a.txt";
  std::ofstream(f) << std::string(1000, 'x');
  BoundedFile ok = read_file_bounded(f.string(), 1000);
  EXPECT_EQ(ok.status, BoundedFile::Status::kOk);
  EXPECT_EQ(ok.text.size(), 1000u);
  BoundedFile big = read_file_bounded(f.string(), 999);
  EXPECT_EQ(big.status, BoundedFile::Status::kTooLarge);
  EXPECT_TRUE(big.text.empty());
  EXPECT_EQ(read_file_bounded("/dev/zero", 1 << 20).status, BoundedFile::Status::kTooLarge);
  BoundedFile missing = read_file_bounded((dir_ / "none").string(), 10);
  EXPECT_EQ(missing.status, BoundedFile::Status::kCannotOpen);
  EXPECT_EQ(missing.errno_value, ENOENT);
  BoundedFile directory = read_file_bounded(dir_.string(), 10);
  EXPECT_EQ(directory.status, BoundedFile::Status::kReadError);
  EXPECT_EQ(directory.errno_value, EISDIR);
}

TEST_F(FilesTest, AtomicWriteReplacesWholeOrLeavesTheOldFile) {
  const fs::path f = dir_ / "cal.yaml";
  ASSERT_TRUE(write_file_atomically(f.string(), "first\n", 0640));
  EXPECT_EQ(read(f), "first\n");
  struct stat st {};
  ASSERT_EQ(::stat(f.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  ASSERT_TRUE(write_file_atomically(f.string(), std::string(100000, 'y')));
  EXPECT_EQ(read(f), std::string(100000, 'y'));
  // A path whose rename fails (a directory is in the way): the error names it, and no temporary
  // is left beside it.
  fs::create_directories(dir_ / "taken" / "inside");
  Status s = write_file_atomically((dir_ / "taken").string(), "x");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("cannot rename over " + (dir_ / "taken").string()), std::string::npos)
      << s.error().message;
  size_t entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++entries;
  EXPECT_EQ(entries, 2u);  // cal.yaml and taken/
  Status nodir = write_file_atomically((dir_ / "no" / "x.yaml").string(), "x");
  ASSERT_FALSE(nodir);
  EXPECT_NE(nodir.error().message.find("cannot create a file in " + (dir_ / "no").string()), std::string::npos)
      << nodir.error().message;
  EXPECT_EQ(read(f), std::string(100000, 'y'));
}

}  // namespace
}  // namespace feedloop
