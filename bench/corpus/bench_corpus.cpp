// bench_corpus: does the default printer slip? Every file of the public G-code corpus
// (../shared/gcode, its README) printed on the simulated printer of its config, in virtual time,
// two ways (issue 13 item 6):
//   batch   engine::run_simulated, what `feedloop batch FILE --simulate` runs (one thread);
//   daemon  a fresh `feedloopd --virtual-time`, the file streamed by `feedloop print` as a user
//           would, then the machine's figures read from the JSON status;
//   realtime the same on the wall clock (not in the default ways: it takes the print's own time;
//           `--only cube20 --ways batch,realtime` compares the real-time daemon's e_t with batch
//           mode's, issue 13: within 10 %).
// Per file and way: lines, lost-step events, e_t from the encoders (mean, max), faults, rejected
// lines, steps the plant lost (batch: the simulator's ground truth), the device loops' |e| max and
// tick cost, print time and wall time. Cartesian files run on the embedded default
// (config/examples/cartesian_sim.yaml), `*delta*` files on config/examples/delta_sim.yaml,
// `*corexy*` files on config/examples/corexy_sim.yaml (none in the corpus today).
//
//   build/bench/corpus/bench_corpus [--corpus DIR] [--only SUBSTRING] [--ways
//   batch,daemon,realtime]
//        [--large] [--feedloopd PATH] [--feedloop PATH] [--json FILE]
// --large also unpacks benchy_x12_cartesian_LARGE.gcode.xz into a temporary directory (xz) and
// runs it (1.8 M lines, about 12 times the benchy). Exit status 1 when any run slipped, faulted
// or rejected a line.
#include <fcntl.h>       // open
#include <poll.h>        // poll
#include <signal.h>      // kill
#include <sys/socket.h>  // socket
#include <sys/un.h>      // sockaddr_un
#include <sys/wait.h>    // waitpid
#include <unistd.h>      // fork, execv

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "config/config.hpp"
#include "engine/config_mapping.hpp"
#include "engine/sim_run.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

