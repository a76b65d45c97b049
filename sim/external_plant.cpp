#include "sim/external_plant.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace feedloop::sim {
namespace {

constexpr double kTimeEps_s = 1e-12;

double monotonic_s() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

// A line from the plant as printable text for a message (at most 60 characters).
std::string quote(const char* s, size_t n) {
  std::string out = "'";
  for (size_t i = 0; i < n && i < 60; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7F) {
      out += static_cast<char>(c);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", c);
      out += hex;
    }
  }
  if (n > 60) out += "...";
  return out + "'";
}

}  // namespace

// ---- ExternalAxisPort ---------------------------------------------------------------------------

ExternalAxisPort::ExternalAxisPort(ExternalPlant& owner, const ExternalAxisParams& p, double period_s)
    : owner_(&owner),
      mm_per_step_(p.mm_per_step),
      start_mm_(p.start_mm),
      y_mm_(p.start_mm),
      encoder_(p.encoder, p.seed),
      history_(static_cast<size_t>(p.encoder.sampling_delay_s / period_s) + 8),
      delay_s_(p.encoder.sampling_delay_s) {
  history_.clear(0.0, p.start_mm);
}

void ExternalAxisPort::step(double t_s, int direction) {
  owner_->advance_to(t_s);  // the periods before this step see the staircase without it
  steps_ += direction >= 0 ? 1 : -1;
}

void ExternalAxisPort::set_enabled(double t_s, bool /*enabled*/) {
  // The contract carries positions only: the plant decides what a disabled driver does.
  owner_->advance_to(t_s);
}

int64_t ExternalAxisPort::read_encoder_counts(double t_s) {
  owner_->advance_to(t_s);
  const double y_mm = delay_s_ > 0.0 ? history_.value_at(t_s - delay_s_) : y_mm_;
  return encoder_.counts(y_mm - start_mm_);
}

// ---- ExternalPlant ------------------------------------------------------------------------------

ExternalPlant::ExternalPlant(const ExternalPlantParams& p) : params_(p) {
  // One line: the time and n numbers of up to ~30 characters each.
  const size_t line_cap = 64 + 32 * p.axes.size();
  out_.resize(line_cap);
  in_.resize(4 * line_cap + 4096);
  line_.resize(in_.size() + 1);
}

