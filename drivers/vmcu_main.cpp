// feedloop-vmcu: a virtual MCU (drivers/device/virtual_mcu.hpp) as its own process on a
// pseudo-terminal, with an ideal motor, so the real serial path can be tested end to end.
//
//   feedloop-vmcu --pty [--link PATH] [--name NAME] [--axis N] [--clock-hz HZ] [--drift-ppm PPM]
//                 [--offset-s S] [--steps-per-mm X] [--protocol-version N]
//                 [--drop P] [--corrupt P] [--duplicate P] [--delay P] [--reorder P]
//                 [--delay-ms MS] [--reorder-ms MS] [--seed N] [--heater-board CONFIG]
//
// The fault options exercise the pty path, per frame in both directions (the bytes read from the
// pty are split into frames first; protocol::FaultyFrameLine): each frame is dropped / has one
// byte corrupted / is sent twice / is delayed by --delay-ms (default 80, beyond the host's
// retransmit timeout) / is held --reorder-ms (default 2) so that later frames overtake it, with
// the given probabilities.
//
// Prints "PTY <slave path>" on stdout once ready (and makes PATH a symlink to it with --link),
// then runs in real time until SIGTERM/SIGINT, and prints what it executed and the faults it
// injected on stderr. The ideal motor's encoder reads the commanded position with AS5311
// resolution (0.49 um counts). With --heater-board CONFIG it is instead a heater board without
// motors: the config's heaters and fans that name --name as their mcu (heater_mcus; those that name
// no board when none does), each heater with its simulated thermal plant (the heater's plant:
// section, sim/thermal_plant.hpp), at that heater_mcus entry's clock_hz. Killing it (SIGKILL) is a
// device that loses power: the host sees the pty hang up; a new feedloop-vmcu on the same --link is
// the device coming back, rebooted. When --name is a motion MCU of the config's mcus, it is that
// board with both: its ideal motor and the heaters and fans named on it (one board for motion and
// heaters; the host's bridge carries both on one session).
#include <fcntl.h>   // posix_openpt, O_RDWR
#include <poll.h>    // ppoll
#include <signal.h>  // sigaction
#include <stdlib.h>  // grantpt, unlockpt, ptsname
#include <termios.h> // cfmakeraw
#include <unistd.h>  // read, write, symlink, unlink

#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <algorithm>
#include <string>

#include "config/config.hpp"
#include "core/clock.hpp"
#include "drivers/device/heater_board.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/protocol/frame.hpp"
#include "drivers/protocol/frame_faults.hpp"
#include "engine/simulated_printer.hpp"
#include "engine/thermal_config.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

struct IdealMotor final : feedloop::device::MotorPort {
  double steps_per_mm = 80.0;
  int64_t steps = 0;
  void step(double, int d) override { steps += d; }
  void set_enabled(double, bool) override {}
  int64_t read_encoder_counts(double) override {
    return static_cast<int64_t>(std::llround(static_cast<double>(steps) / steps_per_mm / 0.49e-3));
  }
};