double since_s(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

struct Args {
  std::string corpus = std::string(FEEDLOOP_SHARED_DIR) + "/gcode";
  std::string only;
  bool batch = true, daemon = true, realtime = false, large = false;
  std::string json_path;
  std::string feedloopd = FEEDLOOPD_PATH, feedloop = FEEDLOOP_PATH;
};

// One file, one way.
struct Row {
  std::string file, machine, way;
  uint64_t lines = 0, rejected = 0, lost_step_events = 0, faults = 0;
  int64_t lost_full_steps = -1;  // batch only (the plant's ground truth); -1: not known
  double et_mean_mm = 0.0, et_max_mm = 0.0, print_s = 0.0, wall_s = 0.0;
  double loop_abs_e_max_mm = 0.0, loop_tick_mean_us = 0.0;  // worst joint's device loop
  std::string error;
  bool clean() const {
    return error.empty() && rejected == 0 && lost_step_events == 0 && faults == 0 &&
           lost_full_steps <= 0;
  }
};

// The machine a corpus file was sliced for: its config (empty: the embedded default).
std::string config_for(const std::string& name) {
  if (name.find("delta") != std::string::npos)
    return std::string(FEEDLOOP_SOURCE_DIR) + "/config/examples/delta_sim.yaml";
  if (name.find("corexy") != std::string::npos)
    return std::string(FEEDLOOP_SOURCE_DIR) + "/config/examples/corexy_sim.yaml";
  return {};
}

std::string machine_name(const std::string& config_path) {
  return config_path.empty() ? "cartesian_sim (default)" : fs::path(config_path).stem().string();
}

std::vector<std::string> read_lines(const std::string& path) {
  std::vector<std::string> out;
  std::ifstream in(path);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

void fold_loops(const feedloop::engine::DeviceLoopTelemetrySet& set, Row& r) {
  for (const auto& t : set) {
    if (!t.enabled) continue;
    r.loop_abs_e_max_mm = std::max(r.loop_abs_e_max_mm, t.max_abs_e_mm);
    r.loop_tick_mean_us = std::max(r.loop_tick_mean_us, t.mean_tick_cost_us());
  }
}

Row run_batch(const std::string& file, const std::string& config_path) {
  Row r;
  r.way = "batch";
  auto cfg =
      config_path.empty()
          ? feedloop::Result<feedloop::config::MachineConfig>(feedloop::config::default_config())
          : feedloop::config::load_config_file(config_path);
  if (!cfg) {
    r.error = cfg.error().to_string();
    return r;
  }
  const std::vector<std::string> lines = read_lines(file);
  r.lines = lines.size();
  feedloop::engine::SimRunOptions o;
  o.keep_samples = false;
  o.timeout_s = 1e7;
  const auto t0 = Clock::now();
  auto s = feedloop::engine::run_simulated(*cfg, lines, o);
  r.wall_s = since_s(t0);
  if (!s) {
    r.error = s.error().to_string();
    return r;
  }
  r.rejected = s->rejected;
  r.lost_step_events = s->lost_step_events;
  r.faults = s->faults;
  r.lost_full_steps = 0;
  for (int64_t n : s->lost_full_steps) r.lost_full_steps += n;
  r.et_mean_mm = s->tracking_error_mean_mm;
  r.et_max_mm = s->tracking_error_max_mm;
  r.print_s = s->motion_time_s;
  fold_loops(s->device_loops, r);
  r.error = s->error;
  return r;
}

// A blocking line connection to a Unix socket.
class Conn {
 public:
  ~Conn() {
    if (fd_ >= 0) ::close(fd_);
  }
  bool connect(const std::string& path, double timeout_s) {
    const auto t0 = Clock::now();
    while (since_s(t0) < timeout_s) {
      fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
      sockaddr_un addr{};
      addr.sun_family = AF_UNIX;
      std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
      if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return true;
      ::close(fd_);
      fd_ = -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  std::optional<json> status() {
    const std::string req = "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"status\"}\n";
    if (::send(fd_, req.data(), req.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(req.size()))
      return std::nullopt;
    const auto t0 = Clock::now();
    while (since_s(t0) < 10.0) {
      if (const size_t nl = buf_.find('\n'); nl != std::string::npos) {
        json j = json::parse(buf_.substr(0, nl), nullptr, false);
        buf_.erase(0, nl + 1);
        if (!j.is_discarded() && j.contains("result")) return j["result"];
        continue;
      }
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      char chunk[65536];
      const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
      if (n <= 0) return std::nullopt;
      buf_.append(chunk, static_cast<size_t>(n));
    }
    return std::nullopt;
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

pid_t spawn(const std::vector<std::string>& argv, const std::string& dir, const std::string& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::setenv("RUNTIME_DIRECTORY", dir.c_str(), 1);
    ::setenv("STATE_DIRECTORY", dir.c_str(), 1);
    std::vector<char*> a;
    for (const std::string& s : argv) a.push_back(const_cast<char*>(s.c_str()));
    a.push_back(nullptr);
    ::execv(a[0], a.data());
    ::_exit(127);
  }
  return pid;
}

std::string tail(const std::string& path, size_t bytes) {
  std::ifstream f(path);
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  return text.size() > bytes ? text.substr(text.size() - bytes) : text;
}

Row run_daemon(const Args& a, const std::string& file, const std::string& config_path,
               bool virtual_time) {
  Row r;
  r.way = virtual_time ? "daemon" : "realtime";
  r.lines = read_lines(file).size();
  std::string tmpl = (fs::temp_directory_path() / "feedloop-bench-corpus-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) {
    r.error = "mkdtemp failed";
    return r;
  }
  const std::string dir = tmpl;
  std::vector<std::string> dargs{a.feedloopd, "--log-level", "warn"};
  if (virtual_time) dargs.push_back("--virtual-time");
  if (!config_path.empty()) dargs.insert(dargs.end(), {"--config", config_path});
  const pid_t daemon = spawn(dargs, dir, dir + "/feedloopd.log");
  const auto t0 = Clock::now();
  Conn api;
  if (!api.connect(dir + "/api.sock", 10.0)) {
    r.error = "feedloopd did not start: " + tail(dir + "/feedloopd.log", 300);
  } else {
    const pid_t client =
        spawn({a.feedloop, "print", fs::absolute(file).string()}, dir, dir + "/print.log");
    int st = 0;
    ::waitpid(client, &st, 0);
    r.wall_s = since_s(t0);
    // feedloop print returns once the machine has finished (it waits for the status to leave
    // "busy"); exit 3: lines were rejected (counted below from the status).
    if (!WIFEXITED(st) || (WEXITSTATUS(st) != 0 && WEXITSTATUS(st) != 3))
      r.error = "feedloop print failed: " + tail(dir + "/print.log", 300);
    if (auto s = api.status()) {
      const json& m = (*s)["motion"];
      r.rejected = (*s)["commands"]["rejected"].get<uint64_t>();
      r.lost_step_events = m["lost_step_events"].get<uint64_t>();
      r.et_mean_mm = m["tracking_error_mm"]["mean"].get<double>();
      r.et_max_mm = m["tracking_error_mm"]["max"].get<double>();
      r.print_s = m["planned_until_s"].get<double>();
      for (const auto& [name, l] : m["device_loops"].items()) {
        r.loop_abs_e_max_mm = std::max(r.loop_abs_e_max_mm, l["abs_e_mm"]["max"].get<double>());
        r.loop_tick_mean_us =
            std::max(r.loop_tick_mean_us, l["tick_cost_us"]["mean"].get<double>());
      }
      const std::string fault = (*s)["last_error"].get<std::string>();
      if (!fault.empty()) {
        r.faults = 1;
        if (r.error.empty()) r.error = fault;
      }
    } else if (r.error.empty()) {
      r.error = "no status from feedloopd";
    }
  }
  ::kill(daemon, SIGTERM);
  int st = 0;
  ::waitpid(daemon, &st, 0);
  std::error_code ec;
  if (r.error.empty())
    fs::remove_all(dir, ec);
  else
    r.error += " (logs kept in " + dir + ")";
  return r;
}

void print_row(const Row& r) {
  std::printf("%-42s %-24s %-6s %8llu %6llu %8llu %9.4f %9.4f %6llu %7s %9.4f %8.2f %8.0f %8.1f\n",
              r.file.c_str(), r.machine.c_str(), r.way.c_str(),
              static_cast<unsigned long long>(r.lines), static_cast<unsigned long long>(r.rejected),
              static_cast<unsigned long long>(r.lost_step_events), r.et_mean_mm, r.et_max_mm,
              static_cast<unsigned long long>(r.faults),
              r.lost_full_steps < 0 ? "-" : std::to_string(r.lost_full_steps).c_str(),
              r.loop_abs_e_max_mm, r.loop_tick_mean_us, r.print_s, r.wall_s);
  if (!r.error.empty()) std::printf("    error: %s\n", r.error.c_str());
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--corpus" && i + 1 < argc)
      a.corpus = argv[++i];
    else if (s == "--only" && i + 1 < argc)
      a.only = argv[++i];
    else if (s == "--json" && i + 1 < argc)
      a.json_path = argv[++i];
    else if (s == "--large")
      a.large = true;
    else if (s == "--feedloopd" && i + 1 < argc)
      a.feedloopd = argv[++i];
    else if (s == "--feedloop" && i + 1 < argc)
      a.feedloop = argv[++i];
    else if (s == "--ways" && i + 1 < argc) {
      const std::string w = argv[++i];
      a.batch = w.find("batch") != std::string::npos;
      a.daemon = w.find("daemon") != std::string::npos;
      a.realtime = w.find("realtime") != std::string::npos;
    } else {
      std::fprintf(stderr,
                   "usage: bench_corpus [--corpus DIR] [--only SUBSTRING] [--ways "
                   "batch,daemon,realtime] [--large] "
                   "[--feedloopd PATH] [--feedloop PATH] [--json FILE]\n");
      return 2;
    }
  }
  if (!fs::is_directory(a.corpus)) {
    std::fprintf(stderr,
                 "bench_corpus: no G-code corpus at %s (the public corpus, ../shared/gcode)\n",
                 a.corpus.c_str());
    return 2;
  }
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(a.corpus))
    if (e.path().extension() == ".gcode" &&
        e.path().filename().string().find(a.only) != std::string::npos)
      files.push_back(e.path());
  std::sort(files.begin(), files.end());
  std::string large_dir;
  if (a.large) {
    const fs::path xz = fs::path(a.corpus) / "benchy_x12_cartesian_LARGE.gcode.xz";
    std::string tmpl = (fs::temp_directory_path() / "feedloop-bench-large-XXXXXX").string();
    if (!fs::exists(xz) || ::mkdtemp(tmpl.data()) == nullptr) {
      std::fprintf(stderr, "bench_corpus: cannot unpack %s\n", xz.string().c_str());
      return 2;
    }
    large_dir = tmpl;
    const std::string out = large_dir + "/benchy_x12_cartesian_LARGE.gcode";
    const std::string cmd = "xz -dc '" + xz.string() + "' > '" + out + "'";
    if (std::system(cmd.c_str()) != 0) {
      std::fprintf(stderr, "bench_corpus: '%s' failed\n", cmd.c_str());
      return 2;
    }
    files.push_back(out);
  }

  std::printf(
      "bench_corpus: every corpus file on the simulated printer of its config (batch, daemon: "
      "virtual "
      "time; realtime: the wall clock)\n");
  std::printf("%-42s %-24s %-6s %8s %6s %8s %9s %9s %6s %7s %9s %8s %8s %8s\n", "file", "machine",
              "way", "lines", "rej", "lost-stp", "e_t mean", "e_t max", "faults", "plant",
              "loop |e|", "tick us", "print s", "wall s");
  std::vector<Row> rows;
  for (const fs::path& f : files) {
    const std::string cfg = config_for(f.filename().string());
    if (!cfg.empty() && !fs::exists(cfg)) {
      Row r;
      r.file = f.filename().string();
      r.machine = machine_name(cfg);
      r.way = "-";
      r.error = "no config for this machine type (" + cfg + ")";
      print_row(r);
      rows.push_back(r);
      continue;
    }
    for (int way = 0; way < 3; ++way) {
      if ((way == 0 && !a.batch) || (way == 1 && !a.daemon) || (way == 2 && !a.realtime)) continue;
      Row r = way == 0 ? run_batch(f.string(), cfg) : run_daemon(a, f.string(), cfg, way == 1);
      r.file = f.filename().string();
      r.machine = machine_name(cfg);
      print_row(r);
      rows.push_back(r);
    }
  }
  if (!large_dir.empty()) {
    std::error_code ec;
    fs::remove_all(large_dir, ec);
  }
  // The real-time daemon against batch mode (virtual time), file by file.
  for (const Row& rt : rows) {
    if (rt.way != "realtime") continue;
    for (const Row& b : rows)
      if (b.way == "batch" && b.file == rt.file && b.et_mean_mm > 0)
        std::printf(
            "%s: e_t real-time daemon / batch: mean %.4f / %.4f mm = %.3f, max %.4f / %.4f mm = "
            "%.3f\n",
            rt.file.c_str(), rt.et_mean_mm, b.et_mean_mm, rt.et_mean_mm / b.et_mean_mm,
            rt.et_max_mm, b.et_max_mm, b.et_max_mm > 0 ? rt.et_max_mm / b.et_max_mm : 0.0);
  }
  const bool all_clean =
      std::all_of(rows.begin(), rows.end(), [](const Row& r) { return r.clean(); });
  std::printf(
      "columns: rej = rejected lines; lost-stp = lost-step events detected (and made up); e_t = "
      "tracking\n"
      "error from the encoders (mm); faults = encoder/following-error trips, MCU faults; plant = "
      "full\n"
      "steps the simulated motors lost (batch only); loop |e| = the device loops' largest |r - y| "
      "at\n"
      "their 100 Hz reports (mm); tick us = their mean cost per tick (us of host CPU)\n");
  std::printf("%s\n", all_clean ? "ALL CLEAN: no lost step, no fault, no rejected line"
                                : "NOT CLEAN: see the rows above");
  if (!a.json_path.empty()) {
    json j = json::array();
    for (const Row& r : rows)
      j.push_back({{"file", r.file},
                   {"machine", r.machine},
                   {"way", r.way},
                   {"lines", r.lines},
                   {"rejected", r.rejected},
                   {"lost_step_events", r.lost_step_events},
                   {"tracking_error_mm", {{"mean", r.et_mean_mm}, {"max", r.et_max_mm}}},
                   {"faults", r.faults},
                   {"plant_lost_full_steps", r.lost_full_steps},
                   {"device_loop_abs_e_max_mm", r.loop_abs_e_max_mm},
                   {"device_loop_tick_mean_us", r.loop_tick_mean_us},
                   {"print_s", r.print_s},
                   {"wall_s", r.wall_s},
                   {"error", r.error}});
    if (!feedloop::bench::write_json(a.json_path, j)) return 1;
  }
  return all_clean ? 0 : 1;
}
