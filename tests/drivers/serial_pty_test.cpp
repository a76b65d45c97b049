// The real serial path end to end: McuSession over SerialTransport (Boost.Asio) to
// feedloop-vmcu running as its own process on a pseudo-terminal, in real time. Every step must be
// executed exactly once, in order (the device's step hash equals the hash of what was sent),
// cleanly and under each fault kind injected on the pty (drop, corrupt, duplicate, delay,
// reorder), and across a device restart (the process killed and started again).
#include <gtest/gtest.h>

#include <pthread.h>       // pthread_setschedparam
#include <sched.h>         // SCHED_FIFO
#include <sys/resource.h>  // getrusage, RUSAGE_THREAD

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "core/clock.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "drivers/stepgen/step_batcher.hpp"
#include "drivers/stepgen/step_compressor.hpp"
#include "drivers/stepgen/step_generator.hpp"
#include "drivers/transport/serial_transport.hpp"
#include "segment_streams.hpp"
#include "tests/common/malloc_counter.hpp"
#include "vmcu_process.hpp"

namespace feedloop::drivers {
namespace {

const std::string kVmcu = std::string(FEEDLOOP_BINARY_DIR) + "/drivers/feedloop-vmcu";

struct Collect final : stepgen::BatchSink {
  McuSession* session = nullptr;
  uint64_t hash = device::kStepHashSeed, steps = 0;
  void on_batch(const stepgen::StepBatch& b) override {
    stepgen::RunDecoder d;
    d.begin(b.body, b.body_bytes);
    int64_t p = d.first_clock();
    stepgen::StepRun r;
    while (!d.done() && d.next(r)) {
      for (uint32_t k = 1; k <= r.count; ++k) hash = device::step_hash_update(hash, stepgen::run_step_clock(p, r, k), r.direction);
      steps += r.count;
      p = stepgen::run_end_clock(p, r);
    }
    session->queue_steps(b);
  }
};

using Clock = MonotonicClock;

// The I/O thread as the machine runs it: SCHED_FIFO below the servo thread (when permitted), so
// that a busy machine does not starve it while the test's thread queues frames.
QueuedTransportParams pty_io() {
  QueuedTransportParams p = SerialTransport::serial_io_params();
  p.rt_priority = 10;
  return p;
}

// Real-time driver of one session over a SerialTransport. The session's time line starts at t0;
// the transport's arrival and departure stamps are put on it.
struct PtyHost {
  SerialTransport& transport;
  McuSession& session;
  Clock clock;
  int64_t t0 = clock.now_ns();
  bool based = (transport.set_time_base_ns(t0), true);
  double now() { return seconds_from_ns(clock.now_ns() - t0); }
  void pump(double until_s) {
    while (now() < until_s) {
      session.poll(now());
      transport.poll(now(), 0.5e-3);
    }
  }
  // Until pred() or timeout_s; returns pred().
  template <class Pred>
  bool pump_until(Pred pred, double timeout_s) {
    const double end = now() + timeout_s;
    while (now() < end && !pred()) pump(now() + 1e-3);
    return pred();
  }
};

struct Streamed {
  uint64_t steps = 0, hash = device::kStepHashSeed;
};

// Streams `moves` trapezoid moves starting lead_s + 0.05 s from now, fed lead_s + 0.25 s ahead,
// runs closed lead_s before due, through stepgen -> session. Stops early (without flushing) at
// now() >= stop_at_s.
Streamed stream(PtyHost& h, int moves, uint64_t seed, double stop_at_s = 1e300,
                double lead_s = 0.25) {
  std::mt19937_64 rng(seed);
  auto segs = testing::trapezoid_stream(rng, moves);
  const double start = h.now() + lead_s + 0.05;
  for (auto& s : segs) s.t0_s += start;
  Collect col;
  col.session = &h.session;
  stepgen::StepBatcher batcher;
  batcher.configure(0, 200, &col);
  stepgen::StepCompressor comp;
  comp.configure({100.0, 65535}, &batcher);
  stepgen::StepGenerator gen;
  const stepgen::TickMap map = h.session.tick_map();
  gen.configure(80.0, map, &comp);
  comp.reset(static_cast<int64_t>(map.ticks(h.now())), map.ticks(h.now()));
  h.session.set_enabled(true);
  size_t next = 0;
  const double end = segs.back().end_s();
  while (h.now() < end + 0.2 && h.now() < stop_at_s) {
    while (next < segs.size() && segs[next].t0_s < h.now() + lead_s + 0.25)
      gen.add_segment(segs[next++]);
    gen.flush();
    const auto deadline = static_cast<int64_t>(map.ticks(h.now() + lead_s));
    comp.flush_if_due(deadline);
    batcher.flush_if_due(deadline);
    if (next == segs.size()) {
      comp.flush();
      batcher.flush();
    }
    h.pump(h.now() + 1e-3);
  }
  return {col.steps, col.hash};
}

// What a timing thread saw of its own cycles.
struct CycleStats {
  uint64_t cycles = 0;
  double max_work_us = 0.0;  // the cycle's work: step generation and the session's poll
  double max_late_us = 0.0;  // its wake-up after the deadline
  long blocked = 0;          // voluntary context switches inside the work: a call that blocked
  long mallocs = -1;         // allocations (any thread) while the session polled; -1: not counted
  void add(double work_us, double late_us, long vcsw) {
    ++cycles;
    max_work_us = std::max(max_work_us, work_us);
    max_late_us = std::max(max_late_us, late_us);
    blocked += vcsw;
  }
};

struct TimedStream {
  Streamed sent;
  CycleStats outside, during;  // cycles outside / inside the I/O thread's pause
  bool realtime = false;       // the loop ran SCHED_FIFO (above the I/O threads), as the servo does
};

// The calling thread at SCHED_FIFO `priority` while it lives (when permitted), like the servo
// thread; back to the default policy after.
struct RealtimeScope {
  bool granted = false;
  explicit RealtimeScope(int priority) {
    sched_param sp{};
    sp.sched_priority = priority;
    granted = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
  }
  ~RealtimeScope() {
    sched_param sp{};
    if (granted) pthread_setschedparam(pthread_self(), SCHED_OTHER, &sp);
  }
};

long voluntary_switches() {
  rusage ru{};
  ::getrusage(RUSAGE_THREAD, &ru);
  return ru.ru_nvcsw;
}

// Like stream(), from a 1 kHz loop with absolute deadlines like the servo thread's; at
// pause_at_s after the motion's start the transport's I/O thread is paused for pause_s, and
// in_pause() (if given) runs in each cycle of the pause.
TimedStream stream_1khz(PtyHost& h, int moves, uint64_t seed, double pause_at_s, double pause_s,
                        const std::function<void()>& in_pause = {}) {
  std::mt19937_64 rng(seed);
  auto segs = testing::trapezoid_stream(rng, moves);
  const double start = h.now() + 0.3;
  for (auto& s : segs) s.t0_s += start;
  Collect col;
  col.session = &h.session;
  stepgen::StepBatcher batcher;
  batcher.configure(0, 200, &col);
  stepgen::StepCompressor comp;
  comp.configure({100.0, 65535}, &batcher);
  stepgen::StepGenerator gen;
  const stepgen::TickMap map = h.session.tick_map();
  gen.configure(80.0, map, &comp);
  comp.reset(static_cast<int64_t>(map.ticks(h.now())), map.ticks(h.now()));
  h.session.set_enabled(true);
  size_t next = 0;
  const double end = segs.back().end_s();
  TimedStream out;
  const RealtimeScope rt(11);  // above the I/O threads (pty_io(): 10), as the servo is
  out.realtime = rt.granted;
  bool paused = false;
  double pause_end_s = 0.0;
  constexpr int64_t kPeriodNs = 1'000'000;
  int64_t deadline = h.clock.now_ns() + kPeriodNs;
  while (h.now() < end + 0.2) {
    h.clock.sleep_until_ns(deadline);
    const int64_t wake = h.clock.now_ns();
    const double late_us = static_cast<double>(wake - deadline) * 1e-3;
    deadline += kPeriodNs;
    if (deadline <= wake) deadline = wake + kPeriodNs;  // periods lost are not caught up
    const long vcsw0 = voluntary_switches();
    const int64_t w0 = h.clock.now_ns();
    const double now = h.now();
    if (!paused && now >= start + pause_at_s) {
      h.transport.pause_io(pause_s);
      paused = true;
      pause_end_s = now + pause_s + 0.002;  // it starts at the I/O thread's next turn
    }
    if (paused && now < pause_end_s && in_pause) in_pause();
    while (next < segs.size() && segs[next].t0_s < now + 0.5) gen.add_segment(segs[next++]);
    gen.flush();
    const auto due = static_cast<int64_t>(map.ticks(now + 0.25));
    comp.flush_if_due(due);
    batcher.flush_if_due(due);
    if (next == segs.size()) {
      comp.flush();
      batcher.flush();
    }
#ifdef FEEDLOOP_COUNT_MALLOC
    const long m0 = g_mallocs.load();
    g_counting.store(true);
#endif
    h.session.poll(now);
#ifdef FEEDLOOP_COUNT_MALLOC
    g_counting.store(false);
    const long polled_mallocs = g_mallocs.load() - m0;
#else
    const long polled_mallocs = -1;
#endif
    const double work_us = static_cast<double>(h.clock.now_ns() - w0) * 1e-3;
    const long vcsw = voluntary_switches() - vcsw0;
    CycleStats& c = paused && now < pause_end_s ? out.during : out.outside;
    c.add(work_us, late_us, vcsw);
    if (polled_mallocs >= 0) c.mallocs = std::max(c.mallocs, 0L) + polled_mallocs;
  }
  out.sent = {col.steps, col.hash};
  return out;
}

// "feedloop-vmcu NAME: faults host->device: F frames, D dropped, C corrupted, U duplicated, L
// delayed, R reordered" (its summary on stderr at exit), both directions summed.
struct InjectedFaults {
  uint64_t frames = 0, dropped = 0, corrupted = 0, duplicated = 0, delayed = 0, reordered = 0;
};
InjectedFaults read_injected(const std::string& path) {
  InjectedFaults f;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    const size_t at = line.find("faults ");
    if (at == std::string::npos) continue;
    const size_t colon = line.find(": ", at);
    unsigned long long a = 0, b = 0, c = 0, d = 0, e = 0, g = 0;
    if (colon != std::string::npos &&
        std::sscanf(line.c_str() + colon + 2,
                    "%llu frames, %llu dropped, %llu corrupted, %llu duplicated, %llu delayed, %llu reordered", &a, &b,
                    &c, &d, &e, &g) == 6) {
      f.frames += a;
      f.dropped += b;
      f.corrupted += c;
      f.duplicated += d;
      f.delayed += e;
      f.reordered += g;
    }
  }
  return f;
}

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() / (name + "-" + std::to_string(::getpid()))).string();
}

