// The JSON API: newline-delimited JSON-RPC 2.0 on a Unix socket (one request object per line,
// one response per request; notifications for subscriptions).
//
// Methods:
//   info                      -> {name, version, kinematics, servo_rate_hz, api_version}
//   status                    -> the status object (state, position, temperatures, queue,
//                                servo cycles, deadline misses, latency, last error, clients)
//   subscribe {topics, interval_ms}  topics: "status", "events"; status is sent as a
//                                "status" notification every interval (default 250 ms, 20..60000)
//                                and events (errors, lost steps, ownership) as "event"
//   unsubscribe {topics}
//   gcode {script}            -> runs the lines as this client (print ownership applies); the
//                                response comes when every line has executed: {results:[...]}
//   emergency_stop {reason}
//   files.list, files.upload {filename, content | content_base64}, files.delete {filename},
//   job.start {filename}, job.pause, job.resume, job.cancel, job.status  (docs/jobs.md)
// `status` is served from a snapshot (JsonApiBackend::status_text): the daemon serialises the
// status at most once per period (and after each completed command) and every client gets that
// same text, spliced into its reply; the snapshot carries {"snapshot": {"seq", "period_ms"}}.
// Errors use JSON-RPC codes: -32700 parse error (with the column), -32600 invalid request,
// -32601 unknown method, -32602 invalid params, -32603 internal error, -32000 machine error.
// No request can end the daemon: a line that is not valid UTF-8, a number out of range (an "id"
// of 1e400), any exception a handler throws gets an error answer and the connection stays open.
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace feedloop::daemon {

class ClientSession;

// The answer of a method a backend adds (files.*, job.*): a result, or an error with its code.
struct MethodResult {
  nlohmann::json result;
  int code = 0;  // 0: success; else a JSON-RPC error code (-32602 invalid params, -32000 machine)
  std::string error;
};

// What the JSON API needs from the rest of the daemon.
class JsonApiBackend {
 public:
  virtual ~JsonApiBackend() = default;
  virtual nlohmann::json info() const = 0;
  virtual nlohmann::json status() const = 0;
  // The status object serialised (to_wire), shared by the replies until the next snapshot. The
  // default serialises status() for every call; the daemon's is a snapshot taken at most once
  // per period.
  virtual std::shared_ptr<const std::string> status_text();
  // Runs a G-code script for `client`; `done` receives {results:[{line, ok, error?, reply?}]}
  // or an error message (e.g. not the print owner) on the I/O thread.
  virtual void run_script(ClientSession& client, std::string script,
                          std::function<void(nlohmann::json result, std::string error)> done) = 0;
  virtual void emergency_stop(const std::string& reason) = 0;
  // Further methods (the daemon's files.* and job.*); nullopt: no such method.
  virtual std::optional<MethodResult> call_method(ClientSession& /*client*/, const std::string& /*method*/,
                                                  const nlohmann::json& /*params*/) {
    return std::nullopt;
  }
};

struct Subscription {
  bool status = false;
  bool events = false;
  int interval_ms = 250;
};

// Handles one request line of one client. Stateless apart from the client's subscription,
// which the caller keeps. `reply` is called zero (notification request) or one time, possibly
// later (gcode).
void handle_json_request(JsonApiBackend& backend, ClientSession& client, std::string_view line,
                         Subscription& subscription,
                         const std::function<void(const nlohmann::json&)>& reply);

// The same with every reply already serialised (to_wire) and without its '\n': the daemon's form,
// which splices the shared status text into `status` replies instead of building them.
void handle_json_request_wire(JsonApiBackend& backend, ClientSession& client, std::string_view line,
                              Subscription& subscription,
                              const std::function<void(std::string wire)>& reply);

// `{"id":ID,"jsonrpc":"2.0","result":RESULT}` around an already serialised result: byte for byte
// what to_wire() makes of the same reply.
std::string result_wire(const nlohmann::json& id, std::string_view result_text);

nlohmann::json json_rpc_error(const nlohmann::json& id, int code, const std::string& message);
// The one way the daemon serialises JSON for the wire: never throws. A string that is not valid
// UTF-8 (it should not reach here: core/utf8.hpp is applied where outside text enters) is sent
// with U+FFFD in place of its invalid bytes instead of aborting the print (nlohmann's default
// handler throws type_error 316 from dump()).
std::string to_wire(const nlohmann::json& message);
nlohmann::json json_rpc_notification(const std::string& method, nlohmann::json params);

}  // namespace feedloop::daemon
