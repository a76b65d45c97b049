#include "web/database.hpp"

#include <sqlite3.h>

#include "core/json_depth.hpp"

namespace feedloop::web {

using nlohmann::json;

namespace {
// One prepared statement, finalised on scope exit.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) { sqlite3_prepare_v2(db, sql, -1, &s_, nullptr); }
  ~Stmt() { sqlite3_finalize(s_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;
  bool ok() const { return s_ != nullptr; }
  void text(int i, const std::string& v) {
    sqlite3_bind_text(s_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  }
  void integer(int i, int64_t v) { sqlite3_bind_int64(s_, i, v); }
  bool row() { return s_ && sqlite3_step(s_) == SQLITE_ROW; }
  bool done() { return s_ && sqlite3_step(s_) == SQLITE_DONE; }
  std::string col_text(int i) {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(s_, i));
    return p ? std::string(p, static_cast<size_t>(sqlite3_column_bytes(s_, i))) : std::string();
  }
  int64_t col_int(int i) { return sqlite3_column_int64(s_, i); }

 private:
  sqlite3_stmt* s_ = nullptr;
};

json parse_or_null(const std::string& text) {
  json v = json::parse(text, nullptr, /*allow_exceptions=*/false);
  return v.is_discarded() ? json(nullptr) : v;
}

// The API answers 404 for these (messages ending in "not found").
Error not_found(const std::string& what) {
  return Error{what};
}
}  // namespace

Result<std::vector<std::string>> split_key(const std::string& key) {
  std::vector<std::string> parts;
  size_t b = 0;
  while (true) {
    const size_t e = key.find('.', b);
    const std::string part = key.substr(b, e == std::string::npos ? std::string::npos : e - b);
    if (part.empty()) return Error{"invalid key '" + key.substr(0, 200) + "': an empty part"};
    // Each part is a level of the stored value: bounded as a client's JSON is
    // (core/json_depth.hpp).
    if (parts.size() == kMaxClientJsonDepth)
      return Error{"invalid key: more than " + std::to_string(kMaxClientJsonDepth) + " parts"};
    parts.push_back(part);
    if (e == std::string::npos) break;
    b = e + 1;
  }
  return parts;
}

Result<std::unique_ptr<Database>> Database::open(const std::string& path) {
  sqlite3* db = nullptr;
  if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) {
    std::string why = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    return Error{"web.database: cannot open '" + path + "': " + why};
  }
  std::unique_ptr<Database> d(new Database(db));
  if (Status s = d->exec("PRAGMA journal_mode=WAL;"
                         "CREATE TABLE IF NOT EXISTS items (ns TEXT NOT NULL, key TEXT NOT NULL, "
                         "value TEXT NOT NULL,"
                         " PRIMARY KEY (ns, key));"
                         "CREATE TABLE IF NOT EXISTS history (id INTEGER PRIMARY KEY "
                         "AUTOINCREMENT, job TEXT NOT NULL);");
      !s)
    return Error{"web.database '" + path + "': " + s.error().message};
  return d;
}

Database::~Database() {
  sqlite3_close(db_);
}

Status Database::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string why = err ? err : "unknown error";
    sqlite3_free(err);
    return Error{why};
  }
  return Status::Ok();
}

std::vector<std::string> Database::namespaces() {
  std::vector<std::string> out;
  Stmt s(db_, "SELECT DISTINCT ns FROM items ORDER BY ns");
  while (s.row()) out.push_back(s.col_text(0));
  return out;
}

Result<json> Database::get(const std::string& ns, const std::string& key) {
  if (key.empty()) {
    Stmt s(db_, "SELECT key, value FROM items WHERE ns = ?1");
    s.text(1, ns);
    json out = json::object();
    bool any = false;
    while (s.row()) {
      any = true;
      out[s.col_text(0)] = parse_or_null(s.col_text(1));
    }
    if (!any) return not_found("Namespace '" + ns + "' not found");
    return out;
  }
  auto parts = split_key(key);
  if (!parts) return parts.error();
  Stmt s(db_, "SELECT value FROM items WHERE ns = ?1 AND key = ?2");
  s.text(1, ns);
  s.text(2, (*parts)[0]);
  if (!s.row()) return not_found("Key '" + key + "' in namespace '" + ns + "' not found");
  json v = parse_or_null(s.col_text(0));
  for (size_t i = 1; i < parts->size(); ++i) {
    if (!v.is_object() || !v.contains((*parts)[i]))
      return not_found("Key '" + key + "' in namespace '" + ns + "' not found");
    v = json(v[(*parts)[i]]);
  }
  return v;
}

