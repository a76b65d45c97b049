// Starts feedloop-vmcu as a child process and reads the pty path it prints; stops it (by its
// pid) when destroyed. Shared by the serial end-to-end test and bench/protocol.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <string>
#include <vector>

extern char** environ;

namespace feedloop::testing {

class VmcuProcess {
 public:
  // Returns false (with a message in error()) when the program cannot be started. With
  // stderr_path, the program's stderr (its summary at exit) goes to that file.
  bool start(const std::string& program, const std::vector<std::string>& extra_args,
             const std::string& stderr_path = {}) {
    int fds[2];
    if (::pipe(fds) != 0) return fail("pipe failed");
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
    posix_spawn_file_actions_addclose(&fa, fds[0]);
    if (!stderr_path.empty())
      posix_spawn_file_actions_addopen(&fa, 2, stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<std::string> args{program, "--pty"};
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = ::posix_spawn(&pid_, program.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(fds[1]);
    if (rc != 0) {
      ::close(fds[0]);
      pid_ = -1;
      return fail("cannot start " + program);
    }
    FILE* out = ::fdopen(fds[0], "r");
    char line[256] = {};
    const bool got = std::fgets(line, sizeof line, out) != nullptr;
    std::fclose(out);
    std::string s = got ? line : "";
    if (s.rfind("PTY ", 0) != 0) return fail("feedloop-vmcu printed no PTY line");
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
    pty_ = s.substr(4);
    return true;
  }
  // SIGTERM: the program prints its summary and exits. SIGKILL: a device losing power.
  void stop(int sig = SIGTERM) {
    if (pid_ > 0) {
      ::kill(pid_, sig);
      int status = 0;
      ::waitpid(pid_, &status, 0);
      pid_ = -1;
    }
  }
  ~VmcuProcess() { stop(); }
  const std::string& pty() const { return pty_; }
  const std::string& error() const { return error_; }

 private:
  bool fail(std::string m) {
    error_ = std::move(m);
    return false;
  }
  pid_t pid_ = -1;
  std::string pty_, error_;
};

}  // namespace feedloop::testing
