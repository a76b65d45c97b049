// gnuplot driver for the identification report (see plots.hpp).
#include "ident/plots.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>

extern char** environ;

namespace feedloop::ident {
namespace {

// Runs `program args...` with stdout/stderr to `log_path` (or /dev/null); exit status, or -1 when
// it could not be started.
int run_program(const std::string& program, const std::vector<std::string>& args, const std::string& log_path) {
  std::vector<std::string> argv_s;
  argv_s.push_back(program);
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  const std::string out = log_path.empty() ? "/dev/null" : log_path;
  posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, program.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) return -1;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
  }
  if (!WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

std::string read_first_line(const std::string& path) {
  std::ifstream f(path);
  std::string line;
  std::getline(f, line);
  return line;
}

}  // namespace

std::string gnuplot_quote(const std::string& s) {
  std::string o = "'";
  for (char c : s) {
    if (c == '\'') o += "''";
    else o += c;
  }
  return o + "'";
}

std::string find_gnuplot() {
  std::string program = "gnuplot";
  if (const char* env = std::getenv("FEEDLOOP_GNUPLOT"); env != nullptr) program = env;
  if (program.empty()) return "";
  return run_program(program, {"--version"}, "") == 0 ? program : "";
}

PlotOutcome draw_plots(const std::string& dir, const std::vector<PlotSpec>& plots) {
  PlotOutcome out;
  const std::string gnuplot = find_gnuplot();
  if (gnuplot.empty()) {
    out.note = "plots not drawn: gnuplot was not found (install gnuplot-nox); their data files are in this "
               "directory and each plot's gnuplot script (*.gp) can be run later";
  }
  std::error_code ec;
  const std::filesystem::path d = std::filesystem::absolute(dir, ec);
  std::vector<std::string> failed;
  for (const PlotSpec& p : plots) {
    const std::filesystem::path png = d / (p.name + ".png");
    const std::filesystem::path gp = d / (p.name + ".gp");
    {
      std::ofstream f(gp);
      f << "# " << p.title << "\n"
        << "if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) {\n"
        << "  set terminal pngcairo size " << p.width_px << "," << p.height_px << " font 'sans,10'\n"
        << "} else {\n"
        << "  set terminal png size " << p.width_px << "," << p.height_px << "\n"
        << "}\n"
        << "set termoption noenhanced\n"
        << "set output " << gnuplot_quote(png.string()) << "\n"
        << "set datafile separator ','\n"
        << "set grid\n"
        << p.script_body << "\n"
        << "unset output\n";
      if (!f) {
        failed.push_back(p.name + " (cannot write " + gp.filename().string() + ")");
        continue;
      }
    }
    if (gnuplot.empty()) continue;
    std::filesystem::remove(png, ec);
    const std::string log = (d / (p.name + ".gnuplot.log")).string();
    const int rc = run_program(gnuplot, {gp.string()}, log);
    if (rc == 0 && std::filesystem::exists(png) && std::filesystem::file_size(png, ec) > 0) {
      out.drawn.push_back(png.filename().string());
      out.drawn_titles.push_back(p.title);
      std::filesystem::remove(log, ec);
    } else {
      failed.push_back(p.name + " (gnuplot exit " + std::to_string(rc) + ": " + read_first_line(log) + ")");
    }
  }
  if (!failed.empty()) {
    if (!out.note.empty()) out.note += "; ";
    out.note += "not drawn:";
    for (const auto& f : failed) out.note += " " + f;
  }
  return out;
}

}  // namespace feedloop::ident
