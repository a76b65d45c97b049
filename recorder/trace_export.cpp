// build_trace / write_trace_csv (see trace_export.hpp).
#include "recorder/trace_export.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "recorder/log_reader.hpp"

namespace feedloop::recorder {
namespace {

// A joint's step stream in file order: runs and origins (position resets).
struct StepItem {
  int64_t clock = 0;  // run: start clock P; origin: its clock
  stepgen::StepRun run;
  bool origin = false;
  int64_t origin_steps = 0;
};

struct JointData {
  std::vector<StepItem> items;
  std::vector<std::pair<int64_t, int64_t>> encoder;  // (clock, counts)
  double first_s = 0.0, last_s = 0.0;
  bool has_data = false;
  void span(double a, double b) {
    if (!has_data) first_s = a, last_s = b;
    first_s = std::min(first_s, a);
    last_s = std::max(last_s, b);
    has_data = true;
  }
};

// Walks a joint's step stream forward in time: position (steps) of the last step at or before
// a clock, exactly as the MCU executes the runs (step_run.hpp).
class StepCursor {
 public:
  explicit StepCursor(const std::vector<StepItem>& items) : items_(items) {}
  int64_t position_at(double clock) {
    while (i_ < items_.size()) {
      const StepItem& it = items_[i_];
      if (it.origin) {
        if (static_cast<double>(it.clock) > clock) break;
        pos_ = it.origin_steps;
        ++i_;
        continue;
      }
      if (it.run.count == 0) { ++i_; continue; }
      // Whole run done by `clock`?
      if (k_ == 0 && static_cast<double>(stepgen::run_end_clock(it.clock, it.run)) <= clock) {
        pos_ += it.run.direction * static_cast<int64_t>(it.run.count);
        ++i_;
        continue;
      }
      // Step by step inside the run.
      while (k_ < it.run.count && static_cast<double>(stepgen::run_step_clock(it.clock, it.run, k_ + 1)) <= clock) {
        pos_ += it.run.direction;
        ++k_;
      }
      if (k_ < it.run.count) break;
      k_ = 0;
      ++i_;
    }
    return pos_;
  }

 private:
  const std::vector<StepItem>& items_;
  size_t i_ = 0;
  uint32_t k_ = 0;  // steps of items_[i_] already counted
  int64_t pos_ = 0;
};

// Encoder counts at a clock, linear between samples, held outside.
class EncoderCursor {
 public:
  explicit EncoderCursor(const std::vector<std::pair<int64_t, int64_t>>& s) : s_(s) {}
  double counts_at(double clock) {
    if (s_.empty()) return 0.0;
    while (i_ + 1 < s_.size() && static_cast<double>(s_[i_ + 1].first) <= clock) ++i_;
    if (clock <= static_cast<double>(s_[i_].first) || i_ + 1 >= s_.size()) return static_cast<double>(s_[i_].second);
    const double c0 = static_cast<double>(s_[i_].first), c1 = static_cast<double>(s_[i_ + 1].first);
    const double f = c1 > c0 ? (clock - c0) / (c1 - c0) : 0.0;
    return static_cast<double>(s_[i_].second) + f * static_cast<double>(s_[i_ + 1].second - s_[i_].second);
  }

