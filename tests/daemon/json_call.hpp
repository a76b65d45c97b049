// Test helper: a JSON-RPC request to the daemon's JSON API over a LineClient, and its reply
// (notifications skipped). A null json when no reply came in time.
#pragma once

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <string>

#include "tests/daemon/line_client.hpp"

namespace feedloop::testing {

// Sends `req` as it is and returns the first line that carries an "id" (the reply, whatever its
// id: a request with a bad id is answered with id null); `raw` gets that line's text.
inline nlohmann::json call(LineClient& c, const nlohmann::json& req, std::string* raw = nullptr) {
  EXPECT_TRUE(c.send_line(req.dump()));
  for (int i = 0; i < 1000; ++i) {
    auto line = c.read_line(10000);
    if (!line) return nlohmann::json();
    nlohmann::json r = nlohmann::json::parse(*line);
    if (r.contains("id")) {
      if (raw != nullptr) *raw = *line;
      return r;
    }
  }
  return nlohmann::json();
}

// Calls `method` with a fresh id and returns the reply with that id.
inline nlohmann::json call(LineClient& c, const std::string& method,
                           const nlohmann::json& params = nlohmann::json::object()) {
  static int next_id = 1;
  const int id = next_id++;
  EXPECT_TRUE(c.send_line(
      nlohmann::json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}
          .dump()));
  for (int i = 0; i < 1000; ++i) {
    auto line = c.read_line(10000);
    if (!line) return nlohmann::json();
    nlohmann::json r = nlohmann::json::parse(*line);
    if (r.contains("id") && r["id"] == id) return r;
  }
  return nlohmann::json();
}
inline nlohmann::json call(LineClient& c, const char* method,
                           const nlohmann::json& params = nlohmann::json::object()) {
  return call(c, std::string(method), params);
}

}  // namespace feedloop::testing
