#include "web/file_store.hpp"

#include <sys/statvfs.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>

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
// "1h 2m 3s", "2d 1h", "45m 10s" -> seconds.
double parse_duration_s(const std::string& text) {
  static const std::regex part(R"((\d+)\s*([dhms]))");
  double s = 0.0;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), part); it != std::sregex_iterator();
       ++it) {
    const double v = std::stod((*it)[1]);
    switch ((*it)[2].str()[0]) {
      case 'd':
        s += v * 86400;
        break;
      case 'h':
        s += v * 3600;
        break;
      case 'm':
        s += v * 60;
        break;
      default:
        s += v;
    }
  }
  return s;
}
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
  std::ifstream in(*p);
  std::string line;
  double max_z = 0.0, first_z = -1.0;
  bool slicer_seen = false;
  static const std::regex z_re(R"(^G[01]\b[^;]*\bZ(-?[0-9.]+))");
  int lines = 0;
  while (std::getline(in, line) && ++lines < 2'000'000) {
    if (line.empty()) continue;
    if (line[0] == ';') {
      if (!slicer_seen && line.find("generated by") != std::string::npos) {
        std::smatch mm;
        if (std::regex_search(line, mm, std::regex(R"(generated by (\S+) (\S+))"))) {
          m["slicer"] = mm[1].str();
          m["slicer_version"] = mm[2].str();
          slicer_seen = true;
        }
      } else if (line.rfind("; estimated printing time", 0) == 0) {
        if (const size_t eq = line.find('='); eq != std::string::npos)
          m["estimated_time"] = parse_duration_s(line.substr(eq + 1));
      } else if (line.rfind(";TIME:", 0) == 0) {
        try {
          m["estimated_time"] = std::stod(line.substr(6));
        } catch (const std::exception&) {
        }
      } else if (line.rfind("; filament used [mm] =", 0) == 0) {
        try {
          m["filament_total"] = std::stod(line.substr(22));
        } catch (const std::exception&) {
        }
      } else if (line.rfind(";Filament used:", 0) == 0) {
        try {
          m["filament_total"] = std::stod(line.substr(15)) * 1000.0;
        } catch (const std::exception&) {
        }
      } else if (line.rfind("; layer_height =", 0) == 0) {
        try {
          m["layer_height"] = std::stod(line.substr(16));
        } catch (const std::exception&) {
        }
      }
      continue;
    }
    if (line[0] == 'G' && line.find('Z') != std::string::npos) {
      std::smatch mm;
      if (std::regex_search(line, mm, z_re)) {
        try {
          const double z = std::stod(mm[1]);
          if (std::isfinite(z)) {
            if (first_z < 0 && z > 0) first_z = z;
            max_z = std::max(max_z, z);
          }
        } catch (const std::exception&) {
        }
      }
    }
  }
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
  const std::string tmp = *p + ".part";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    if (!out) {
      fs::remove(tmp, ec);
      return Error{"cannot write '" + rel + "'"};
    }
  }
  fs::rename(tmp, *p, ec);
  if (ec) return Error{"cannot write '" + rel + "': " + ec.message()};
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