struct PtyCase {
  const char* name;
  std::vector<std::string> args;
  uint64_t InjectedFaults::*injected;  // nullptr: clean
};

class SerialPtyMotion : public ::testing::TestWithParam<PtyCase> {};

TEST_P(SerialPtyMotion, EveryStepExactlyOnce) {
  testing::VmcuProcess vmcu;
  std::vector<std::string> args{"--name", "pty-x", "--drift-ppm", "50"};
  args.insert(args.end(), GetParam().args.begin(), GetParam().args.end());
  const std::string log = temp_path(std::string("feedloop-vmcu-") + GetParam().name + ".log");
  ASSERT_TRUE(vmcu.start(kVmcu, args, log)) << vmcu.error();
  SerialTransport transport(vmcu.pty(), 250000, pty_io());
  McuSessionParams sp;
  sp.name = "pty-x";
  // What this test asks is that every step arrives exactly once through the injected faults, not
  // how soon a silent device is declared dead (SerialPty.DeviceRestartIsReportedAndRecovered asks
  // that, at the default 1 s). The machine under the CI (the sanitizer build beside the
  // wall-clock tests) held this program's SCHED_FIFO I/O thread for 1.99 s in a fresh-clone run,
  // and two of these tests beside stress-ng --cpu 2 for 2.7 and 3.3 s: the session then declared
  // the device dead. 5 s of silence here. The same for the device's watchdog (0.5 s by default):
  // a fresh-clone CI held the I/O thread for 1.40 s, the device stopped its motor on it and the
  // test's status never came (the watchdog itself: VirtualMcu's tests, SerialPty.*).
  sp.link_stall_s = 5.0;
  sp.watchdog_s = 5.0;
  McuSession session(sp, transport);
  PtyHost h{transport, session};
  ASSERT_TRUE(session.start(h.now()).ok()) << session.error()->message;
  ASSERT_TRUE(
      h.pump_until([&] { return session.ready() || session.state() == McuState::kFailed; }, 6.0));
  ASSERT_TRUE(session.ready()) << (session.error() ? session.error()->message : "not ready");
  h.pump(h.now() + 0.6);  // clock queries: the burst and a few more

  // ~1.5 s of moves, their steps sent 4 s ahead: the same machine held the I/O thread for 2.29 s
  // in a fresh-clone CI, and steps sent 0.25 s ahead reached the device after their time (a step
  // queue underrun: the device's answer to a host that stalls, SerialPty's stall test).
  const Streamed sent = stream(h, 12, 5, 1e300, 4.0);
  // Up to 3 s: with 5 % of frames dropped, the request or its answer may need retransmissions
  // behind the step batches still queued (CI once saw no status after 1 s of pumping). Up to 8 s:
  // a fresh-clone CI saw the link's I/O thread stalled for 991 ms by the machine (the sanitizer
  // build beside the wall-clock tests) and no status after 3 s; the wait ends as soon as it comes.
  session.request_status();
  h.pump_until([&] { return session.last_status().has_value(); }, 8.0);
  for (const auto& e : session.take_events()) std::printf("event: %s\n", e.c_str());
  std::printf("clock rate %+.2f ppm (device: +50)\n", (session.clock().freq_hz() / session.mcu_clock_hz() - 1.0) * 1e6);
  std::printf("I/O thread (%s): longest gap between turns %.0f us, %llu turns; clock rtt min %.0f us, mean %.0f us\n",
              transport.io_stats().io_realtime ? "SCHED_FIFO" : "default policy", transport.io_stats().io_max_gap_us,
              (unsigned long long)transport.io_stats().io_turns,
              session.clock().min_rtt_s() * 1e6, session.clock().mean_rtt_s() * 1e6);
  vmcu.stop();
  const InjectedFaults inj = read_injected(log);
  std::remove(log.c_str());
  ASSERT_TRUE(session.last_status().has_value());
  const DeviceStatus st = *session.last_status();
  std::printf("pty %s: %llu steps sent, %llu executed; host: %llu frames, %llu bytes written, %llu retransmitted; "
              "injected by feedloop-vmcu: %llu frames, %llu dropped, %llu corrupted, %llu duplicated, %llu delayed, "
              "%llu reordered\n",
              GetParam().name, (unsigned long long)sent.steps, (unsigned long long)st.steps_executed,
              (unsigned long long)session.frames_written(), (unsigned long long)session.bytes_written(),
              (unsigned long long)session.link_stats().retransmitted, (unsigned long long)inj.frames,
              (unsigned long long)inj.dropped, (unsigned long long)inj.corrupted, (unsigned long long)inj.duplicated,
              (unsigned long long)inj.delayed, (unsigned long long)inj.reordered);
  EXPECT_GT(sent.steps, 3000u);
  EXPECT_EQ(st.steps_executed, sent.steps);
  EXPECT_EQ(st.step_hash, sent.hash);
  EXPECT_FALSE(st.stopped);
  EXPECT_EQ(session.state(), McuState::kReady);
  EXPECT_GT(inj.frames, 200u);  // the summary was read
  if (GetParam().injected != nullptr) {
    EXPECT_GE(inj.*(GetParam().injected), 5u) << "the fault was exercised";
  }
}

