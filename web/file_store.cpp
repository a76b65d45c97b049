#include "web/file_store.hpp"

#include <sys/statvfs.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string_view>

#include "core/atomic_file.hpp"
#include "gcode/file_lines.hpp"

namespace feedloop::web {

namespace fs = std::filesystem;
using nlohmann::json;

const std::vector<std::string>& FileStore::roots() {
  static const std::vector<std::string> r{"gcodes", "config"};
  return r;
}

std::string bad_path_reason(std::string_view rel) {
  if (rel.size() > 1024) return "path longer than 1024 bytes";
  if (!rel.empty() && rel.front() == '/') return "absolute path";
  int depth = 0;
  size_t b = 0;
  while (b <= rel.size()) {
    size_t e = rel.find('/', b);
    if (e == std::string_view::npos) e = rel.size();
    const std::string_view part = rel.substr(b, e - b);
    if (part == "..") return "'..' in the path";
    // "gcodes/." named the root itself: a forced delete_directory removed every file in it.
    if (part == ".") return "'.' in the path";
    if (!part.empty() && ++depth > 8) return "more than 8 levels";
    b = e + 1;
  }
  for (char c : rel)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return "a control character in the path";
  return {};
}

Result<FileStore> FileStore::open(const std::string& dir, const std::string& gcodes_dir) {
  FileStore s;
  s.dir_ = dir;
  s.gcodes_dir_ = gcodes_dir;
  std::error_code ec;
  for (const std::string& r : roots()) {
    const std::string d = s.root_dir(r);
    fs::create_directories(d, ec);
    if (ec)
      return Error{
          std::string(r == "gcodes" && !gcodes_dir.empty() ? "jobs.directory" : "web.files_dir") +
          ": cannot create '" + d + "': " + ec.message()};
  }
  return s;
}

std::string FileStore::root_dir(std::string_view root) const {
  if (root == "gcodes" && !gcodes_dir_.empty()) return gcodes_dir_;
  return (fs::path(dir_) / std::string(root)).string();
}

Result<std::pair<std::string, std::string>> FileStore::split_root(std::string_view path) {
  while (!path.empty() && path.front() == '/') path.remove_prefix(1);
  const size_t slash = path.find('/');
  std::string root(path.substr(0, slash));
  std::string rest =
      slash == std::string_view::npos ? std::string() : std::string(path.substr(slash + 1));
  if (std::find(roots().begin(), roots().end(), root) == roots().end())
    return Error{"Invalid root '" + root + "' (known: gcodes, config)"};
  return std::pair{root, rest};
}

Result<std::string> FileStore::resolve(std::string_view root, std::string_view rel) const {
  if (std::find(roots().begin(), roots().end(), root) == roots().end())
    return Error{"Invalid root '" + std::string(root) + "' (known: gcodes, config)"};
  if (std::string why = bad_path_reason(rel); !why.empty())
    return Error{"invalid path '" + std::string(rel) + "': " + why};
  fs::path p = root_dir(root);
  if (!rel.empty()) p /= std::string(rel);
  return p.lexically_normal().string();
}

namespace {
double mtime_s(const fs::path& p) {
  std::error_code ec;
  const auto t = fs::last_write_time(p, ec);
  if (ec) return 0.0;
  // GCC 12 has no clock_cast: shift by the two clocks' "now".
  const auto sys = std::chrono::system_clock::now() +
                   std::chrono::duration_cast<std::chrono::system_clock::duration>(
                       t - fs::file_time_type::clock::now());
  return std::chrono::duration<double>(sys.time_since_epoch()).count();
}
json disk_usage(const std::string& dir) {
  struct statvfs v {};
  if (statvfs(dir.c_str(), &v) != 0) return {{"total", 0}, {"used", 0}, {"free", 0}};
  const double total = static_cast<double>(v.f_blocks) * static_cast<double>(v.f_frsize);
  const double free_b = static_cast<double>(v.f_bavail) * static_cast<double>(v.f_frsize);
  return {{"total", total}, {"used", total - free_b}, {"free", free_b}};
}
bool hidden(const fs::path& p) {
  return p.filename().string().rfind('.', 0) == 0;
}
}  // namespace

Result<json> FileStore::list(const std::string& root) const {
  auto base = resolve(root, "");
  if (!base) return base.error();
  json out = json::array();
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(
           *base, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (hidden(it->path())) {
      if (it->is_directory()) it.disable_recursion_pending();
      continue;
    }
    if (!it->is_regular_file()) continue;
    out.push_back({{"path", fs::relative(it->path(), *base).string()},
                   {"modified", mtime_s(it->path())},
                   {"size", it->file_size()},
                   {"permissions", "rw"}});
  }
  return out;
}

Result<json> FileStore::directory(const std::string& path) const {
  auto rr = split_root(path.empty() ? std::string("gcodes") : path);
  if (!rr) return rr.error();
  auto p = resolve(rr->first, rr->second);
  if (!p) return p.error();
  std::error_code ec;
  if (!fs::is_directory(*p, ec)) return Error{"Directory '" + path + "' not found"};
  json dirs = json::array(), files = json::array();
  for (const auto& e : fs::directory_iterator(*p, ec)) {
    if (hidden(e.path())) continue;
    if (e.is_directory())
      dirs.push_back({{"dirname", e.path().filename().string()},
                      {"modified", mtime_s(e.path())},
                      {"size", 4096},
                      {"permissions", "rw"}});
    else if (e.is_regular_file())
      files.push_back({{"filename", e.path().filename().string()},
                       {"modified", mtime_s(e.path())},
                       {"size", e.file_size()},
                       {"permissions", "rw"}});
  }
  return json{{"dirs", dirs},
              {"files", files},
              {"disk_usage", disk_usage(*p)},
              {"root_info", {{"name", rr->first}, {"permissions", "rw"}}}};
}

namespace {
// Hand-written scanners, not std::regex: libstdc++'s regex recurses once per character matched,
// and a 100 kB line of an uploaded file overflowed the stack (the daemon crashed when a front end
// asked for the file's metadata). Each scan here is a loop over the line.

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}
bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}
bool is_word(char c) {
  return is_digit(c) || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}

