// Moonraker's database (server.database.*): namespaces of JSON items, stored in SQLite. Keys may
// be dotted paths into an item ("gcodeViewer.klipperCache.kinematics"), as in Moonraker's
// database component: the first part is the row, the rest a path inside its JSON value.
// Also the print history (server.history.*), one row per job.
#pragma once

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

#include "core/result.hpp"

struct sqlite3;

namespace feedloop::web {

class Database {
 public:
  // ":memory:" for a database that lives as long as the object.
  static Result<std::unique_ptr<Database>> open(const std::string& path);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  std::vector<std::string> namespaces();
  // The item at `key` (empty: the whole namespace as an object). Absent: an error whose message
  // ends in "not found" (the API answers 404).
  Result<nlohmann::json> get(const std::string& ns, const std::string& key);
  Status post(const std::string& ns, const std::string& key, const nlohmann::json& value);
  // Returns the removed value.
  Result<nlohmann::json> remove(const std::string& ns, const std::string& key);

  // History: adds a job (its id is returned), updates it, lists newest first.
  int64_t add_job(const nlohmann::json& job);
  void update_job(int64_t id, const nlohmann::json& job);
  nlohmann::json jobs(int64_t start, int64_t limit);
  int64_t job_count();
  Status delete_job(const std::string& id_or_all);

 private:
  explicit Database(sqlite3* db) : db_(db) {}
  Status exec(const char* sql);
  sqlite3* db_;
};

// Splits "a.b.c" into its parts; an empty part ("a..b", ".a") is an error.
Result<std::vector<std::string>> split_key(const std::string& key);

}  // namespace feedloop::web
