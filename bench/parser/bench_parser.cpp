// bench_parser: how fast the G-code front end turns files into Commands. Each file is read in
// 64 KiB chunks (gcode/file_lines.hpp), split into lines and parsed into one reused Command,
// exactly as batch mode does; best wall time of 3 runs. Prints a table; --json FILE writes it.
// Usage: bench_parser [--json FILE] [FILES...]
//   default files: ../shared/gcode/*.gcode next to the source tree, plus the LARGE .xz file
//   decompressed to a temporary folder when `xz` is available.
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bench_json.hpp"
#include "gcode/file_lines.hpp"
#include "gcode/parser.hpp"

namespace fs = std::filesystem;
using namespace feedloop;
using namespace feedloop::gcode;

namespace {

struct Row {
  std::string name;
  double size_mb = 0;
  int64_t lines = 0;
  int64_t commands = 0;
  int64_t errors = 0;
  double wall_s = 0;
  double cpu_s = 0;  // CPU time of this thread in the best run (robust on a loaded machine)
};

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// One pass over the file; returns false when it cannot be read.
bool run_once(const std::string& path, Row& row) {
  Command cmd;
  SourceLocation where{fs::path(path).filename().string(), 0, 0};
  int64_t lines = 0, commands = 0, errors = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = thread_cpu_s();
  Status st = for_each_file_line(path, [&](const SplitLine& line) {
    ++lines;
    where.line = static_cast<int>(line.number);
    if (line.too_long) {
      ++errors;
      return;
    }
    if (!parse_line(line.text, where, cmd)) ++errors;
    else if (!cmd.empty()) ++commands;
  });
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu = thread_cpu_s() - c0;
  if (!st) {
    std::fprintf(stderr, "%s\n", st.error().to_string().c_str());
    return false;
  }
  row.lines = lines;
  row.commands = commands;
  row.errors = errors;
  row.wall_s = row.wall_s == 0 ? wall : std::min(row.wall_s, wall);
  row.cpu_s = row.cpu_s == 0 ? cpu : std::min(row.cpu_s, cpu);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::string json_path;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--json" && i + 1 < argc) json_path = argv[++i];
    else if (a == "-h" || a == "--help") {
      std::printf("usage: bench_parser [--json FILE] [FILES...]\n");
      return 0;
    } else files.push_back(a);
  }
  fs::path temp_dir;
  if (files.empty()) {
    const fs::path corpus = fs::path(FEEDLOOP_SOURCE_DIR) / ".." / "shared" / "gcode";
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(corpus, ec))
      if (e.path().extension() == ".gcode") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    if (files.empty()) {
      std::fprintf(stderr, "no corpus at %s; pass G-code files as arguments\n",
                   corpus.string().c_str());
      return 1;
    }
    const fs::path large = corpus / "benchy_x12_cartesian_LARGE.gcode.xz";
    if (fs::exists(large) && std::system("xz --version > /dev/null 2>&1") == 0) {
      char tmpl[] = "/tmp/bench_parser.XXXXXX";
      if (char* d = ::mkdtemp(tmpl)) {
        temp_dir = d;
        const fs::path out = temp_dir / "benchy_x12_cartesian_LARGE.gcode";
        const std::string cmd = "xz -dc '" + large.string() + "' > '" + out.string() + "'";
        if (std::system(cmd.c_str()) == 0) files.push_back(out.string());
      }
    }
  }

  std::vector<Row> rows;
  int status = 0;
  std::printf("%-42s %8s %9s %7s %8s %12s %8s %8s %16s\n", "file", "size_MB", "lines", "errors",
              "wall_s", "lines_per_s", "MB_per_s", "cpu_s", "lines_per_cpu_s");
  for (const auto& f : files) {
    Row row;
    row.name = fs::path(f).filename().string();
    std::error_code ec;
    row.size_mb = static_cast<double>(fs::file_size(f, ec)) / 1e6;
    bool ok = true;
    for (int rep = 0; rep < 3 && ok; ++rep) ok = run_once(f, row);
    if (!ok) {
      status = 1;
      continue;
    }
    std::printf("%-42s %8.2f %9lld %7lld %8.4f %12.0f %8.1f %8.4f %16.0f\n", row.name.c_str(),
                row.size_mb, static_cast<long long>(row.lines), static_cast<long long>(row.errors),
                row.wall_s, static_cast<double>(row.lines) / row.wall_s, row.size_mb / row.wall_s,
                row.cpu_s, static_cast<double>(row.lines) / row.cpu_s);
    rows.push_back(row);
  }
  if (!temp_dir.empty()) fs::remove_all(temp_dir);

  if (!json_path.empty()) {
    nlohmann::json out = {{"benchmark", "parser"},
                          {"repeats", 3},
                          {"statistic", "best"},
                          {"files", nlohmann::json::array()}};
    for (const Row& r : rows)
      out["files"].push_back({{"file", r.name},
                              {"size_mb", r.size_mb},
                              {"lines", r.lines},
                              {"commands", r.commands},
                              {"errors", r.errors},
                              {"wall_s", r.wall_s},
                              {"lines_per_s", static_cast<double>(r.lines) / r.wall_s},
                              {"mb_per_s", r.size_mb / r.wall_s},
                              {"cpu_s", r.cpu_s},
                              {"lines_per_cpu_s", static_cast<double>(r.lines) / r.cpu_s}});
    if (!feedloop::bench::write_json(json_path, out)) return 1;
  }
  return status;
}
