// A short, deterministic fuzz run inside the normal test suite: the libFuzzer entry point of
// fuzz/fuzz_gcode_parser.cpp on every seed in fuzz/corpus/gcode, then on seeded random mutations
// of them (byte flips, G-code token splices, truncation, duplication) and a few megabyte inputs.
// Under the sanitizer build this catches memory errors; the target traps on broken invariants.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

namespace fs = std::filesystem;

int run(const std::string& s) {
  return LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(s.data()), s.size());
}

std::vector<std::string> seeds() {
  std::vector<std::string> out;
  const fs::path dir = fs::path(FEEDLOOP_SOURCE_DIR) / "fuzz" / "corpus" / "gcode";
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::ifstream in(e.path(), std::ios::binary);
    out.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(FuzzSmoke, SeedsAndMutationsRunClean) {
  const std::vector<std::string> corpus = seeds();
  ASSERT_GE(corpus.size(), 24u) << "seed corpus missing";
  for (const auto& s : corpus) EXPECT_EQ(run(s), 0);

  static const char* kTokens[] = {"G1", "X", "E", "e-", "e+", "N", "*", ";", "(", ")", "M110",
                                  "M112", "M117 ", "\n", "\r", "-", ".", "9999999999999999999",
                                  "1e+999", "\xff", "\x01"};
  std::mt19937 rng(12345);
  int runs = 0;
  for (int iter = 0; iter < 4000; ++iter) {
    std::string s = corpus[rng() % corpus.size()];
    const int edits = 1 + static_cast<int>(rng() % 8);
    for (int k = 0; k < edits; ++k) {
      const size_t pos = s.empty() ? 0 : rng() % (s.size() + 1);
      switch (rng() % 5) {
        case 0:
          if (!s.empty()) s[std::min(pos, s.size() - 1)] ^= static_cast<char>(1u << (rng() % 8));
          break;
        case 1: s.insert(pos, kTokens[rng() % std::size(kTokens)]); break;
        case 2: s.resize(pos); break;
        case 3: s.insert(pos, s.substr(pos, rng() % 64)); break;
        default: s.insert(pos, 1, static_cast<char>(rng() % 256)); break;
      }
    }
    EXPECT_EQ(run(s), 0);
    ++runs;
  }
  // Megabyte lines of different kinds.
  EXPECT_EQ(run(std::string(3 << 20, 'X')), 0);
  EXPECT_EQ(run("G1 X" + std::string(2 << 20, '7') + "\nG1 X1\n"), 0);
  EXPECT_EQ(run("M117 " + std::string(1 << 20, '*') + "\n"), 0);
  EXPECT_EQ(runs, 4000);
}

}  // namespace