// A finite number from the text (nullopt: none, or out of range).
std::optional<double> finite_number(std::string_view text) {
  if (text.empty() || text.size() > 64) return std::nullopt;
  const std::string s(text);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end == s.c_str() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// "1h 2m 3s", "2d 1h", "45m 10s" -> seconds: every run of digits followed (after spaces) by
// d, h, m or s.
double parse_duration_s(std::string_view text) {
  double s = 0.0;
  size_t i = 0;
  while (i < text.size()) {
    if (!is_digit(text[i])) {
      ++i;
      continue;
    }
    const size_t start = i;
    while (i < text.size() && is_digit(text[i])) ++i;
    const std::string_view digits = text.substr(start, i - start);
    size_t j = i;
    while (j < text.size() && is_space(text[j])) ++j;
    if (j == text.size()) break;
    const char unit = text[j];
    if (unit != 'd' && unit != 'h' && unit != 'm' && unit != 's') continue;
    i = j + 1;
    const auto v = finite_number(digits);
    if (!v) continue;
    s += *v * (unit == 'd' ? 86400.0 : unit == 'h' ? 3600.0 : unit == 'm' ? 60.0 : 1.0);
  }
  return s;
}

// The Z of a G0/G1 line (the last Z word before a comment), if it has one.
std::optional<double> move_z(std::string_view line) {
  if (line.size() < 2 || line[0] != 'G' || (line[1] != '0' && line[1] != '1')) return std::nullopt;
  if (line.size() > 2 && is_word(line[2])) return std::nullopt;  // G10, G1X: not a G0/G1 word
  const std::string_view code = line.substr(0, line.find(';'));
  std::optional<double> z;
  for (size_t i = 2; i < code.size(); ++i) {
    if (code[i] != 'Z' || is_word(code[i - 1])) continue;
    size_t j = i + 1;
    if (j < code.size() && code[j] == '-') ++j;
    const size_t digits = j;
    while (j < code.size() && (is_digit(code[j]) || code[j] == '.')) ++j;
    if (j == digits) continue;
    if (const auto v = finite_number(code.substr(i + 1, j - i - 1))) z = v;
  }
  return z;
}

// "generated by SLICER VERSION" in a comment: the two words after it.
bool slicer_of(std::string_view line, std::string* slicer, std::string* version) {
  static constexpr std::string_view kKey = "generated by ";
  const size_t at = line.find(kKey);
  if (at == std::string_view::npos) return false;
  const size_t name_at = at + kKey.size();
  size_t i = name_at;
  while (i < line.size() && !is_space(line[i])) ++i;
  const size_t name_end = i;
  if (name_end == name_at || i >= line.size() || line[i] != ' ') return false;
  const size_t version_at = ++i;
  while (i < line.size() && !is_space(line[i])) ++i;
  if (i == version_at) return false;
  *slicer = std::string(line.substr(name_at, name_end - name_at));
  *version = std::string(line.substr(version_at, i - version_at));
  return true;
}

// Lines longer than this are skipped by the metadata scan (a slicer's lines are under 1 kB).
constexpr size_t kMetadataMaxLineBytes = 4096;
// ... and at most this many lines are read (the header comments and the moves' heights).
constexpr int64_t kMetadataMaxLines = 2'000'000;
}  // namespace

