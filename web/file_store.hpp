// The files the UIs manage (server.files.*): roots "gcodes" and "config" under one directory.
// Every path from outside is checked: relative, no "..", no NUL, no control characters, at
// most 4 levels deep; a path that fails gets an error naming it.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <string_view>

#include "core/result.hpp"

namespace feedloop::web {

class FileStore {
 public:
  // Creates <dir>/gcodes and <dir>/config when missing. A non-empty `gcodes_dir` is the gcodes
  // root instead of <dir>/gcodes: the daemon passes its job folder (jobs.directory), so a file
  // the UI uploads is the file M23/M32 and the JSON API's job.start print (one job path).
  static Result<FileStore> open(const std::string& dir, const std::string& gcodes_dir = {});

  static const std::vector<std::string>& roots();
  // "gcodes/a/b.gcode" or root + relative path -> the absolute path (checked).
  Result<std::string> resolve(std::string_view root, std::string_view rel) const;
  // Splits "gcodes/a/b.gcode" into root and rest (the rest may be empty).
  static Result<std::pair<std::string, std::string>> split_root(std::string_view path);

  // Moonraker's server.files.list: every file under the root, [{path, modified, size,
  // permissions}].
  Result<nlohmann::json> list(const std::string& root) const;
  // server.files.get_directory: {dirs, files, disk_usage, root_info}.
  Result<nlohmann::json> directory(const std::string& path) const;
  // server.files.metadata: size, modified and what the slicer wrote in the file's comments
  // (PrusaSlicer/SuperSlicer/OrcaSlicer "; estimated printing time", Cura ";TIME:",
  // ";Filament used:", first layer height, object height from the largest Z).
  Result<nlohmann::json> metadata(const std::string& filename) const;
  // Writes atomically (a temporary file, then rename). Returns the item {path, root, modified,
  // size, permissions}.
  Result<nlohmann::json> write(const std::string& root, const std::string& rel,
                               std::string_view data) const;
  Result<nlohmann::json> remove(const std::string& path) const;
  Result<nlohmann::json> make_dir(const std::string& path) const;
  Result<nlohmann::json> remove_dir(const std::string& path, bool force) const;

  const std::string& dir() const { return dir_; }
  // The folder a root lives in (absolute or as configured).
  std::string root_dir(std::string_view root) const;

 private:
  std::string dir_;
  std::string gcodes_dir_;
};

// Checks one outside relative path (see above); returns the message when it is not allowed.
std::string bad_path_reason(std::string_view rel);

}  // namespace feedloop::web
