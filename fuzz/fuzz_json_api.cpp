// libFuzzer target for the JSON-RPC API: the input bytes are what a client writes to api.sock.
// They go through ClientSession's line splitting into daemon::handle_json_request, as in
// Daemon::add_client, with a fake backend in place of the machine: `gcode` scripts are parsed
// with the real parser, queries (M105, M114, M115, M117, M73) answered, other lines complete
// later with ok, a machine error or "busy" (decided by the line's length); `status` carries the
// last M117 text and M73 progress, like Daemon::status().
// Besides crashes, sanitizer reports and escaping exceptions, these trap: a reply that is not
// valid UTF-8 before to_wire()'s safety net or does not parse back, that is not a JSON-RPC 2.0
// response with exactly one of result and error, a known error code and a message; a reply to a
// request with an id that carries another id (null when JSON-RPC does not allow the request's);
// more than one reply per request, or none to a line that is not JSON; a subscription interval
// outside 20..60000 ms.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/utf8.hpp"
#include "daemon/client_session.hpp"
#include "daemon/json_api.hpp"
#include "fuzz/fuzz_input.hpp"
#include "gcode/parser.hpp"

namespace {

using namespace feedloop;
using fuzz::check;
using nlohmann::json;

class FakeSession final : public daemon::ClientSession {
 public:
  FakeSession() : ClientSession(1, "api#1") {}
  void start() override {}
  void feed(std::string_view bytes) { on_bytes(bytes.data(), bytes.size()); }
  size_t bytes_written = 0;

 protected:
  void do_write(const std::string& data) override {
    bytes_written += data.size();
    on_write_done(true);
  }
  void do_close() override {}
  void do_read() override {}
};

// The daemon's side of the API without a machine.
class FakeBackend final : public daemon::JsonApiBackend {
 public:
  json info() const override {
    return {{"name", "fuzz"}, {"version", "0"}, {"api_version", 1}, {"kinematics", "cartesian"}};
  }
  json status() const override {
    return {{"state", "idle"},
            {"message", message_},
            {"progress_percent", progress_},
            {"owner", "api#1"}};
  }
  void run_script(daemon::ClientSession& client, std::string script,
                  std::function<void(json, std::string)> done) override {
    json results = json::array();
    int line_number = 0;
    for (size_t b = 0; b <= script.size();) {
      size_t e = script.find('\n', b);
      if (e == std::string::npos) e = script.size();
      const std::string text = script.substr(b, e - b);
      b = e + 1;
      auto cmd = gcode::parse_line(text, SourceLocation{"api:" + client.name(), ++line_number, 0});
      if (!cmd) {
        results.push_back({{"line", text}, {"ok", false}, {"error", cmd.error().to_string()}});
        break;
      }
      if (cmd->empty() || cmd->is('M', 105) || cmd->is('M', 114) || cmd->is('M', 115)) {
        results.push_back({{"line", text}, {"ok", true}, {"reply", "ok T:20.0 /0.0"}});
      } else if (cmd->is('M', 117)) {
        message_ = cmd->text;
        results.push_back({{"line", text}, {"ok", true}, {"reply", "ok"}});
      } else if (cmd->is('M', 73)) {
        if (cmd->has('P')) progress_ = static_cast<int>(cmd->get('P'));
        results.push_back({{"line", text}, {"ok", true}, {"reply", "ok"}});
      } else if (text.size() % 5 == 4) {
        later_.push_back([done] { done({}, "busy: the print is owned by pty#2"); });
        return;
      } else {
        const bool ok = text.size() % 5 != 3;
        results.push_back({{"line", text}, {"ok", ok}});
        if (!ok)
          results.back()["error"] = "api:" + client.name() + ":" + std::to_string(line_number) +
                                    ": move outside the travel limits";
        if (!ok) break;
      }
    }
    later_.push_back([done, results] { done({{"results", results}}, ""); });
  }
  void emergency_stop(const std::string& reason) override { last_stop_reason_ = reason; }