// Clean, each fault kind alone and all together, injected by feedloop-vmcu on the pty in both
// directions.
INSTANTIATE_TEST_SUITE_P(
    Pty, SerialPtyMotion,
    ::testing::Values(PtyCase{"clean", {}, nullptr},
                      PtyCase{"drop", {"--drop", "0.05", "--seed", "3"}, &InjectedFaults::dropped},
                      PtyCase{"corrupt", {"--corrupt", "0.05", "--seed", "4"}, &InjectedFaults::corrupted},
                      PtyCase{"duplicate", {"--duplicate", "0.1", "--seed", "5"}, &InjectedFaults::duplicated},
                      PtyCase{"delay", {"--delay", "0.03", "--seed", "6"}, &InjectedFaults::delayed},
                      PtyCase{"reorder", {"--reorder", "0.1", "--seed", "7"}, &InjectedFaults::reordered},
                      PtyCase{"all",
                              {"--drop", "0.03", "--corrupt", "0.03", "--duplicate", "0.03", "--delay", "0.02",
                               "--reorder", "0.03", "--seed", "8"},
                              &InjectedFaults::frames}),
    [](const auto& tp) { return std::string(tp.param.name); });

// A disconnect over the pty: feedloop-vmcu is killed mid-stream (a device losing power) and a new
// one started on the same link path (the device back, rebooted, its queue lost). The session
// reports which MCU disconnected, reopens the port, finds that the device acknowledges nothing
// of the old link (it restarted) and fails naming it; start() re-identifies it and a new stream
// is executed exactly once.
TEST(SerialPty, DeviceRestartIsReportedAndRecovered) {
  const std::string link = temp_path("feedloop-vmcu-link");
  testing::VmcuProcess first;
  ASSERT_TRUE(first.start(kVmcu, {"--name", "pty-x", "--link", link})) << first.error();
  SerialTransport transport(link, 250000, pty_io());
  McuSessionParams sp;
  sp.name = "pty-x";
  McuSession session(sp, transport);
  PtyHost h{transport, session};
  ASSERT_TRUE(session.start(h.now()).ok()) << session.error()->message;
  ASSERT_TRUE(h.pump_until([&] { return session.ready(); }, 2.0));
  h.pump(h.now() + 0.5);
  // Stream, and pull the plug 1 s in.
  const double kill_at = h.now() + 1.0;
  const Streamed part1 = stream(h, 40, 5, kill_at);
  first.stop(SIGKILL);
  const double killed_at = h.now();
  ASSERT_TRUE(h.pump_until([&] { return session.state() == McuState::kDisconnected; }, 1.0));
  const double detected_s = h.now() - killed_at;
  std::vector<std::string> events = session.take_events();
  ASSERT_FALSE(events.empty());
  std::printf("after %llu steps sent, killed; %.1f ms later: %s\n", (unsigned long long)part1.steps, detected_s * 1e3,
              events[0].c_str());
  EXPECT_NE(events[0].find("MCU 'pty-x' (serial " + link + ") disconnected"), std::string::npos) << events[0];
  EXPECT_GT(part1.steps, 500u);
  EXPECT_LT(detected_s, 0.1);
  // Stays disconnected (retrying) while nothing is there.
  h.pump(h.now() + 0.6);
  EXPECT_EQ(session.state(), McuState::kDisconnected);

  // The device comes back, rebooted.
  testing::VmcuProcess second;
  ASSERT_TRUE(second.start(kVmcu, {"--name", "pty-x", "--link", link})) << second.error();
  const double back_at = h.now();
  ASSERT_TRUE(h.pump_until([&] { return session.state() == McuState::kFailed; }, 3.0));
  const double failed_s = h.now() - back_at;
  events = session.take_events();
  for (const auto& e : events) std::printf("event: %s\n", e.c_str());
  bool reconnected = false;
  for (const auto& e : events) reconnected |= e.find("MCU 'pty-x' (serial " + link + ") reconnected") != std::string::npos;
  EXPECT_TRUE(reconnected);
  const std::string msg = session.error()->message;
  std::printf("%.0f ms after the device came back: %s\n", failed_s * 1e3, msg.c_str());
  EXPECT_NE(msg.find("MCU 'pty-x'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("restarted"), std::string::npos) << msg;
  EXPECT_LT(failed_s, 2.0);  // reopen every 250 ms + 1 s of silence on the old link

  // Recovery: identify again, resynchronise, stream; every new step exactly once.
  ASSERT_TRUE(session.start(h.now()).ok());
  // Up to 5 s: on a busy CI host (the sanitizer build compiling beside it) a recovery once needed
  // over 2 s of retransmissions (122 frames sent, 132 retransmitted) to identify again.
  ASSERT_TRUE(h.pump_until([&] { return session.ready(); }, 5.0))
      << (session.error() ? session.error()->message : "");
  h.pump(h.now() + 0.5);
  const Streamed part2 = stream(h, 8, 10);
  session.request_status();
  h.pump_until([&] { return session.last_status().has_value() && session.last_status()->steps_executed == part2.steps; }, 1.0);
  ASSERT_TRUE(session.last_status().has_value());
  std::printf("after recovery: %llu steps sent, %llu executed\n", (unsigned long long)part2.steps,
              (unsigned long long)session.last_status()->steps_executed);
  EXPECT_GT(part2.steps, 2000u);
  EXPECT_EQ(session.last_status()->steps_executed, part2.steps);
  EXPECT_EQ(session.last_status()->step_hash, part2.hash);
  EXPECT_EQ(session.state(), McuState::kReady);
  second.stop();
}

// DESIGN.md "Threads and time": the serial bytes move on the transport's I/O thread, so a stalled
// I/O thread (paused 50 ms mid-print) does not delay the thread that streams the steps: its
// cycles go on at 1 kHz, none blocks (no voluntary context switch inside a cycle's work), its
// work and wake-up times stay what they are outside the pause; the frames wait in the send queue
// and every step is executed exactly once.
TEST(SerialPty, StalledIoThreadDoesNotDelayTheTimingThread) {
  testing::VmcuProcess vmcu;
  ASSERT_TRUE(vmcu.start(kVmcu, {"--name", "pty-x", "--drift-ppm", "50"})) << vmcu.error();
  SerialTransport transport(vmcu.pty(), 250000, pty_io());
  McuSessionParams sp;
  sp.name = "pty-x";
  McuSession session(sp, transport);
  PtyHost h{transport, session};
  ASSERT_TRUE(session.clock_fit_async()) << "the clock fit runs on the I/O thread";
  ASSERT_TRUE(session.start(h.now()).ok()) << session.error()->message;
  ASSERT_TRUE(h.pump_until([&] { return session.ready(); }, 2.0));
  h.pump(h.now() + 0.6);
  const double cpu0 = transport.io_thread_cpu_s(), t_stream0 = h.now();
  const TimedStream r = stream_1khz(h, 12, 5, 0.5, 0.05);
  const double io_cpu_s = transport.io_thread_cpu_s() - cpu0, stream_s = h.now() - t_stream0;
  session.request_status();
  h.pump_until([&] { return session.last_status().has_value() && session.last_status()->steps_executed == r.sent.steps; },
               1.0);
  for (const auto& e : session.take_events()) std::printf("event: %s\n", e.c_str());
  const TransportStats io = transport.io_stats();
  std::printf("1 kHz timing thread (%s), I/O thread paused 50 ms: %llu cycles during the pause (max work %.0f us, "
              "max wake-up lateness %.0f us, %ld blocking), %llu outside (max work %.0f us, max lateness %.0f us, "
              "%ld blocking); %llu frames refused, %llu retransmitted; clock rtt min %.0f us mean %.0f us over %d "
              "samples\n",
              r.realtime ? "SCHED_FIFO" : "default policy: its lateness is the machine's load", (unsigned long long)r.during.cycles, r.during.max_work_us, r.during.max_late_us, r.during.blocked,
              (unsigned long long)r.outside.cycles, r.outside.max_work_us, r.outside.max_late_us, r.outside.blocked,
              (unsigned long long)io.tx_full, (unsigned long long)session.link_stats().retransmitted,
              session.clock().min_rtt_s() * 1e6, session.clock().mean_rtt_s() * 1e6, session.clock().samples());
  std::printf("I/O thread while streaming: %.1f ms of CPU in %.2f s (%.2f %% of a core), %llu frames sent, %llu "
              "chunks received; allocations while the session polled: %ld (pause), %ld (outside)\n",
              io_cpu_s * 1e3, stream_s, io_cpu_s * 100.0 / stream_s, (unsigned long long)io.tx_frames,
              (unsigned long long)io.rx_chunks, r.during.mallocs, r.outside.mallocs);
  vmcu.stop();
  EXPECT_EQ(io.io_pauses, 1u);
  EXPECT_EQ(r.during.blocked, 0);
  EXPECT_EQ(r.outside.blocked, 0);
#ifdef FEEDLOOP_COUNT_MALLOC
  // The session's steady streaming (frames out, bytes in, clock samples to the I/O thread's fit)
  // allocates nothing, in either thread, during the pause or outside it.
  EXPECT_EQ(r.during.mallocs, 0);
  EXPECT_EQ(r.outside.mallocs, 0);
#endif
  // A timing thread that waited for the I/O thread would show the 50 ms in one cycle's work (or
  // block: counted above). Its wake-up lateness is the machine's scheduler, not the I/O thread
  // (which runs below it): a busy or virtualised host delays even a SCHED_FIFO thread by a few
  // ms now and then (6.0 ms seen once on a CI machine, 0.3 ms outside the pause in the same run),
  // so the bounds on it only say the thread kept cycling through the 52 ms window and was never
  // late by anything like the pause: at most 20 ms late, and at least 30 of its ~52 cycles.
  EXPECT_LT(r.during.max_work_us, 20000.0);
  if (r.realtime) {
    EXPECT_GE(r.during.cycles, 30u);
    EXPECT_LT(r.during.max_late_us, 20000.0);
  }
  ASSERT_TRUE(session.last_status().has_value());
  EXPECT_GT(r.sent.steps, 3000u);
  EXPECT_EQ(session.last_status()->steps_executed, r.sent.steps);
  EXPECT_EQ(session.last_status()->step_hash, r.sent.hash);
  EXPECT_FALSE(session.last_status()->stopped);
  EXPECT_EQ(session.state(), McuState::kReady);
}

// Back pressure loses nothing: with a send queue of 15 frames and the I/O thread paused for 100 ms
// while the session asks for the device's status every cycle, the link fills its window of 12
// frames, retransmits them after its timeout (25 ms, then 50 ms) and the queue refuses what does
// not fit; the refusals are counted (transport and
// session) and the reliable link sends those frames again, so every step is still executed
// exactly once.
TEST(SerialPty, FullSendQueueIsCountedAndLosesNoStep) {
  testing::VmcuProcess vmcu;
  ASSERT_TRUE(vmcu.start(kVmcu, {"--name", "pty-x"})) << vmcu.error();
  QueuedTransportParams io = pty_io();
  io.tx_frames = 15;  // a little more than the link's window of 12 frames
  SerialTransport transport(vmcu.pty(), 250000, io);
  McuSessionParams sp;
  sp.name = "pty-x";
  McuSession session(sp, transport);
  PtyHost h{transport, session};
  ASSERT_TRUE(session.start(h.now()).ok()) << session.error()->message;
  ASSERT_TRUE(h.pump_until([&] { return session.ready(); }, 2.0));
  h.pump(h.now() + 0.6);
  const TimedStream r = stream_1khz(h, 12, 7, 0.4, 0.1, [&] { session.request_status(); });
  session.request_status();
  h.pump_until([&] { return session.last_status().has_value() && session.last_status()->steps_executed == r.sent.steps; },
               1.0);
  for (const auto& e : session.take_events()) std::printf("event: %s\n", e.c_str());
  const TransportStats st = transport.io_stats();
  std::printf("send queue of 15 frames, I/O thread paused 100 ms: %llu frames refused (session: %llu), %llu retransmitted; "
              "%llu steps sent, %llu executed\n",
              (unsigned long long)st.tx_full, (unsigned long long)session.frames_refused(),
              (unsigned long long)session.link_stats().retransmitted, (unsigned long long)r.sent.steps,
              (unsigned long long)(session.last_status() ? session.last_status()->steps_executed : 0));
  vmcu.stop();
  EXPECT_GT(st.tx_full, 0u);
  EXPECT_EQ(session.frames_refused(), st.tx_full);
  EXPECT_GT(session.link_stats().retransmitted, 0u);
  EXPECT_EQ(r.during.blocked, 0);
  ASSERT_TRUE(session.last_status().has_value());
  EXPECT_EQ(session.last_status()->steps_executed, r.sent.steps);
  EXPECT_EQ(session.last_status()->step_hash, r.sent.hash);
  EXPECT_EQ(session.state(), McuState::kReady);
}

// A stall of the I/O thread longer than the MCU's watchdog (0.5 s) and the steps' lead: the MCU
// stops its motor (watchdog or underrun), and the session's failure (the MCU's report, or the link
// silent for 1 s) names the stalled I/O thread.
TEST(SerialPty, IoThreadStalledBeyondTheLeadIsNamed) {
  testing::VmcuProcess vmcu;
  ASSERT_TRUE(vmcu.start(kVmcu, {"--name", "pty-x"})) << vmcu.error();
  SerialTransport transport(vmcu.pty(), 250000, pty_io());
  McuSessionParams sp;
  sp.name = "pty-x";
  McuSession session(sp, transport);
  PtyHost h{transport, session};
  ASSERT_TRUE(session.start(h.now()).ok()) << session.error()->message;
  ASSERT_TRUE(h.pump_until([&] { return session.ready(); }, 2.0));
  h.pump(h.now() + 0.6);
  const TimedStream r = stream_1khz(h, 12, 5, 0.3, 0.7);
  h.pump_until([&] { return session.state() == McuState::kFailed; }, 1.0);
  for (const auto& e : session.take_events()) std::printf("event: %s\n", e.c_str());
  vmcu.stop();
  ASSERT_EQ(session.state(), McuState::kFailed);
  const std::string msg = session.error()->message;
  std::printf("I/O thread paused 700 ms: %s\n", msg.c_str());
  EXPECT_NE(msg.find("MCU 'pty-x'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("I/O thread did not run for up to"), std::string::npos) << msg;
  EXPECT_EQ(r.during.blocked, 0);
}

TEST(SerialPty, VersionMismatchRefused) {
  testing::VmcuProcess vmcu;
  ASSERT_TRUE(vmcu.start(kVmcu, {"--protocol-version", "9"})) << vmcu.error();
  SerialTransport transport(vmcu.pty(), 250000, pty_io());
  McuSession session({}, transport);
  MonotonicClock clock;
  const int64_t t0 = clock.now_ns();
  ASSERT_TRUE(session.start(0.0).ok());
  while (seconds_from_ns(clock.now_ns() - t0) < 1.0 && session.state() != McuState::kFailed) {
    session.poll(seconds_from_ns(clock.now_ns() - t0));
    transport.poll(0, 1e-3);
  }
  ASSERT_EQ(session.state(), McuState::kFailed);
  EXPECT_NE(session.error()->message.find("protocol version 9"), std::string::npos) << session.error()->message;
}

TEST(SerialPty, MissingPortIsAClearError) {
  SerialTransport t("/dev/feedloop-no-such-port");
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("/dev/feedloop-no-such-port"), std::string::npos);
  EXPECT_NE(st.error().message.find("plugged in"), std::string::npos) << st.error().message;
}

}  // namespace
}  // namespace feedloop::drivers