Result<std::unique_ptr<ExternalPlant>> ExternalPlant::start(const ExternalPlantParams& p) {
  if (p.command.empty()) return Error{"external plant: the command is empty"};
  if (p.axes.empty()) return Error{"external plant: no axes"};
  if (!(p.period_s > 0.0)) return Error{"external plant: the period must be > 0"};
  for (const ExternalAxisParams& a : p.axes) {
    if (!(a.mm_per_step > 0.0)) return Error{"external plant: axis " + a.name + ": mm per step must be > 0"};
    if (Status s = validate(a.encoder); !s) return Error{"external plant: axis " + a.name + ": " + s.error().message};
  }
  std::unique_ptr<ExternalPlant> plant(new ExternalPlant(p));
  ExternalPlant& e = *plant;
  for (const ExternalAxisParams& a : p.axes)
    e.ports_.push_back(std::unique_ptr<ExternalAxisPort>(new ExternalAxisPort(e, a, p.period_s)));

  int in_pipe[2], out_pipe[2];
  if (::pipe2(in_pipe, O_CLOEXEC) != 0) return Error{std::string("external plant: pipe: ") + std::strerror(errno)};
  if (::pipe2(out_pipe, O_CLOEXEC) != 0) {
    ::close(in_pipe[0]);
    ::close(in_pipe[1]);
    return Error{std::string("external plant: pipe: ") + std::strerror(errno)};
  }
  const pid_t pid = ::fork();
  if (pid < 0) {
    for (int fd : {in_pipe[0], in_pipe[1], out_pipe[0], out_pipe[1]}) ::close(fd);
    return Error{std::string("external plant: fork: ") + std::strerror(errno)};
  }
  if (pid == 0) {  // child: only async-signal-safe calls until exec
    ::setpgid(0, 0);  // its own process group: the shell and what it starts end together
    ::dup2(in_pipe[0], 0);
    ::dup2(out_pipe[1], 1);
    ::signal(SIGPIPE, SIG_DFL);
    ::execl("/bin/sh", "sh", "-c", p.command.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ::close(in_pipe[0]);
  ::close(out_pipe[1]);
  e.pid_ = pid;
  e.to_plant_ = in_pipe[1];
  e.from_plant_ = out_pipe[0];

  // Handshake: "feedloop-plant 1 axes=x,y period_s=0.0001" -> "ready".
  std::string hello = "feedloop-plant 1 axes=";
  for (size_t i = 0; i < p.axes.size(); ++i) hello += (i ? "," : "") + p.axes[i].name;
  char period[48];
  std::snprintf(period, sizeof period, " period_s=%.9g\n", p.period_s);
  hello += period;
  if (!e.write_all(hello.data(), hello.size()) || !e.read_line("the handshake's 'ready'", p.handshake_timeout_s))
    return Error{e.fault_};
  size_t n = std::strlen(e.line_.data());
  while (n > 0 && (e.line_[n - 1] == '\r' || e.line_[n - 1] == ' ')) --n;
  if (n != 5 || std::strncmp(e.line_.data(), "ready", 5) != 0)
    return Error{"external plant '" + p.command + "' answered the handshake with " + quote(e.line_.data(), n) +
                 " instead of 'ready'"};
  e.next_end_s_ = p.period_s;
  return plant;
}

ExternalPlant::~ExternalPlant() {
  if (to_plant_ >= 0) ::close(to_plant_);  // end of input: the plant exits
  if (pid_ > 0) {
    int status = 0;
    const double deadline = monotonic_s() + 1.0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (monotonic_s() > deadline) {
        ::kill(-pid_, SIGKILL);  // the process group: /bin/sh and the plant it started
        ::waitpid(pid_, &status, 0);
        break;
      }
      ::usleep(1000);
    }
  }
  if (from_plant_ >= 0) ::close(from_plant_);
}

void ExternalPlant::set_fault(const std::string& message) {
  if (fault_.empty()) fault_ = message;
}

bool ExternalPlant::write_all(const char* data, size_t n) {
  // A plant that has exited turns write() into SIGPIPE: block it on this thread for the call and
  // take the pending signal back, so that only the error remains (EPIPE).
  sigset_t pipe_set, old_set;
  sigemptyset(&pipe_set);
  sigaddset(&pipe_set, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe_set, &old_set);
  bool ok = true;
  int err = 0;
  while (n > 0) {
    const ssize_t w = ::write(to_plant_, data, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      ok = false;
      err = errno;
      break;
    }
    data += w;
    n -= static_cast<size_t>(w);
  }
  if (!ok && err == EPIPE) {
    const timespec zero{0, 0};
    while (sigtimedwait(&pipe_set, nullptr, &zero) > 0) {
    }
  }
  pthread_sigmask(SIG_SETMASK, &old_set, nullptr);
  if (!ok) {
    int status = 0;
    char why[160];
    if (err == EPIPE && ::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      std::snprintf(why, sizeof why, "exited (%s %d)", WIFEXITED(status) ? "status" : "signal",
                    WIFEXITED(status) ? WEXITSTATUS(status) : WTERMSIG(status));
    } else {
      std::snprintf(why, sizeof why, "could not be written to: %s", std::strerror(err));
    }
    char at[64];
    std::snprintf(at, sizeof at, " at t = %.6f s", next_end_s_);
    set_fault("external plant '" + params_.command + "' " + why + at + "; the machine stopped");
  }
  return ok;
}

bool ExternalPlant::read_line(const char* waiting_for, double timeout_s) {
  const double deadline = monotonic_s() + timeout_s;
  for (;;) {
    if (void* nl = std::memchr(in_.data(), '\n', in_len_)) {
      const size_t n = static_cast<size_t>(static_cast<char*>(nl) - in_.data());
      std::memcpy(line_.data(), in_.data(), n);
      line_[n] = '\0';
      std::memmove(in_.data(), in_.data() + n + 1, in_len_ - n - 1);
      in_len_ -= n + 1;
      return true;
    }
    char at[64];
    std::snprintf(at, sizeof at, " (at t = %.6f s)", next_end_s_);
    if (in_len_ == in_.size()) {
      set_fault("external plant '" + params_.command + "': a line longer than " + std::to_string(in_.size()) +
                " bytes while waiting for " + waiting_for + at + ": " + quote(in_.data(), in_len_) +
                "; the machine stopped");
      return false;
    }
    const double left_s = deadline - monotonic_s();
    if (left_s <= 0.0) {
      char secs[32];
      std::snprintf(secs, sizeof secs, "%.3g", timeout_s);
      set_fault("external plant '" + params_.command + "' did not answer within " + secs + " s while feedloop waited for " +
                waiting_for + at + "; the machine stopped");
      return false;
    }
    pollfd pfd{from_plant_, POLLIN, 0};
    const int r = ::poll(&pfd, 1, static_cast<int>(std::ceil(left_s * 1e3)));
    if (r < 0 && errno == EINTR) continue;
    if (r == 0) continue;  // the deadline check above reports it
    const ssize_t got = ::read(from_plant_, in_.data() + in_len_, in_.size() - in_len_);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      int status = 0;
      std::string how = "closed its output";
      if (::waitpid(pid_, &status, 0) == pid_) {
        pid_ = -1;
        how = WIFEXITED(status) ? "exited with status " + std::to_string(WEXITSTATUS(status))
                                : "was killed by signal " + std::to_string(WTERMSIG(status));
      }
      set_fault("external plant '" + params_.command + "' " + how + " while feedloop waited for " + waiting_for + at +
                "; the machine stopped");
      return false;
    }
    in_len_ += static_cast<size_t>(got);
  }
}