  // Completes the scripts (the machine's done callbacks, on the I/O thread later).
  void complete() {
    std::vector<std::function<void()>> now;
    now.swap(later_);
    for (auto& f : now) f();
  }

 private:
  std::string message_;
  int progress_ = -1;
  std::string last_stop_reason_;
  std::vector<std::function<void()>> later_;
};

// What handle_json_request refuses before parsing (-32700): a NUL byte, where the JSON parser
// would stop reading, or bytes that are not UTF-8.
bool refused_before_parsing(std::string_view line) {
  size_t bad = 0;
  for (size_t i = 0; i < line.size();) {
    if (line[i] == '\0') return true;
    const size_t n = utf8_sequence_length(line, i, &bad);
    if (n == 0) return true;
    i += n;
  }
  return false;
}

void check_reply(const json& r, const json* request_id) {
  // Outside text is made valid UTF-8 where it enters (core/utf8.hpp), so the strict dump()
  // succeeds (it throws on invalid UTF-8) and the wire form (to_wire, the daemon's) equals it.
  const std::string strict = r.dump();
  const std::string wire = daemon::to_wire(r);
  check(wire == strict);
  const json back = json::parse(wire, nullptr, /*allow_exceptions=*/false);
  check(!back.is_discarded() && back == r);
  check(r.is_object() && r.value("jsonrpc", "") == "2.0" && r.contains("id"));
  check(r.contains("result") != r.contains("error"));
  if (r.contains("error")) {
    const json& e = r["error"];
    check(e.is_object() && e.contains("code") && e["code"].is_number_integer());
    const int code = e["code"].get<int>();
    check(code == -32700 || code == -32600 || code == -32601 || code == -32602 || code == -32603 ||
          code == -32000);
    check(e.contains("message") && e["message"].is_string() &&
          !e["message"].get<std::string>().empty());
  }
  if (request_id != nullptr) check(r["id"] == *request_id);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FakeBackend backend;
  auto session = std::make_shared<FakeSession>();
  daemon::Subscription subscription;
  session->set_handlers(
      [&](daemon::ClientSession& s, std::string_view line, bool too_long) {
        if (too_long) {
          s.send_line(
              daemon::to_wire(daemon::json_rpc_error(nullptr, -32700, "request line too long")));
          return;
        }
        // What the harness can tell about the request on its own.
        const bool refused = refused_before_parsing(line);
        const json req = refused ? json(json::value_t::discarded)
                                 : json::parse(line, nullptr, /*allow_exceptions=*/false);
        const bool has_id = !req.is_discarded() && req.is_object() && req.contains("id");
        // JSON-RPC 2.0, Sect. 4: an id is a string, a number or null; an answer to any other
        // "id" carries null.
        json id = has_id ? req["id"] : json();
        if (!id.is_string() && !id.is_number()) id = nullptr;
        auto replies = std::make_shared<int>(0);
        daemon::handle_json_request(backend, s, line, subscription,
                                    [&s, replies, has_id, id, refused](const json& r) {
                                      check(++*replies == 1);
                                      check_reply(r, has_id ? &id : nullptr);
                                      if (refused)
                                        check(r["error"]["code"] == -32700 && r["id"].is_null());
                                      s.send_line(daemon::to_wire(r));
                                    });
        backend.complete();
        check(subscription.interval_ms >= 20 && subscription.interval_ms <= 60000);
        if (!req.is_discarded() && req.is_object()) check(*replies <= 1);
        if (req.is_discarded()) check(*replies == 1);  // a parse error is always answered
      },
      [](daemon::ClientSession&) {});
  // Chunked like socket reads: the first byte picks the chunk size.
  const size_t chunk = size > 0 ? 1 + data[0] * 64 : 1;
  const std::string_view stream(reinterpret_cast<const char*>(data), size);
  for (size_t i = 1; i < stream.size(); i += chunk) session->feed(stream.substr(i, chunk));
  session->feed("\n");
  return 0;
}
