// Flight recorder figures: cost of a record_*() call on the real-time side, drain + encode
// throughput of the recorder thread, bytes per record on disk for realistic streams, and read-back
// speed. Usage: bench_recorder [--json FILE] [--moves N]
#include <time.h>  // clock_gettime

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "recorder/log_reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder_test_util.hpp"

using namespace feedloop;
using namespace feedloop::recorder;

namespace {

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct Row {
  std::string stream;
  uint64_t records = 0;
  double record_ns = 0.0;   // per record_*() call (producer thread CPU)
  double encode_ns = 0.0;   // per record: drain + encode + write (recorder CPU)
  double bytes_per_record = 0.0;
  double read_ns = 0.0;     // per record, LogReader
};

Row measure(const std::string& name, int moves, int kind) {
  testing::ScratchDir dir("bench");
  auto opt = testing::test_options(dir.str());
  opt.servo_ring_bytes = 64u << 20;
  opt.planner_ring_bytes = 64u << 20;
  auto rec = Recorder::create(opt);
  if (!rec.ok()) { std::fprintf(stderr, "%s\n", rec.error().to_string().c_str()); std::exit(1); }
  Recorder& r = **rec;
  (void)r.start_print(name);
  Row row;
  row.stream = name;
  double t0 = 0.0, t1 = 0.0;
  if (kind == 0) {  // compressed step runs of trapezoid moves at 72 MHz, 80 steps/mm
    const auto runs = testing::trapezoid_runs(moves, 80.0, 72e6);
    t0 = thread_cpu_s();
    for (const auto& it : runs) r.writer(Stream::servo).step_run(0, it.start_clock, it.run);
    t1 = thread_cpu_s();
    row.records = runs.size();
  } else if (kind == 1) {  // encoder samples at 1 kHz, 0.49 um counts, moving carriage
    const uint64_t n = static_cast<uint64_t>(moves) * 100;
    std::vector<int64_t> counts(n);
    for (uint64_t i = 0; i < n; ++i) counts[i] = static_cast<int64_t>((50.0 + 40.0 * std::sin(0.0025 * static_cast<double>(i))) / 0.00049);
    t0 = thread_cpu_s();
    for (uint64_t i = 0; i < n; ++i) r.writer(Stream::servo).encoder_sample(0, static_cast<int64_t>(i) * 72000 + static_cast<int64_t>(i % 3), counts[i]);
    t1 = thread_cpu_s();
    row.records = n;
  } else {  // planned moves of a polyline with extrusion
    const uint64_t n = static_cast<uint64_t>(moves) * 10;
    planner::PlannedMove m;
    std::vector<planner::PlannedMove> ms(n);
    for (uint64_t i = 0; i < n; ++i) {
      m.index = i;
      m.line = static_cast<int>(100 + i);
      m.start_time_s += m.duration_s;
      m.duration_s = 0.01 + 0.001 * static_cast<double>(i % 7);
      m.start_mm = m.end_mm;
      const double a = 0.1 * static_cast<double>(i);
      m.end_mm = {100.0 + 20.0 * std::cos(a), 100.0 + 20.0 * std::sin(a), 0.2, m.end_mm[3] + 0.0331};
      m.v_entry_mm_s = m.v_exit_mm_s;
      m.v_cruise_mm_s = 60.0;
      m.v_exit_mm_s = 20.0 + static_cast<double>(i % 3);
      m.accel_mm_s2 = 3000.0;
      ms[i] = m;
    }
    t0 = thread_cpu_s();
    for (const auto& mv : ms) r.writer(Stream::planner).move(mv);
    t1 = thread_cpu_s();
    row.records = n;
  }
  row.record_ns = 1e9 * (t1 - t0) / static_cast<double>(row.records);
  const double e0 = thread_cpu_s();
  (void)r.end_print();
  const double e1 = thread_cpu_s();
  row.encode_ns = 1e9 * (e1 - e0) / static_cast<double>(row.records);
  const RecorderStats st = r.stats();
  if (st.dropped[1] || st.dropped[2]) std::fprintf(stderr, "warning: %s dropped records\n", name.c_str());

  const auto logs = dir.logs();
  auto reader = LogReader::open(logs.at(0));
  uint64_t bytes = 0, n = 0;
  const double r0 = thread_cpu_s();
  while (const DecodedRecord* d = reader->next())
    if (!std::holds_alternative<TimeSyncRecord>(d->record)) bytes += d->size, ++n;
  const double r1 = thread_cpu_s();
  row.read_ns = 1e9 * (r1 - r0) / static_cast<double>(row.records);
  row.bytes_per_record = static_cast<double>(bytes) / static_cast<double>(n);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  std::string json;
  int moves = 2000;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
    else if (!std::strcmp(argv[i], "--moves") && i + 1 < argc) moves = std::atoi(argv[++i]);
    else { std::fprintf(stderr, "usage: %s [--json FILE] [--moves N]\n", argv[0]); return 2; }
  }
  std::vector<Row> rows = {measure("step_run", moves, 0), measure("encoder", moves, 1), measure("move", moves, 2)};
  std::printf("%-10s %10s %10s %10s %8s %10s\n", "record", "records", "record_ns", "encode_ns", "B/rec", "read_ns");
  for (const Row& r : rows)
    std::printf("%-10s %10llu %10.1f %10.1f %8.2f %10.1f\n", r.stream.c_str(), static_cast<unsigned long long>(r.records),
                r.record_ns, r.encode_ns, r.bytes_per_record, r.read_ns);
  if (!json.empty()) {
    nlohmann::json out = {{"benchmark", "recorder"}, {"rows", nlohmann::json::array()}};
    for (const Row& r : rows)
      out["rows"].push_back({{"record", r.stream},
                             {"records", r.records},
                             {"record_ns", r.record_ns},
                             {"encode_ns", r.encode_ns},
                             {"bytes_per_record", r.bytes_per_record},
                             {"read_ns", r.read_ns}});
    if (!feedloop::bench::write_json(json, out)) return 1;
  }
  return 0;
}