void ExternalPlant::exchange_period() {
  // "t_s u_1 ... u_n": %.12g keeps at least 9 significant digits of every value.
  int len = std::snprintf(out_.data(), out_.size(), "%.12g", next_end_s_);
  for (const auto& p : ports_)
    len += std::snprintf(out_.data() + len, out_.size() - static_cast<size_t>(len), " %.12g", p->commanded_mm());
  out_[static_cast<size_t>(len)] = '\n';
  if (!write_all(out_.data(), static_cast<size_t>(len) + 1)) return;
  if (!read_line("the answer to a period", params_.answer_timeout_s)) return;
  // "y_1 ... y_n": exactly n finite decimals.
  const char* s = line_.data();
  char* end = nullptr;
  for (size_t i = 0; i < ports_.size(); ++i) {
    errno = 0;
    const double y = std::strtod(s, &end);
    if (end == s || errno == ERANGE || !std::isfinite(y)) {
      char at[96];
      std::snprintf(at, sizeof at, " at t = %.6f s: expected %zu numbers, got ", next_end_s_, ports_.size());
      set_fault("external plant '" + params_.command + "' answered a malformed line" + at +
                quote(line_.data(), std::strlen(line_.data())) + "; the machine stopped");
      return;
    }
    ports_[i]->y_mm_ = y;
    s = end;
  }
  while (*s == ' ' || *s == '\t' || *s == '\r') ++s;
  if (*s != '\0') {
    char at[96];
    std::snprintf(at, sizeof at, " at t = %.6f s: expected %zu numbers, got ", next_end_s_, ports_.size());
    set_fault("external plant '" + params_.command + "' answered a malformed line" + at +
              quote(line_.data(), std::strlen(line_.data())) + "; the machine stopped");
    return;
  }
  for (const auto& p : ports_) p->history_.push(next_end_s_, p->y_mm_);
  ++periods_;
  next_end_s_ = params_.period_s * static_cast<double>(periods_ + 1);
}

void ExternalPlant::advance_to(double t_s) {
  while (fault_.empty() && next_end_s_ <= t_s + kTimeEps_s) exchange_period();
}

}  // namespace feedloop::sim