int usage(const char* argv0) {
  std::fprintf(
      stderr,
      "usage: %s --pty [--link PATH] [--name NAME] [--axis N] [--clock-hz HZ] [--drift-ppm PPM]\n"
      "          [--offset-s S] [--steps-per-mm X] [--protocol-version N]\n"
      "          [--drop P] [--corrupt P] [--duplicate P] [--delay P] [--reorder P]\n"
      "          [--delay-ms MS] [--reorder-ms MS] [--seed N] [--heater-board CONFIG]\n",
      argv0);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using feedloop::device::VirtualMcu;
  feedloop::device::VirtualMcuParams params;
  std::snprintf(params.name, sizeof params.name, "vmcu");
  IdealMotor motor;
  bool pty = false;
  std::string link;
  feedloop::protocol::FrameFaults faults;  // no added latency: the pty and scheduler are the link
  unsigned long long seed = 1;
  std::string heater_config;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    const char* v = nullptr;
    if (a == "--pty") pty = true;
    else if (a == "--link" && (v = next())) link = v;
    else if (a == "--name" && (v = next())) std::snprintf(params.name, sizeof params.name, "%s", v);
    else if (a == "--axis" && (v = next())) params.axis = static_cast<uint8_t>(std::atoi(v));
    else if (a == "--clock-hz" && (v = next())) params.clock_hz = std::atof(v);
    else if (a == "--drift-ppm" && (v = next())) params.drift_ppm = std::atof(v);
    else if (a == "--offset-s" && (v = next())) params.offset_s = std::atof(v);
    else if (a == "--steps-per-mm" && (v = next())) motor.steps_per_mm = std::atof(v);
    else if (a == "--protocol-version" && (v = next())) params.protocol_version = static_cast<uint16_t>(std::atoi(v));
    else if (a == "--drop" && (v = next())) faults.drop = std::atof(v);
    else if (a == "--corrupt" && (v = next())) faults.corrupt = std::atof(v);
    else if (a == "--duplicate" && (v = next())) faults.duplicate = std::atof(v);
    else if (a == "--delay" && (v = next())) faults.delay = std::atof(v);
    else if (a == "--reorder" && (v = next())) faults.reorder = std::atof(v);
    else if (a == "--delay-ms" && (v = next())) faults.delay_extra_s = std::atof(v) * 1e-3;
    else if (a == "--reorder-ms" && (v = next())) faults.reorder_extra_s = std::atof(v) * 1e-3;
    else if (a == "--seed" && (v = next())) seed = std::strtoull(v, nullptr, 10);
    else if (a == "--heater-board" && (v = next()))
      heater_config = v;
    else return usage(argv[0]);
  }
  if (!pty) return usage(argv[0]);
  if (!(params.clock_hz > 1e3) || !(motor.steps_per_mm > 0)) {
    std::fprintf(stderr, "feedloop-vmcu: --clock-hz must be > 1000 and --steps-per-mm > 0\n");
    return 2;
  }

  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0) {
    std::perror("feedloop-vmcu: cannot create a pseudo-terminal");
    return 1;
  }
  const std::string slave_path = ::ptsname(master);
  // Keep the slave open ourselves: raw mode sticks, and the master never sees EIO while the
  // host is not connected.
  const int slave = ::open(slave_path.c_str(), O_RDWR | O_NOCTTY);
  termios tio{};
  if (slave >= 0 && ::tcgetattr(slave, &tio) == 0) {
    ::cfmakeraw(&tio);
    ::tcsetattr(slave, TCSANOW, &tio);
  }
  if (!link.empty()) {
    ::unlink(link.c_str());
    if (::symlink(slave_path.c_str(), link.c_str()) != 0) {
      std::perror(("feedloop-vmcu: cannot create link " + link).c_str());
      return 1;
    }
  }
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  ::sigaction(SIGTERM, &sa, nullptr);
  ::sigaction(SIGINT, &sa, nullptr);

  std::unique_ptr<feedloop::engine::SimulatedHeaterDevice> board;
  std::unique_ptr<feedloop::engine::SimulatedHeaterBoard> motion_board_heaters;
  std::unique_ptr<VirtualMcu> own;
  if (!heater_config.empty()) {
    auto cfg = feedloop::config::load_config_file(heater_config);
    if (!cfg.ok()) {
      std::fprintf(stderr, "feedloop-vmcu: %s\n", cfg.error().to_string().c_str());
      return 2;
    }
    const std::string name = params.name;
    feedloop::engine::BoardChannels ch = feedloop::engine::board_channels(*cfg, name);
    if (ch.empty()) ch = feedloop::engine::board_channels(*cfg, "");  // a config without boards
    if (ch.empty()) {
      std::fprintf(stderr, "feedloop-vmcu: %s has no heaters or fans for '%s'\n",
                   heater_config.c_str(), name.c_str());
      return 2;
    }
    double clock_hz = static_cast<double>(cfg->stepgen.mcu_clock_hz);
    for (const auto& b : cfg->heater_mcus)
      if (b.name == name) clock_hz = static_cast<double>(b.clock_hz);
    bool motion_mcu = false;
    for (const auto& b : cfg->mcus) motion_mcu = motion_mcu || b.name == name;
    if (motion_mcu) {  // the motor and the heaters on one MCU, at --clock-hz
      motion_board_heaters =
          feedloop::engine::make_simulated_heater_board(*cfg, ch.heaters, ch.fans, params.clock_hz);
      feedloop::device::MotorPort* ports[1] = {&motor};
      own = std::make_unique<VirtualMcu>(params, ports, 1, &motion_board_heaters->board());
    } else {
      board =
          feedloop::engine::make_simulated_heater_device(*cfg, ch.heaters, ch.fans, clock_hz, name);
    }
  } else {
    own = std::make_unique<VirtualMcu>(params, &motor);
  }
  VirtualMcu* mcu = board ? &board->vmcu() : own.get();
  feedloop::MonotonicClock clock;
  const int64_t t0_ns = clock.now_ns();
  auto now_s = [&] { return feedloop::seconds_from_ns(clock.now_ns() - t0_ns); };
  std::printf("PTY %s\n", slave_path.c_str());
  std::fflush(stdout);

  // Per-frame faults, both directions (static: ~130 kB of frame pools).
  using Line = feedloop::protocol::FaultyFrameLine<256>;
  static Line to_device, to_host;
  to_device.configure(faults, seed);
  to_host.configure(faults, seed * 0x9E3779B97F4A7C15ull + 1);
  feedloop::protocol::FrameDecoder host_frames;
  auto write_all = [&](const uint8_t* d, size_t n) {
    size_t off = 0;
    while (off < n) {
      const ssize_t w = ::write(master, d + off, n - off);
      if (w <= 0) break;
      off += static_cast<size_t>(w);
    }
  };
  uint8_t buf[4096];
  uint8_t frame[feedloop::protocol::kMaxFrame];
  while (!g_stop) {
    const double next = std::min({mcu->next_event_time(), to_device.next_due(), to_host.next_due()});
    const double wait_s = std::min(1e-3, std::max(0.0, next - now_s()));
    pollfd p{master, POLLIN, 0};
    const auto wait_ns = static_cast<long>(wait_s * 1e9);
    timespec ts{0, wait_ns};
    const int r = ::ppoll(&p, 1, &ts, nullptr);
    const double t = now_s();
    if (r > 0 && (p.revents & POLLIN)) {
      const ssize_t n = ::read(master, buf, sizeof buf);
      // Split into frames (garbage between frames is lost here as it would be at the device).
      for (size_t off = 0; n > 0 && off < static_cast<size_t>(n);) {
        off += host_frames.feed(buf + off, static_cast<size_t>(n) - off);
        feedloop::protocol::FrameView f;
        while (host_frames.next(f)) {
          const size_t len = feedloop::protocol::encode_frame(frame, f.flags, f.seq, f.ack, f.payload, f.len);
          to_device.send(frame, len, t);
        }
      }
    }
    size_t n = 0;
    while (to_device.pop_due(t, frame, n)) mcu->receive(frame, n, t);
    mcu->run_until(t);
    while (mcu->pop_frame(frame, n)) to_host.send(frame, n, t);
    while (to_host.pop_due(t, frame, n)) write_all(frame, n);
  }
  if (!link.empty()) ::unlink(link.c_str());
  const auto& st = mcu->status();
  const auto& ls = mcu->link_stats();
  std::fprintf(stderr,
               "feedloop-vmcu %s: %llu steps executed, position %lld, %llu errors; link: %llu frames sent, "
               "%llu retransmitted, %llu delivered, %llu duplicates dropped\n",
               params.name, static_cast<unsigned long long>(st.steps_executed),
               static_cast<long long>(st.position_steps), static_cast<unsigned long long>(st.errors),
               static_cast<unsigned long long>(ls.sent), static_cast<unsigned long long>(ls.retransmitted),
               static_cast<unsigned long long>(ls.delivered), static_cast<unsigned long long>(ls.duplicates_dropped));
  if (board)
    for (int i = 0; i < 4; ++i) {
      const auto& h = board->board().heater(i);
      if (!h.configured) continue;
      std::fprintf(stderr, "feedloop-vmcu %s: heater %d duty %u/65535%s\n", params.name, i,
                   static_cast<unsigned>(h.duty), h.faulted ? ", faulted" : "");
    }
  for (const auto* line : {&to_device, &to_host}) {
    const auto& fs = line->stats();
    std::fprintf(stderr,
                 "feedloop-vmcu %s: faults %s: %llu frames, %llu dropped, %llu corrupted, %llu duplicated, "
                 "%llu delayed, %llu reordered\n",
                 params.name, line == &to_device ? "host->device" : "device->host",
                 static_cast<unsigned long long>(fs.frames), static_cast<unsigned long long>(fs.dropped),
                 static_cast<unsigned long long>(fs.corrupted), static_cast<unsigned long long>(fs.duplicated),
                 static_cast<unsigned long long>(fs.delayed), static_cast<unsigned long long>(fs.reordered));
  }
  if (slave >= 0) ::close(slave);
  ::close(master);
  return 0;
}
