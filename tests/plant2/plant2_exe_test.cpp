// feedloop-plant2, the second simulator as an External plant v1 (DESIGN.md), through pipes: the
// handshake, one answer per period in lock-step, any number of axes, a clean exit when stdin
// closes, a message and a non-zero exit on garbage; and driven by feedloop's own side of the
// contract (sim/external_plant.hpp), as a printer would.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "sim/external_plant.hpp"

namespace feedloop::plant2 {
namespace {

const std::string kExe = std::string(FEEDLOOP_BINARY_DIR) + "/plant2/feedloop-plant2";

// The plant as a child process with its stdin, stdout and stderr on pipes.
class Child {
 public:
  explicit Child(const std::vector<std::string>& args) {
    int in[2], out[2], err[2];
    if (pipe(in) != 0 || pipe(out) != 0 || pipe(err) != 0) return;
    pid_ = fork();
    if (pid_ == 0) {
      dup2(in[0], 0);
      dup2(out[1], 1);
      dup2(err[1], 2);
      for (int fd : {in[0], in[1], out[0], out[1], err[0], err[1]}) close(fd);
      std::vector<char*> argv;
      std::vector<std::string> all = {kExe};
      all.insert(all.end(), args.begin(), args.end());
      for (auto& a : all) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(kExe.c_str(), argv.data());
      _exit(127);
    }
    close(in[0]);
    close(out[1]);
    close(err[1]);
    to_ = in[1];
    from_ = out[0];
    err_ = err[0];
  }
  ~Child() {
    close_stdin();
    if (pid_ > 0 && status_ < 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
    if (from_ >= 0) close(from_);
    if (err_ >= 0) close(err_);
  }

  void send(const std::string& line) {
    const std::string s = line + "\n";
    ASSERT_EQ(write(to_, s.data(), s.size()), static_cast<ssize_t>(s.size()));
  }
  // One line from stdout within 5 s ("" on EOF or timeout).
  std::string read_line() {
    std::string line;
    char c = 0;
    for (;;) {
      pollfd p{from_, POLLIN, 0};
      if (poll(&p, 1, 5000) <= 0) return line;
      if (read(from_, &c, 1) != 1) return line;
      if (c == '\n') return line;
      line.push_back(c);
    }
  }
  void close_stdin() {
    if (to_ >= 0) close(to_);
    to_ = -1;
  }
  // Exit status (waits up to 5 s; -1 if still running).
  int wait_exit() {
    for (int i = 0; i < 500 && status_ < 0; ++i) {
      int st = 0;
      if (waitpid(pid_, &st, WNOHANG) == pid_) {
        status_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
        break;
      }
      usleep(10000);
    }
    return status_;
  }
  std::string stderr_text() {
    std::string s;
    char buf[512];
    for (;;) {
      pollfd p{err_, POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) break;
      const ssize_t n = read(err_, buf, sizeof buf);
      if (n <= 0) break;
      s.append(buf, static_cast<size_t>(n));
    }
    return s;
  }

 private:
  pid_t pid_ = -1;
  int to_ = -1, from_ = -1, err_ = -1;
  int status_ = -1;
};

std::vector<double> numbers(const std::string& line) {
  std::istringstream in(line);
  std::vector<double> v;
  double d = 0.0;
  while (in >> d) v.push_back(d);
  return v;
}

std::string period_line(int k, double period_s, const std::vector<double>& u) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9f", k * period_s);
  std::string s = buf;
  for (double x : u) {
    std::snprintf(buf, sizeof buf, " %.9f", x);
    s += buf;
  }
  return s;
}

TEST(Plant2Exe, HandshakeAndLockStepAnswersForThreeAxes) {
  Child c({"--seed", "5", "--effect", "none"});
  c.send("feedloop-plant 1 axes=x,y,z period_s=0.0001");
  ASSERT_EQ(c.read_line(), "ready");
  std::vector<double> u = {10.0, 50.0, 3.0};
  // At rest: every answer is the start position.
  for (int k = 1; k <= 20; ++k) {
    c.send(period_line(k, 1e-4, u));
    const auto y = numbers(c.read_line());
    ASSERT_EQ(y.size(), 3u);
    EXPECT_NEAR(y[0], 10.0, 1e-9);
    EXPECT_NEAR(y[1], 50.0, 1e-9);
    EXPECT_NEAR(y[2], 3.0, 1e-9);
  }
  // x jumps 0.1 mm: it answers with the belt's dynamics (not there at once, there after 0.3 s);
  // y and z stay.
  u[0] = 10.1;
  std::vector<double> y;
  for (int k = 21; k <= 3020; ++k) {
    c.send(period_line(k, 1e-4, u));
    y = numbers(c.read_line());
    ASSERT_EQ(y.size(), 3u) << "period " << k;
    if (k == 22) {
      EXPECT_LT(y[0], 10.09);
    }
  }
  EXPECT_NEAR(y[0], 10.1, 0.01);
  EXPECT_NEAR(y[1], 50.0, 1e-9);
  EXPECT_NEAR(y[2], 3.0, 1e-9);
  c.close_stdin();
  EXPECT_EQ(c.wait_exit(), 0);
}

TEST(Plant2Exe, EarlyStdinCloseExitsCleanly) {
  {
    Child c({});
    c.close_stdin();  // before the handshake
    EXPECT_EQ(c.wait_exit(), 0);
  }
  {
    Child c({"--effect", "backlash"});
    c.send("feedloop-plant 1 axes=x period_s=0.001");
    ASSERT_EQ(c.read_line(), "ready");
    c.send(period_line(1, 1e-3, {0.0}));
    EXPECT_EQ(numbers(c.read_line()).size(), 1u);
    c.close_stdin();
    EXPECT_EQ(c.wait_exit(), 0);
  }
}

TEST(Plant2Exe, GarbageIsRefusedWithAMessage) {
  struct Case {
    std::string handshake, line, message;
  };
  const std::vector<Case> cases = {
      {"hello plant", "", "handshake"},
      {"feedloop-plant 2 axes=x period_s=0.001", "", "handshake"},
      {"feedloop-plant 1 axes=x period_s=-1", "", "period_s must be a positive number"},
      {"feedloop-plant 1 axes=x,y period_s=0.001", "0.001 1.0 banana", "field 3 is not a number"},
      {"feedloop-plant 1 axes=x,y period_s=0.001", "0.001 1.0", "expected 3 numbers"},
      {"feedloop-plant 1 axes=x period_s=0.001", "0.005 1.0", "expected period 1"},
      {"feedloop-plant 1 axes=x period_s=0.001", "0.001 9000", "cannot start at"},
  };
  for (const Case& k : cases) {
    Child c({});
    c.send(k.handshake);
    if (!k.line.empty()) {
      ASSERT_EQ(c.read_line(), "ready") << k.handshake;
      c.send(k.line);
    }
    EXPECT_EQ(c.read_line(), "") << k.line;  // no answer
    EXPECT_EQ(c.wait_exit(), 2) << k.line;
    const std::string err = c.stderr_text();
    EXPECT_NE(err.find("feedloop-plant2: "), std::string::npos) << err;
    EXPECT_NE(err.find(k.message), std::string::npos) << err;
  }
  Child bad_option({"--effect", "wobble"});
  EXPECT_EQ(bad_option.wait_exit(), 2);
  EXPECT_NE(bad_option.stderr_text().find("unknown effect 'wobble'"), std::string::npos);
}

TEST(Plant2Exe, FeedloopsExternalPlantDrivesIt) {
  sim::ExternalPlantParams p;
  p.command = kExe + " --seed 9 --effect extra_resonance";
  p.period_s = 1e-4;
  for (int i = 0; i < 2; ++i) {
    sim::ExternalAxisParams a;
    a.name = i == 0 ? "x" : "y";
    a.mm_per_step = 0.0106;
    a.start_mm = i == 0 ? 20.0 : 80.0;
    a.encoder.resolution_um = 0.5;
    a.encoder.noise_um = 0.0;
    p.axes.push_back(a);
  }
  auto plant = sim::ExternalPlant::start(p);
  ASSERT_TRUE(plant.ok()) << plant.error().message;
  sim::ExternalPlant& ep = *plant.value();
  ep.advance_to(0.001);
  // 100 steps (1.06 mm) on x over 20 ms.
  for (int i = 0; i < 100; ++i) ep.port(0).step(0.001 + 2e-4 * (i + 1), +1);
  ep.advance_to(0.012);
  EXPECT_GT(ep.port(0).carriage_mm(), 20.1);  // moving
  EXPECT_LT(ep.port(0).carriage_mm(), 21.0);
  ep.advance_to(0.5);
  ASSERT_FALSE(ep.faulted()) << ep.fault();
  EXPECT_EQ(ep.periods(), 5000u);
  EXPECT_NEAR(ep.port(0).carriage_mm(), 21.06, 0.01);
  EXPECT_NEAR(ep.port(1).carriage_mm(), 80.0, 1e-6);
}

}  // namespace
}  // namespace feedloop::plant2
