// `feedloop log info|export`: argument parsing around the recorder library (see log_command.hpp).
#include "cli/log_command.hpp"

#include <cstdio>
#include <cstdlib>  // strtod

#include "recorder/log_summary.hpp"
#include "recorder/trace_export.hpp"

namespace feedloop::cli {
namespace {

void usage(std::FILE* out) {
  std::fputs(
      "usage: feedloop log info LOG...\n"
      "       feedloop log export LOG... --csv FILE [--rate-hz N]\n"
      "  info    summary of a flight-recorder log: duration, G-code lines, moves, steps per joint,\n"
      "          encoder samples, events, dropped records, file size, bytes per record\n"
      "  export  trace CSV v1 (time_s,<a>_cmd_mm,<a>_meas_mm,...) sampled at N Hz (default 1000);\n"
      "          several LOGs are the parts of one print, in order\n",
      out);
}

int info(const std::vector<std::string>& logs) {
  int rc = 0;
  for (size_t i = 0; i < logs.size(); ++i) {
    auto s = recorder::summarize_log(logs[i]);
    if (!s) {
      std::fprintf(stderr, "feedloop log info: %s\n", s.error().to_string().c_str());
      rc = 1;
      continue;
    }
    if (i) std::fputs("\n", stdout);
    std::fputs(recorder::format_summary(*s).c_str(), stdout);
    if (s->damage) rc = 1;
  }
  return rc;
}

int export_csv(const std::vector<std::string>& logs, const std::string& csv, double rate_hz) {
  recorder::ExportOptions opt;
  opt.rate_hz = rate_hz;
  auto trace = recorder::build_trace(logs, opt);
  if (!trace) {
    std::fprintf(stderr, "feedloop log export: %s\n", trace.error().to_string().c_str());
    return 1;
  }
  Status st = recorder::write_trace_csv(*trace, csv);
  if (!st) {
    std::fprintf(stderr, "feedloop log export: %s\n", st.error().to_string().c_str());
    return 1;
  }
  for (const std::string& c : trace->comments) std::fprintf(stderr, "feedloop log export: %s\n", c.c_str());
  std::printf("wrote %s: %zu rows at %g Hz, joints", csv.c_str(), trace->time_s.size(), trace->rate_hz);
  for (const std::string& j : trace->joints) std::printf(" %s", j.c_str());
  std::printf("\n");
  return 0;
}

}  // namespace

int log_command(const std::vector<std::string>& args) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    usage(args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  const std::string& sub = args[0];
  std::vector<std::string> logs;
  std::string csv;
  double rate_hz = 1000.0;
  for (size_t i = 1; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--csv" && i + 1 < args.size()) {
      csv = args[++i];
    } else if (a == "--rate-hz" && i + 1 < args.size()) {
      char* end = nullptr;
      rate_hz = std::strtod(args[++i].c_str(), &end);
      if (end == args[i].c_str() || *end != '\0' || !(rate_hz > 0.0)) {
        std::fprintf(stderr, "feedloop log: --rate-hz needs a positive number, got '%s'\n", args[i].c_str());
        return 2;
      }
    } else if (a == "--help") {
      usage(stdout);
      return 0;
    } else if (a.rfind("--", 0) == 0) {
      std::fprintf(stderr, "feedloop log: unknown option '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    } else {
      logs.push_back(a);
    }
  }
  if (logs.empty()) {
    std::fprintf(stderr, "feedloop log %s: no LOG given\n", sub.c_str());
    usage(stderr);
    return 2;
  }
  if (sub == "info") {
    if (!csv.empty()) {
      std::fprintf(stderr, "feedloop log info: --csv belongs to 'log export'\n");
      return 2;
    }
    return info(logs);
  }
  if (sub == "export") {
    if (csv.empty()) {
      std::fprintf(stderr, "feedloop log export: --csv FILE is required\n");
      usage(stderr);
      return 2;
    }
    return export_csv(logs, csv, rate_hz);
  }
  std::fprintf(stderr, "feedloop log: unknown subcommand '%s'\n", sub.c_str());
  usage(stderr);
  return 2;
}

}  // namespace feedloop::cli
