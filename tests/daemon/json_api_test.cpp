// handle_json_request on its own, with a fake backend: what fuzz/fuzz_json_api.cpp found.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "daemon/client_session.hpp"
#include "daemon/json_api.hpp"

namespace feedloop::daemon {
namespace {

using nlohmann::json;

struct NullSession final : ClientSession {
  NullSession() : ClientSession(1, "api#1") {}
  void start() override {}
  void do_write(const std::string&) override {}
  void do_close() override {}
  void do_read() override {}
};

struct CountingBackend final : JsonApiBackend {
  mutable int infos = 0;
  json info() const override {
    ++infos;
    return {{"name", "test"}};
  }
  json status() const override { return json::object(); }
  void run_script(ClientSession&, std::string, std::function<void(json, std::string)> done) override {
    done({{"results", json::array()}}, "");
  }
  void emergency_stop(const std::string&) override {}
};

// fuzz/corpus/json_api/regress_nul_byte: the JSON parser stops at a NUL byte, so a request
// followed by a NUL and anything else was taken as that request, the rest silently ignored.
TEST(JsonApiInput, ANulByteIsAParseErrorAtItsColumn) {
  CountingBackend backend;
  auto session = std::make_shared<NullSession>();
  Subscription sub;
  std::vector<json> replies;
  const std::string first = R"({"jsonrpc":"2.0","id":1,"method":"info"})";
  const std::string line = first + std::string(1, '\0') + R"({"jsonrpc":"2.0","id":2,"method":"info"})";
  handle_json_request(backend, *session, line, sub, [&](const json& r) { replies.push_back(r); });
  ASSERT_EQ(replies.size(), 1u);
  EXPECT_EQ(backend.infos, 0);
  EXPECT_EQ(replies[0]["error"]["code"], -32700);
  EXPECT_TRUE(replies[0]["id"].is_null());
  const std::string msg = replies[0]["error"]["message"];
  EXPECT_NE(msg.find("column " + std::to_string(first.size() + 1)), std::string::npos) << msg;
  EXPECT_NE(msg.find("NUL"), std::string::npos) << msg;
  // The same request without the NUL is answered.
  replies.clear();
  handle_json_request(backend, *session, first, sub, [&](const json& r) { replies.push_back(r); });
  ASSERT_EQ(replies.size(), 1u);
  EXPECT_EQ(replies[0]["id"], 1);
  EXPECT_EQ(backend.infos, 1);
}

// Nesting beyond 64 levels is refused before the parse (core/json_depth.hpp): nlohmann parses
// any depth but dumps and copies by recursion, so a value nested 100 000 deep, once stored or
// echoed, overflows the stack. Brackets inside strings are no nesting.
TEST(JsonApiInput, NestingDeeperThan64IsAParseError) {
  CountingBackend backend;
  auto session = std::make_shared<NullSession>();
  Subscription sub;
  std::vector<json> replies;
  auto send = [&](const std::string& params) {
    replies.clear();
    handle_json_request(backend, *session,
                        R"({"jsonrpc":"2.0","id":3,"method":"info","params":)" + params + "}", sub,
                        [&](const json& r) { replies.push_back(r); });
    EXPECT_EQ(replies.size(), 1u);
    return replies.empty() ? json() : replies[0];
  };
  const json deep = send("{\"a\":" + std::string(100000, '[') + std::string(100000, ']') + "}");
  EXPECT_EQ(deep["error"]["code"], -32700);
  EXPECT_NE(deep["error"]["message"].get<std::string>().find("deeper than 64 levels"),
            std::string::npos)
      << deep.dump();
  EXPECT_EQ(backend.infos, 0);
  const json ok =
      send("{\"a\":" + std::string(60, '[') + "\"[[[[\\\"[\"" + std::string(60, ']') + "}");
  EXPECT_EQ(ok["result"]["name"], "test") << ok.dump();
  EXPECT_EQ(backend.infos, 1);
}

}  // namespace
}  // namespace feedloop::daemon