 private:
  const std::vector<std::pair<int64_t, int64_t>>& s_;
  size_t i_ = 0;
};

}  // namespace

Result<TraceColumns> build_trace(const std::vector<std::string>& logs, const ExportOptions& options) {
  if (!(options.rate_hz > 0.0) || !std::isfinite(options.rate_hz))
    return Error{"sample rate must be a positive number of Hz", {}};
  if (options.rate_hz < kMinExportRateHz || options.rate_hz > kMaxExportRateHz) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "sample rate %.6g Hz: must be %g Hz to %g kHz (the encoders report at 1 kHz)",
                  options.rate_hz, kMinExportRateHz, kMaxExportRateHz * 1e-3);
    return Error{buf, {}};
  }
  if (logs.empty()) return Error{"no log given", {}};
  TraceColumns out;
  std::vector<JointInfo> joints;
  std::vector<JointData> data;
  for (const std::string& path : logs) {
    auto reader = LogReader::open(path);
    if (!reader) return reader.error();
    uint64_t servo_dropped = 0;  // a file's DropRecords are running totals since it was opened
    if (joints.empty()) {
      joints = reader->header().joints;
      data.resize(joints.size());
    } else if (reader->header().joints != joints) {
      return Error{"the joints in this log differ from those of " + logs.front(), {path, 0, 0}};
    }
    while (const DecodedRecord* d = reader->next()) {
      if (const auto* r = std::get_if<StepRunRecord>(&d->record)) {
        if (static_cast<size_t>(r->joint) >= joints.size() || r->run.count == 0) continue;
        const double hz = static_cast<double>(joints[static_cast<size_t>(r->joint)].clock_hz);
        JointData& jd = data[static_cast<size_t>(r->joint)];
        jd.items.push_back(StepItem{r->start_clock, r->run, false, 0});
        jd.span(static_cast<double>(stepgen::run_step_clock(r->start_clock, r->run, 1)) / hz,
                static_cast<double>(stepgen::run_end_clock(r->start_clock, r->run)) / hz);
      } else if (const auto* o = std::get_if<OriginRecord>(&d->record)) {
        if (static_cast<size_t>(o->joint) >= joints.size()) continue;
        data[static_cast<size_t>(o->joint)].items.push_back(StepItem{o->clock, {}, true, o->position_steps});
      } else if (const auto* e = std::get_if<EncoderRecord>(&d->record)) {
        if (static_cast<size_t>(e->joint) >= joints.size()) continue;
        const double hz = static_cast<double>(joints[static_cast<size_t>(e->joint)].clock_hz);
        JointData& jd = data[static_cast<size_t>(e->joint)];
        jd.encoder.emplace_back(e->clock, e->counts);
        jd.span(static_cast<double>(e->clock) / hz, static_cast<double>(e->clock) / hz);
      } else if (const auto* dr = std::get_if<DropRecord>(&d->record)) {
        if (dr->stream == Stream::servo) servo_dropped = std::max(servo_dropped, dr->dropped_total);
      }
    }
    out.servo_records_dropped += servo_dropped;
    if (reader->error())
      out.comments.push_back("warning: " + reader->error()->to_string() + "; data before it exported");
  }
  if (out.servo_records_dropped > 0)
    out.comments.push_back(
        "warning: the recorder dropped " + std::to_string(out.servo_records_dropped) +
        " servo records (its ring was full): step runs or encoder samples may be missing");
  for (size_t j = 0; j < joints.size(); ++j)
    if (data[j].has_data && joints[j].clock_hz <= 0)
      return Error{"joint " + joints[j].name + " has no MCU clock rate in the log header", {logs.front(), 0, 0}};

  double t_first = 0.0, t_last = 0.0;
  bool any = false;
  for (const JointData& jd : data) {
    if (!jd.has_data) continue;
    t_first = any ? std::min(t_first, jd.first_s) : jd.first_s;
    t_last = any ? std::max(t_last, jd.last_s) : jd.last_s;
    any = true;
  }
  if (!any) return Error{"the log has no step runs and no encoder samples: nothing to export", {logs.front(), 0, 0}};
  const auto rows = static_cast<size_t>(std::floor((t_last - t_first) * options.rate_hz + 1e-9)) + 1;
  if (rows < 2) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "the log's data spans less than one sample period at %.6g Hz",
                  options.rate_hz);
    return Error{buf, {logs.front(), 0, 0}};
  }
  // The columns are held in memory: a bound, with the way out, rather than an allocation failure.
  size_t columns = 1;
  for (const JointData& jd : data) columns += jd.has_data ? 2 : 0;
  const double bytes = static_cast<double>(rows) * static_cast<double>(columns) * sizeof(double);
  if (bytes > kMaxExportBytes) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "the export would hold %zu rows of %zu columns (%.1f GiB in memory, at most "
                  "%.0f): export fewer "
                  "logs or at a lower --rate-hz",
                  rows, columns, bytes / (1024.0 * 1024.0 * 1024.0),
                  kMaxExportBytes / (1024.0 * 1024.0 * 1024.0));
    return Error{buf, {logs.front(), 0, 0}};
  }

  out.t0_s = t_first;
  out.rate_hz = options.rate_hz;
  out.time_s.resize(rows);
  for (size_t k = 0; k < rows; ++k) out.time_s[k] = static_cast<double>(k) / options.rate_hz;
  for (size_t j = 0; j < joints.size(); ++j) {
    const JointData& jd = data[j];
    if (!jd.has_data) continue;
    const JointInfo& ji = joints[j];
    const double hz = static_cast<double>(ji.clock_hz);
    const double mm_per_step = ji.steps_per_mm > 0.0 ? 1.0 / ji.steps_per_mm : 0.0;
    const bool measured = !jd.encoder.empty() && ji.encoder_resolution_mm > 0.0;
    out.joints.push_back(ji.name);
    std::vector<double> cmd(rows), meas(rows);
    StepCursor steps(jd.items);
    EncoderCursor enc(jd.encoder);
    for (size_t k = 0; k < rows; ++k) {
      const double clock = (t_first + out.time_s[k]) * hz;
      cmd[k] = static_cast<double>(steps.position_at(clock)) * mm_per_step;
      meas[k] = measured ? enc.counts_at(clock) * ji.encoder_resolution_mm : cmd[k];
    }
    out.cmd_mm.push_back(std::move(cmd));
    out.meas_mm.push_back(std::move(meas));
    out.meas_span_s.emplace_back(
        measured ? static_cast<double>(jd.encoder.front().first) / hz - t_first : NAN,
        measured ? static_cast<double>(jd.encoder.back().first) / hz - t_first : NAN);
    if (!measured)
      out.comments.push_back("joint " + ji.name + ": no encoder samples, " + ji.name + "_meas_mm = " + ji.name + "_cmd_mm");
  }
  return out;
}

Status write_trace_csv(const TraceColumns& t, const std::string& csv_path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(csv_path.c_str(), "w"), &std::fclose);
  if (!f) return Error{"cannot write CSV", {csv_path, 0, 0}};
  std::FILE* o = f.get();
  std::fprintf(o, "# feedloop log export, trace CSV v1\n");
  std::fprintf(o, "# sample_rate_hz=%.9g\n", t.rate_hz);
  std::fprintf(o, "# t0_mcu_s=%.9f\n", t.t0_s);
  for (const std::string& c : t.comments) std::fprintf(o, "# %s\n", c.c_str());
  std::fprintf(o, "time_s");
  for (const std::string& j : t.joints) std::fprintf(o, ",%s_cmd_mm,%s_meas_mm", j.c_str(), j.c_str());
  std::fprintf(o, "\n");
  for (size_t k = 0; k < t.time_s.size(); ++k) {
    std::fprintf(o, "%.9f", t.time_s[k]);
    for (size_t j = 0; j < t.joints.size(); ++j) std::fprintf(o, ",%.7f,%.7f", t.cmd_mm[j][k], t.meas_mm[j][k]);
    std::fprintf(o, "\n");
  }
  const bool write_error = std::ferror(o) != 0;
  if (std::fclose(f.release()) != 0 || write_error) return Error{"error writing CSV (disk full?)", {csv_path, 0, 0}};
  return Status::Ok();
}

}  // namespace feedloop::recorder