Status Database::post(const std::string& ns, const std::string& key, const json& value) {
  if (ns.empty()) return Error{"'namespace' must not be empty"};
  auto parts = split_key(key);
  if (!parts) return parts.error();
  json row = value;
  if (parts->size() > 1) {
    Stmt s(db_, "SELECT value FROM items WHERE ns = ?1 AND key = ?2");
    s.text(1, ns);
    s.text(2, (*parts)[0]);
    row = s.row() ? parse_or_null(s.col_text(0)) : json::object();
    json* at = &row;
    for (size_t i = 1; i < parts->size(); ++i) {
      if (!at->is_object()) *at = json::object();
      at = &(*at)[(*parts)[i]];
    }
    *at = value;
  }
  Stmt s(db_, "INSERT OR REPLACE INTO items (ns, key, value) VALUES (?1, ?2, ?3)");
  s.text(1, ns);
  s.text(2, (*parts)[0]);
  s.text(3, row.dump(-1, ' ', false, json::error_handler_t::replace));
  if (!s.done()) return Error{std::string("database write failed: ") + sqlite3_errmsg(db_)};
  return Status::Ok();
}

Result<json> Database::remove(const std::string& ns, const std::string& key) {
  auto old = get(ns, key);
  if (!old) return old.error();
  auto parts = split_key(key);
  if (parts->size() == 1) {
    Stmt s(db_, "DELETE FROM items WHERE ns = ?1 AND key = ?2");
    s.text(1, ns);
    s.text(2, key);
    s.done();
    return old;
  }
  auto row = get(ns, (*parts)[0]);
  json* at = &*row;
  for (size_t i = 1; i + 1 < parts->size(); ++i) at = &(*at)[(*parts)[i]];
  at->erase(parts->back());
  if (Status st = post(ns, (*parts)[0], *row); !st) return st.error();
  return old;
}

int64_t Database::add_job(const json& job) {
  Stmt s(db_, "INSERT INTO history (job) VALUES (?1)");
  s.text(1, job.dump(-1, ' ', false, json::error_handler_t::replace));
  s.done();
  return sqlite3_last_insert_rowid(db_);
}

void Database::update_job(int64_t id, const json& job) {
  Stmt s(db_, "UPDATE history SET job = ?1 WHERE id = ?2");
  s.text(1, job.dump(-1, ' ', false, json::error_handler_t::replace));
  s.integer(2, id);
  s.done();
}

json Database::jobs(int64_t start, int64_t limit) {
  json out = json::array();
  Stmt s(db_, "SELECT id, job FROM history ORDER BY id DESC LIMIT ?1 OFFSET ?2");
  s.integer(1, limit);
  s.integer(2, start);
  while (s.row()) {
    json j = parse_or_null(s.col_text(1));
    if (!j.is_object()) continue;
    j["job_id"] = std::to_string(s.col_int(0));
    out.push_back(std::move(j));
  }
  return out;
}

int64_t Database::job_count() {
  Stmt s(db_, "SELECT COUNT(*) FROM history");
  return s.row() ? s.col_int(0) : 0;
}

Status Database::delete_job(const std::string& id_or_all) {
  if (id_or_all == "all") return exec("DELETE FROM history");
  int64_t id = 0;
  try {
    id = std::stoll(id_or_all);
  } catch (const std::exception&) {
    return Error{"invalid job id '" + id_or_all + "'"};
  }
  Stmt s(db_, "DELETE FROM history WHERE id = ?1");
  s.integer(1, id);
  s.done();
  if (sqlite3_changes(db_) == 0) return not_found("Job '" + id_or_all + "' not found");
  return Status::Ok();
}

}  // namespace feedloop::web