Result<json> FileStore::metadata(const std::string& filename) const {
  auto p = resolve("gcodes", filename);
  if (!p) return p.error();
  std::error_code ec;
  if (!fs::is_regular_file(*p, ec))
    return Error{"Metadata not available for <" + filename + ">: file not found"};
  json m{{"filename", filename},
         {"size", fs::file_size(*p, ec)},
         {"modified", mtime_s(*p)},
         {"print_start_time", nullptr},
         {"job_id", nullptr}};
  double max_z = 0.0, first_z = -1.0;
  bool slicer_seen = false;
  auto on_line = [&](const gcode::SplitLine& l) {
    if (l.too_long || l.number > kMetadataMaxLines) return;
    const std::string_view line = l.text;
    if (line.empty()) return;
    if (line[0] == ';') {
      std::string slicer, version;
      if (!slicer_seen && slicer_of(line, &slicer, &version)) {
        m["slicer"] = slicer;
        m["slicer_version"] = version;
        slicer_seen = true;
      } else if (line.rfind("; estimated printing time", 0) == 0) {
        if (const size_t eq = line.find('='); eq != std::string_view::npos)
          m["estimated_time"] = parse_duration_s(line.substr(eq + 1));
      } else if (line.rfind(";TIME:", 0) == 0) {
        if (const auto v = finite_number(line.substr(6))) m["estimated_time"] = *v;
      } else if (line.rfind("; filament used [mm] =", 0) == 0) {
        if (const auto v = finite_number(line.substr(22))) m["filament_total"] = *v;
      } else if (line.rfind(";Filament used:", 0) == 0) {
        if (const auto v = finite_number(line.substr(15))) m["filament_total"] = *v * 1000.0;
      } else if (line.rfind("; layer_height =", 0) == 0) {
        if (const auto v = finite_number(line.substr(16))) m["layer_height"] = *v;
      }
      return;
    }
    if (const auto z = move_z(line)) {
      if (first_z < 0 && *z > 0) first_z = *z;
      max_z = std::max(max_z, *z);
    }
  };
  int64_t lines = 0;
  auto count = [&](const gcode::SplitLine& l) {
    lines = l.number;
    on_line(l);
  };
  // Stops after kMetadataMaxLines (a whole 512 MB upload is not read for its metadata).
  const auto more = [&](size_t) { return lines <= kMetadataMaxLines; };
  if (Status read = gcode::for_each_file_line_reporting(*p, count, more, kMetadataMaxLineBytes);
      !read)
    return Error{"Metadata not available for <" + filename + ">: " + read.error().message};
  if (first_z > 0) m["first_layer_height"] = first_z;
  m["object_height"] = max_z;
  return m;
}

Result<json> FileStore::write(const std::string& root, const std::string& rel,
                              std::string_view data) const {
  if (rel.empty() || rel.back() == '/') return Error{"invalid file name '" + rel + "'"};
  auto p = resolve(root, rel);
  if (!p) return p.error();
  std::error_code ec;
  fs::create_directories(fs::path(*p).parent_path(), ec);
  if (ec) return Error{"cannot create the folder of '" + rel + "': " + ec.message()};
  if (Status s = write_file_atomically(*p, data, 0640); !s)
    return Error{"cannot store '" + rel + "': " + s.error().message};
  return json{{"path", rel},
              {"root", root},
              {"modified", mtime_s(*p)},
              {"size", data.size()},
              {"permissions", "rw"}};
}

Result<json> FileStore::remove(const std::string& path) const {
  auto rr = split_root(path);
  if (!rr) return rr.error();
  auto p = resolve(rr->first, rr->second);
  if (!p) return p.error();
  std::error_code ec;
  if (rr->second.empty() || !fs::is_regular_file(*p, ec))
    return Error{"File '" + path + "' not found"};
  fs::remove(*p, ec);
  if (ec) return Error{"cannot delete '" + path + "': " + ec.message()};
  return json{{"item",
               {{"path", rr->second},
                {"root", rr->first},
                {"size", 0},
                {"modified", 0},
                {"permissions", "rw"}}},
              {"action", "delete_file"}};
}

Result<json> FileStore::make_dir(const std::string& path) const {
  auto rr = split_root(path);
  if (!rr) return rr.error();
  auto p = resolve(rr->first, rr->second);
  if (!p) return p.error();
  std::error_code ec;
  fs::create_directories(*p, ec);
  if (ec) return Error{"cannot create '" + path + "': " + ec.message()};
  return json{{"item",
               {{"path", rr->second},
                {"root", rr->first},
                {"modified", mtime_s(*p)},
                {"size", 4096},
                {"permissions", "rw"}}},
              {"action", "create_dir"}};
}

Result<json> FileStore::remove_dir(const std::string& path, bool force) const {
  auto rr = split_root(path);
  if (!rr) return rr.error();
  if (rr->second.empty()) return Error{"cannot delete a root"};
  auto p = resolve(rr->first, rr->second);
  if (!p) return p.error();
  std::error_code ec;
  if (!fs::is_directory(*p, ec)) return Error{"Directory '" + path + "' not found"};
  if (force)
    fs::remove_all(*p, ec);
  else
    fs::remove(*p, ec);
  if (ec) return Error{"cannot delete '" + path + "': " + ec.message()};
  return json{{"item",
               {{"path", rr->second},
                {"root", rr->first},
                {"modified", 0},
                {"size", 0},
                {"permissions", "rw"}}},
              {"action", "delete_dir"}};
}

}  // namespace feedloop::web
