// Protocol throughput through the real serial path: host session -> SerialTransport -> pty ->
// feedloop-vmcu (its own process, real time). Usage:
//   bench_protocol [--json FILE] [--seconds S] [--steps-per-mm X] [--faults P] [--vmcu PATH]
// Phase "stream": printing-like moves at a high microstep count are generated, compressed and
// streamed 0.5 s ahead; reports executed steps/s, frames/s and bytes/s on the wire, and whether
// the device's step hash matches what was sent. Phase "ping": STATUS queries one at a time:
// round trips/s and the mean round-trip time. --faults P: feedloop-vmcu drops, corrupts,
// duplicates and reorders each frame with probability P and delays it (80 ms) with P/4, in both
// directions, so the figures show the cost of retransmission.
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "core/clock.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "drivers/transport/serial_transport.hpp"
#include "segment_streams.hpp"
#include "vmcu_process.hpp"

using namespace feedloop;
using namespace feedloop::drivers;

namespace {

struct Collect final : stepgen::BatchSink {
  McuSession* session = nullptr;
  uint64_t hash = device::kStepHashSeed, steps = 0;
  void on_batch(const stepgen::StepBatch& b) override {
    stepgen::RunDecoder d;
    d.begin(b.body, b.body_bytes);
    int64_t p = d.first_clock();
    stepgen::StepRun r;
    while (!d.done() && d.next(r)) {
      for (uint32_t k = 1; k <= r.count; ++k)
        hash = device::step_hash_update(hash, stepgen::run_step_clock(p, r, k), r.direction);
      steps += r.count;
      p = stepgen::run_end_clock(p, r);
    }
    session->queue_steps(b);
  }
};

}  // namespace

