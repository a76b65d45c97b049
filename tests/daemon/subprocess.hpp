// Test helper: runs a program as a child process with its output captured to a file.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace feedloop::testing {

class Subprocess {
 public:
  // Starts argv[0] with the given arguments and extra environment ("K=V"); stdout and stderr go
  // to `log_path`; stdin is a pipe the test may write to.
  Subprocess(const std::vector<std::string>& argv, const std::vector<std::string>& env,
             const std::string& log_path)
      : log_path_(log_path) {
    int in[2];
    if (::pipe(in) != 0) return;
    // Emptied here, before the child exists: truncated by the child, a reused log could still show
    // the previous process's "ready" to wait_for_output (a flake under load).
    if (const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644); fd >= 0) ::close(fd);
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(in[0], 0);
      ::close(in[1]);
      const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      for (const std::string& e : env) ::putenv(const_cast<char*>(e.c_str()));
      std::vector<char*> args;
      for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      ::execvp(args[0], args.data());
      ::_exit(127);
    }
    ::close(in[0]);
    stdin_fd_ = in[1];
  }
  ~Subprocess() {
    if (stdin_fd_ >= 0) ::close(stdin_fd_);
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  bool started() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }
  void write_stdin(const std::string& s) {
    if (stdin_fd_ >= 0 && ::write(stdin_fd_, s.data(), s.size()) < 0) {
    }
  }
  void close_stdin() {
    if (stdin_fd_ >= 0) ::close(stdin_fd_);
    stdin_fd_ = -1;
  }
  void signal(int sig) { ::kill(pid_, sig); }
  // Exit code, or -1 on timeout, or 128+signal.
  int wait(double timeout_s) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < deadline) {
      int st = 0;
      const pid_t r = ::waitpid(pid_, &st, WNOHANG);
      if (r == pid_) {
        exited_ = true;
        return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return -1;
  }
  std::string output() const {
    std::ifstream f(log_path_);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }
  // Waits until the output contains `text`.
  bool wait_for_output(const std::string& text, double timeout_s) const {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < deadline) {
      if (output().find(text) != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }

 private:
  std::string log_path_;
  pid_t pid_ = -1;
  int stdin_fd_ = -1;
  bool exited_ = false;
};

}  // namespace feedloop::testing
