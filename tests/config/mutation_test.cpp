// Seeded random edits of the example configs: loading never throws or crashes, every problem has
// a line and column inside the text, and a config either loads fully or reports problems.
#include <gtest/gtest.h>

#include <cstdio>  // printf
#include <random>

#include "config/config.hpp"
#include "config_fixture.hpp"

namespace feedloop::config {
namespace {

std::string mutate(std::string text, std::mt19937& rng) {
  static const std::string alphabet = "abcxyz_:-[]{},#'\"\t\n 0123456789.e";
  const int edits = 1 + static_cast<int>(rng() % 3);
  for (int i = 0; i < edits && !text.empty(); ++i) {
    const std::size_t at = rng() % text.size();
    switch (rng() % 4) {
      case 0: text.erase(at, 1 + rng() % 8); break;                           // delete
      case 1: text.insert(at, 1, alphabet[rng() % alphabet.size()]); break;   // insert
      case 2: text[at] = alphabet[rng() % alphabet.size()]; break;            // replace
      default: {                                                              // duplicate a line
        const std::size_t begin = text.rfind('\n', at) == std::string::npos ? 0 : text.rfind('\n', at) + 1;
        const std::size_t end = text.find('\n', at);
        if (end != std::string::npos) text.insert(begin, text.substr(begin, end - begin + 1));
      }
    }
  }
  return text;
}

TEST(ConfigMutations, EveryProblemIsLocatedAndNothingThrows) {
  std::mt19937 rng(20261122);
  int rejected = 0, accepted = 0;
  for (const char* name : {"cartesian_sim.yaml", "delta_sim.yaml", "cartesian_usb.yaml"}) {
    const std::string original = testing::read_text(testing::example_path(name));
    ASSERT_FALSE(original.empty()) << name;
    int lines = 1;
    for (char c : original) lines += c == '\n';
    for (int i = 0; i < 60; ++i) {
      const std::string text = mutate(original, rng);
      std::vector<Error> errors;
      ASSERT_NO_THROW(errors = check_config_text(text, "m.yaml"));
      const Result<MachineConfig> r = load_config_text(text, "m.yaml");
      EXPECT_EQ(r.ok(), errors.empty());
      if (errors.empty()) {
        ++accepted;
        continue;
      }
      ++rejected;
      for (const Error& e : errors) {
        EXPECT_GE(e.where.line, 1) << e.to_string() << "\n--- text ---\n" << text;
        EXPECT_LE(e.where.line, lines + 20) << e.to_string();
        EXPECT_GE(e.where.column, 1) << e.to_string();
        EXPECT_EQ(e.where.source, "m.yaml");
      }
    }
  }
  std::printf("mutated configs: %d rejected, %d accepted\n", rejected, accepted);
  // The edits must exercise both outcomes (comments and whitespace edits keep a file valid).
  EXPECT_GT(rejected, 40) << accepted;
  EXPECT_GT(accepted, 2) << rejected;
}

}  // namespace
}  // namespace feedloop::config