int main(int argc, char** argv) {
  std::string json, vmcu_path = FEEDLOOP_VMCU_PATH;
  double seconds = 3.0, spm = 1600.0, faults = 0.0;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
    else if (!std::strcmp(argv[i], "--seconds") && i + 1 < argc) seconds = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--steps-per-mm") && i + 1 < argc) spm = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--vmcu") && i + 1 < argc) vmcu_path = argv[++i];
    else if (!std::strcmp(argv[i], "--faults") && i + 1 < argc) faults = std::atof(argv[++i]);
    else {
      std::fprintf(stderr, "usage: %s [--json FILE] [--seconds S] [--steps-per-mm X] [--faults P] [--vmcu PATH]\n",
                   argv[0]);
      return 2;
    }
  }
  testing::VmcuProcess vmcu;
  std::vector<std::string> vargs{"--name", "bench"};
  if (faults > 0) {
    const std::string p = std::to_string(faults), q = std::to_string(faults / 4);
    for (const char* k : {"--drop", "--corrupt", "--duplicate", "--reorder"}) vargs.insert(vargs.end(), {k, p});
    vargs.insert(vargs.end(), {"--delay", q});
  }
  if (!vmcu.start(vmcu_path, vargs)) {
    std::fprintf(stderr, "bench_protocol: %s\n", vmcu.error().c_str());
    return 1;
  }
  // The I/O thread as the machine runs it: SCHED_FIFO below the servo thread, when permitted.
  QueuedTransportParams io = SerialTransport::serial_io_params();
  io.rt_priority = 79;
  SerialTransport transport(vmcu.pty(), 250000, io);
  McuSessionParams sp;
  sp.name = "bench";
  McuSession session(sp, transport);
  MonotonicClock clock;
  const int64_t t0 = clock.now_ns();
  transport.set_time_base_ns(t0);  // the I/O thread's stamps on this time line (clock sync)
  auto now = [&] { return seconds_from_ns(clock.now_ns() - t0); };
  auto pump = [&](double until_s) {
    while (now() < until_s) {
      session.poll(now());
      transport.poll(now(), 0.2e-3);
    }
  };
  if (!session.start(now()).ok()) {
    std::fprintf(stderr, "bench_protocol: %s\n", session.error()->message.c_str());
    return 1;
  }
  pump(1.5);
  if (!session.ready()) {
    std::fprintf(stderr, "bench_protocol: MCU not ready: %s\n", session.error() ? session.error()->message.c_str() : "timeout");
    return 1;
  }

  // Phase 1: stream.
  std::mt19937_64 rng(1);
  auto segs = feedloop::testing::trapezoid_stream(rng, 400);
  const double start = now() + 0.3;
  for (auto& s : segs) s.t0_s += start;
  while (!segs.empty() && segs.back().end_s() > start + seconds) segs.pop_back();
  Collect col;
  col.session = &session;
  stepgen::StepBatcher batcher;
  batcher.configure(0, 200, &col);
  stepgen::StepCompressor comp;
  comp.configure({100.0, 65535}, &batcher);
  stepgen::StepGenerator gen;
  const stepgen::TickMap map = session.tick_map();
  gen.configure(spm, map, &comp);
  comp.reset(static_cast<int64_t>(map.ticks(now())), map.ticks(now()));
  session.set_enabled(true);
  const uint64_t frames0 = session.frames_written(), bytes0 = session.bytes_written();
  size_t next = 0;
  const double end = segs.empty() ? start : segs.back().end_s();
  while (now() < end + 0.1) {
    while (next < segs.size() && segs[next].t0_s < now() + 0.5) gen.add_segment(segs[next++]);
    gen.flush();
    const auto deadline = static_cast<int64_t>(map.ticks(now() + 0.25));
    comp.flush_if_due(deadline);
    batcher.flush_if_due(deadline);
    if (next == segs.size()) {
      comp.flush();
      batcher.flush();
    }
    pump(now() + 0.5e-3);
  }
  session.request_status();
  pump(now() + 0.3);
  const double stream_s = end - start;
  const double frames = static_cast<double>(session.frames_written() - frames0);
  const double bytes = static_cast<double>(session.bytes_written() - bytes0);
  const bool ok = session.last_status() && session.last_status()->steps_executed == col.steps &&
                  session.last_status()->step_hash == col.hash;

  // Phase 2: ping-pong status queries.
  int pings = 0;
  double rtt_sum = 0.0;
  const double ping_end = now() + 1.0;
  while (now() < ping_end) {
    const int64_t before = session.last_status() ? session.last_status()->clock : -1;
    const double sent = now();
    session.request_status();
    while (now() - sent < 0.1 && (!session.last_status() || session.last_status()->clock == before)) {
      session.poll(now());
      transport.poll(now(), 0.1e-3);
    }
    rtt_sum += now() - sent;
    ++pings;
  }
  for (const auto& e : session.take_events()) std::fprintf(stderr, "event: %s\n", e.c_str());
  std::fprintf(stderr, "host link: %llu sent, %llu retransmitted, %llu acks sent, %llu dup dropped\n",
               (unsigned long long)session.link_stats().sent, (unsigned long long)session.link_stats().retransmitted,
               (unsigned long long)session.link_stats().acks_sent,
               (unsigned long long)session.link_stats().duplicates_dropped);

  std::printf("%-8s %10s %10s %12s %10s %12s %8s\n", "phase", "steps", "steps/s", "frames/s", "bytes/s", "B/step(wire)",
              "ok");
  std::printf("%-8s %10llu %10.0f %12.0f %10.0f %12.3f %8s\n", "stream", (unsigned long long)col.steps,
              col.steps / stream_s, frames / stream_s, bytes / stream_s, bytes / std::max<double>(1, col.steps),
              ok ? "yes" : "NO");
  std::printf("%-8s %10s %10s %12.0f %10s %12s %8s   mean RTT %.0f us\n", "ping", "-", "-", pings / 1.0, "-", "-",
              "-", rtt_sum / pings * 1e6);
  if (!json.empty()) {
    const nlohmann::json out = {{"benchmark", "protocol"},
                                {"transport", "pty"},
                                {"faults", faults},
                                {"steps", col.steps},
                                {"steps_per_s", col.steps / stream_s},
                                {"frames_per_s", frames / stream_s},
                                {"bytes_per_s", bytes / stream_s},
                                {"wire_bytes_per_step", bytes / std::max<double>(1, col.steps)},
                                {"all_steps_ok", ok},
                                {"ping_round_trips_per_s", pings},
                                {"ping_mean_rtt_us", rtt_sum / pings * 1e6}};
    if (!feedloop::bench::write_json(json, out)) return 1;
  }
  return ok ? 0 : 1;
}
