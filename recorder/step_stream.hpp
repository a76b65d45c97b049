// The commanded step stream of a recording, per joint, and the comparison a replay needs: are two
// step streams the same, step for step, and if not, where do they first differ.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

struct StepStreams {
  std::vector<JointInfo> joints;
  std::vector<std::vector<StepRunRecord>> runs;  // [joint], in order
};

// Reads the step runs of one print (its parts in order). A damaged tail is an Error: a comparison
// against a partial stream would be misleading.
Result<StepStreams> read_step_streams(const std::vector<std::string>& logs);

struct StepMismatch {
  int joint = 0;
  uint64_t step = 0;             // 0-based index of the first differing step of that joint
  int64_t clock_a = 0, clock_b = 0;
  int dir_a = 0, dir_b = 0;      // 0: that stream has no such step (it ended)
  std::string to_string(const std::vector<JointInfo>& joints) const;
};

// Compares the expanded steps (clock and direction of every step, joint by joint): two streams
// whose runs are split differently but produce the same steps are equal. nullopt: identical.
std::optional<StepMismatch> compare_step_streams(const StepStreams& a, const StepStreams& b);

}  // namespace feedloop::recorder
