// Replays a fuzz target's corpus through its libFuzzer entry point (LLVMFuzzerTestOneInput of
// fuzz/<target>.cpp, linked into this test): every seed and every regress_* reproducer of a past
// finding must run clean. The target traps on a broken invariant; the sanitizer build adds
// memory errors and undefined behaviour.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) __attribute__((weak));

namespace {

namespace fs = std::filesystem;

TEST(FuzzCorpusReplay, EveryFileRunsClean) {
  if (LLVMFuzzerInitialize != nullptr) LLVMFuzzerInitialize(nullptr, nullptr);
  const fs::path dir = fs::path(FEEDLOOP_SOURCE_DIR) / "fuzz" / "corpus" / FUZZ_CORPUS;
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 5u) << "corpus missing: " << dir;
  size_t regressions = 0;
  for (const fs::path& f : files) {
    std::ifstream in(f, std::ios::binary);
    const std::string data{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    SCOPED_TRACE(f.filename().string());
    EXPECT_EQ(LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(data.data()), data.size()), 0);
    regressions += f.filename().string().rfind("regress_", 0) == 0;
  }
  std::printf("%s: %zu files replayed, %zu of them reproducers of past findings\n", FUZZ_CORPUS,
              files.size(), regressions);
}

}  // namespace
