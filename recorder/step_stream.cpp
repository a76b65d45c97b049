// read_step_streams / compare_step_streams (see step_stream.hpp).
#include "recorder/step_stream.hpp"

#include <algorithm>

#include "drivers/stepgen/step_run.hpp"  // run_is_valid
#include "recorder/log_reader.hpp"

namespace feedloop::recorder {
namespace {

// Walks a joint's runs step by step.
class StepWalker {
 public:
  explicit StepWalker(const std::vector<StepRunRecord>& runs) : runs_(runs) { skip_empty(); }
  bool done() const { return i_ >= runs_.size(); }
  int64_t clock() const { return stepgen::run_step_clock(runs_[i_].start_clock, runs_[i_].run, k_ + 1); }
  int dir() const { return runs_[i_].run.direction; }
  void next() {
    if (++k_ >= runs_[i_].run.count) {
      k_ = 0;
      ++i_;
      skip_empty();
    }
  }
  // Both walkers at the start of identical runs: skip the whole run at once.
  bool same_run_as(const StepWalker& o) const {
    if (k_ != 0 || o.k_ != 0 || done() || o.done()) return false;
    const StepRunRecord& a = runs_[i_];
    const StepRunRecord& b = o.runs_[o.i_];
    return a.start_clock == b.start_clock && a.run.interval_ticks == b.run.interval_ticks &&
           a.run.add_ticks == b.run.add_ticks && a.run.count == b.run.count && a.run.direction == b.run.direction;
  }
  uint32_t run_count() const { return runs_[i_].run.count; }
  void skip_run() {
    ++i_;
    k_ = 0;
    skip_empty();
  }

 private:
  void skip_empty() {
    while (i_ < runs_.size() && runs_[i_].run.count == 0) ++i_;
  }
  const std::vector<StepRunRecord>& runs_;
  size_t i_ = 0;
  uint32_t k_ = 0;
};

}  // namespace

Result<StepStreams> read_step_streams(const std::vector<std::string>& logs) {
  StepStreams s;
  for (const std::string& path : logs) {
    auto r = LogReader::open(path);
    if (!r) return r.error();
    if (s.joints.empty()) {
      s.joints = r->header().joints;
      s.runs.resize(s.joints.size());
    }
    while (const DecodedRecord* d = r->next()) {
      const auto* run = std::get_if<StepRunRecord>(&d->record);
      if (!run || static_cast<size_t>(run->joint) >= s.runs.size()) continue;
      // Expanding such a run step by step would overflow the clock arithmetic: no comparison.
      if (run->run.count > 0 && !stepgen::run_is_valid(run->start_clock, run->run))
        return Error{"step run at byte offset " + std::to_string(d->offset) +
                         " breaks the step law (an interval below 1 tick, or clocks beyond 2^63)",
                     {path, 0, 0}};
      s.runs[static_cast<size_t>(run->joint)].push_back(*run);
    }
    if (r->error()) return *r->error();
  }
  return s;
}

std::optional<StepMismatch> compare_step_streams(const StepStreams& a, const StepStreams& b) {
  const size_t joints = std::max(a.runs.size(), b.runs.size());
  static const std::vector<StepRunRecord> kNone;
  for (size_t j = 0; j < joints; ++j) {
    StepWalker wa(j < a.runs.size() ? a.runs[j] : kNone);
    StepWalker wb(j < b.runs.size() ? b.runs[j] : kNone);
    uint64_t step = 0;
    while (!wa.done() || !wb.done()) {
      if (wa.same_run_as(wb)) {
        step += wa.run_count();
        wa.skip_run();
        wb.skip_run();
        continue;
      }
      StepMismatch m;
      m.joint = static_cast<int>(j);
      m.step = step;
      if (!wa.done()) m.clock_a = wa.clock(), m.dir_a = wa.dir();
      if (!wb.done()) m.clock_b = wb.clock(), m.dir_b = wb.dir();
      if (wa.done() || wb.done() || m.clock_a != m.clock_b || m.dir_a != m.dir_b) return m;
      wa.next();
      wb.next();
      ++step;
    }
  }
  return std::nullopt;
}

std::string StepMismatch::to_string(const std::vector<JointInfo>& joints) const {
  const std::string name = static_cast<size_t>(joint) < joints.size() ? joints[static_cast<size_t>(joint)].name
                                                                      : std::to_string(joint);
  auto side = [](int dir, int64_t clock) {
    return dir == 0 ? std::string("no step (stream ended)")
                    : std::string(dir > 0 ? "+" : "-") + " at clock " + std::to_string(clock);
  };
  return "joint " + name + ", step " + std::to_string(step) + ": " + side(dir_a, clock_a) + " vs " + side(dir_b, clock_b);
}

}  // namespace feedloop::recorder
