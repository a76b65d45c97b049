#include "web/calibration_report.hpp"

#include <chrono>
#include <cstring>
#include <filesystem>
#include <utility>

#include "core/bounded_file.hpp"

namespace feedloop::web {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {
constexpr uintmax_t kMaxReportBytes = 1 << 20;    // report.json
constexpr uintmax_t kMaxMarkdownBytes = 1 << 20;  // report.md

double unix_s(fs::file_time_type t) {
  // GCC 12 has no clock_cast: shift by the two clocks' "now".
  const auto sys = std::chrono::system_clock::now() +
                   std::chrono::duration_cast<std::chrono::system_clock::duration>(
                       t - fs::file_time_type::clock::now());
  return std::chrono::duration<double>(sys.time_since_epoch()).count();
}

bool read_capped(const fs::path& p, uintmax_t cap, std::string* out, std::string* why) {
  BoundedFile f = read_file_bounded(p.string(), static_cast<std::size_t>(cap));
  switch (f.status) {
    case BoundedFile::Status::kOk:
      *out = std::move(f.text);
      return true;
    case BoundedFile::Status::kTooLarge:
      *why = p.string() + " is over " + std::to_string(cap) + " bytes";
      return false;
    case BoundedFile::Status::kCannotOpen:
    case BoundedFile::Status::kReadError:
      break;
  }
  *why = "cannot read " + p.string() + ": " + std::strerror(f.errno_value);
  return false;
}
}  // namespace

json latest_calibration_report(const std::string& dir) {
  json out = {{"found", false}, {"dir", dir}};
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    out["message"] = "no calibration report yet: " + dir +
                     " does not exist (feedloop ident fit --out " + dir + "/NAME)";
    return out;
  }
  fs::path best;
  fs::file_time_type best_t{};
  auto consider = [&](const fs::path& p) {
    std::error_code e;
    if (!fs::is_regular_file(p, e)) return;
    const auto t = fs::last_write_time(p, e);
    if (e) return;
    if (best.empty() || t > best_t) {
      best = p;
      best_t = t;
    }
  };
  consider(fs::path(dir) / "report.json");
  for (fs::directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
       !ec && it != end; it.increment(ec)) {
    std::error_code e;
    if (it->is_directory(e)) consider(it->path() / "report.json");
  }
  if (best.empty()) {
    out["message"] =
        "no calibration report yet in " + dir + " (feedloop ident fit --out " + dir + "/NAME)";
    return out;
  }
  std::string text, why;
  if (!read_capped(best, kMaxReportBytes, &text, &why)) {
    out["message"] = why;
    return out;
  }
  json report;
  try {
    report = json::parse(text);
  } catch (const json::parse_error& e) {
    out["message"] = best.string() + ": not JSON (" + e.what() + ")";
    return out;
  }
  if (!report.is_object()) {
    out["message"] = best.string() + ": not a report (the top level is not an object)";
    return out;
  }
  std::string markdown;
  const fs::path md = best.parent_path() / "report.md";
  if (fs::exists(md, ec) && !read_capped(md, kMaxMarkdownBytes, &markdown, &why)) markdown.clear();
  out = {{"found", true},
         {"dir", dir},
         {"path", best.string()},
         {"modified", unix_s(best_t)},
         {"report", std::move(report)},
         {"markdown", json::string_t(markdown)}};
  return out;
}

}  // namespace feedloop::web
