#include "daemon/json_api.hpp"

#include <algorithm>  // std::clamp
#include <cmath>
#include <cstdio>

#include "core/json_depth.hpp"
#include "core/result.hpp"
#include "core/utf8.hpp"

namespace feedloop::daemon {

using nlohmann::json;

json json_rpc_error(const json& id, int code, const std::string& message) {
  return json{{"jsonrpc", "2.0"}, {"id", id}, {"error", {{"code", code}, {"message", message}}}};
}

std::string to_wire(const json& message) {
  return message.dump(-1, ' ', /*ensure_ascii=*/false, json::error_handler_t::replace);
}

json json_rpc_notification(const std::string& method, json params) {
  return json{{"jsonrpc", "2.0"}, {"method", method}, {"params", std::move(params)}};
}

std::string result_wire(const json& id, std::string_view result_text) {
  // nlohmann's objects keep their keys sorted: "id", "jsonrpc", "result".
  std::string out;
  const std::string id_text = to_wire(id);
  out.reserve(result_text.size() + id_text.size() + 32);
  out += "{\"id\":";
  out += id_text;
  out += ",\"jsonrpc\":\"2.0\",\"result\":";
  out += result_text;
  out += '}';
  return out;
}

std::shared_ptr<const std::string> JsonApiBackend::status_text() {
  return std::make_shared<const std::string>(to_wire(status()));
}

namespace {

// One reply: a JSON value, or text already serialised (the status snapshot spliced in).
struct Reply {
  const json* value = nullptr;
  std::string_view wire;
};
using ReplyFn = std::function<void(const Reply&)>;

json result_of(const json& id, json result) {
  return json{{"jsonrpc", "2.0"}, {"id", id}, {"result", std::move(result)}};
}

Status read_topics(const json& params, Subscription& sub, bool on) {
  if (!params.contains("topics")) return Status::Ok();
  const json& topics = params["topics"];
  if (!topics.is_array()) return Error{"'topics' must be an array of strings"};
  for (const json& t : topics) {
    if (!t.is_string()) return Error{"'topics' must be an array of strings"};
    const std::string name = t.get<std::string>();
    if (name == "status")
      sub.status = on;
    else if (name == "events")
      sub.events = on;
    else
      return Error{"unknown topic '" + name + "' (known: status, events)"};
  }
  return Status::Ok();
}

}  // namespace

namespace {

// The request's "id" when it is one JSON-RPC allows (string, number, null); else null.
json request_id(const json& req) {
  if (!req.is_object() || !req.contains("id")) return nullptr;
  const json& id = req["id"];
  if (id.is_string() || id.is_number_integer() || id.is_number_unsigned() || id.is_null())
    return id;
  if (id.is_number_float() && std::isfinite(id.get<double>())) return id;
  return nullptr;
}

void dispatch(JsonApiBackend& backend, ClientSession& client, const json& req,
              Subscription& subscription, const ReplyFn& out) {
  auto reply = [&out](const json& r) { out(Reply{&r, {}}); };
  if (!req.is_object() || req.value("jsonrpc", "") != "2.0" || !req.contains("method") ||
      !req["method"].is_string()) {
    reply(json_rpc_error(
        request_id(req), -32600,
        "invalid request: expected {\"jsonrpc\":\"2.0\",\"method\":...,\"id\":...}"));
    return;
  }
  const bool notification = !req.contains("id");
  const json id = request_id(req);
  if (!notification && id.is_null() && !req["id"].is_null()) {
    reply(json_rpc_error(nullptr, -32600,
                         "invalid request: 'id' must be a string, a number or null"));
    return;
  }
  const std::string method = req["method"].get<std::string>();
  const json params = req.contains("params") ? req["params"] : json::object();
  auto respond = [&](json r) {
    if (!notification) reply(r);
  };
  if (!params.is_object()) {
    respond(json_rpc_error(id, -32602, "params must be an object"));
    return;
  }

  if (method == "info") {
    respond(result_of(id, backend.info()));
  } else if (method == "status") {
    if (notification) return;
    const std::shared_ptr<const std::string> text = backend.status_text();
    const std::string wire = result_wire(id, *text);
    out(Reply{nullptr, wire});
  } else if (method == "subscribe" || method == "unsubscribe") {
    const bool on = method == "subscribe";
    Subscription next = subscription;
    if (Status s = read_topics(params, next, on); !s) {
      respond(json_rpc_error(id, -32602, s.error().message));
      return;
    }
    if (on && params.contains("interval_ms")) {
      const json& v = params["interval_ms"];
      if (!v.is_number() || !std::isfinite(v.get<double>())) {
        respond(json_rpc_error(id, -32602, "'interval_ms' must be a number"));
        return;
      }
      // Clamped as a double first: a cast of 1e30 to int is undefined behaviour.
      next.interval_ms = static_cast<int>(std::clamp(v.get<double>(), 20.0, 60000.0));
    }
    subscription = next;
    respond(result_of(id, {{"status", subscription.status},
                           {"events", subscription.events},
                           {"interval_ms", subscription.interval_ms}}));
  } else if (method == "gcode") {
    if (!params.contains("script") || !params["script"].is_string()) {
      respond(json_rpc_error(id, -32602, "'script' (a string of G-code lines) is required"));
      return;
    }
    backend.run_script(client, params["script"].get<std::string>(),
                       [out, id, notification](json result, std::string error) {
                         if (notification) return;
                         const json r = !error.empty() ? json_rpc_error(id, -32000, error)
                                                       : result_of(id, std::move(result));
                         out(Reply{&r, {}});
                       });
  } else if (method == "emergency_stop") {
    std::string reason = "requested over the JSON API";
    if (params.contains("reason") && params["reason"].is_string()) reason = params["reason"];
    backend.emergency_stop(reason);
    respond(result_of(id, {{"stopped", true}}));
  } else if (std::optional<MethodResult> r = backend.call_method(client, method, params)) {
    if (r->code != 0) respond(json_rpc_error(id, r->code, r->error));
    else respond(result_of(id, std::move(r->result)));
  } else {
    respond(json_rpc_error(id, -32601,
                           "unknown method '" + valid_utf8(method) +
                               "' (known: info, status, subscribe, unsubscribe, "
                               "gcode, emergency_stop, files.list, files.upload, files.delete, "
                               "job.start, job.pause, job.resume, job.cancel, job.status)"));
  }
}

void handle_request(JsonApiBackend& backend, ClientSession& client, std::string_view line,
                    Subscription& subscription, const ReplyFn& out) {
  auto reply = [&out](const json& r) { out(Reply{&r, {}}); };
  // The outside-string boundary (core/utf8.hpp): a request must be UTF-8 (RFC 8259 Sect. 8.1).
  // Checked here so the error can say where, and so no invalid byte reaches a reply.
  {
    size_t bad = 0;
    for (size_t i = 0; i < line.size();) {
      if (line[i] == '\0') {
        // The JSON parser would stop here and ignore the rest of the line (a second request
        // behind it would get no answer): no JSON text has a NUL byte.
        reply(json_rpc_error(
            nullptr, -32700,
            "parse error at column " + std::to_string(i + 1) + ": a NUL byte in the request"));
        return;
      }
      const size_t n = utf8_sequence_length(line, i, &bad);
      if (n == 0) {
        reply(json_rpc_error(
            nullptr, -32700,
            "parse error at column " + std::to_string(i + 1) +
                ": the request is not valid UTF-8 (byte 0x" +
                [&] {
                  char hex[3];
                  std::snprintf(hex, sizeof hex, "%02X",
                                static_cast<unsigned>(static_cast<uint8_t>(line[i])));
                  return std::string(hex);
                }() +
                ")"));
        return;
      }
      i += n;
    }
  }
  if (json_nesting_depth(line) > kMaxClientJsonDepth) {
    reply(json_rpc_error(nullptr, -32700,
                         "parse error: the request nests arrays or objects deeper than " +
                             std::to_string(kMaxClientJsonDepth) + " levels"));
    return;
  }
  json req;
  try {
    req = json::parse(line);
  } catch (const json::parse_error& e) {
    // e.byte is the 1-based position of the error in the line; keep the library's reason only.
    std::string why = e.what();
    if (const size_t p = why.find("column "); p != std::string::npos) {
      if (const size_t colon = why.find(": ", p); colon != std::string::npos)
        why = why.substr(colon + 2);
    }
    reply(
        json_rpc_error(nullptr, -32700,
                       "parse error at column " + std::to_string(e.byte) + ": " + valid_utf8(why)));
    return;
  } catch (const json::exception& e) {
    // out_of_range 406: a number the parser cannot hold ("id": 1e400).
    std::string why = e.what();
    if (const size_t p = why.find("] "); p != std::string::npos) why = why.substr(p + 2);
    reply(json_rpc_error(nullptr, -32700, "parse error: " + valid_utf8(why)));
    return;
  }
  try {
    dispatch(backend, client, req, subscription, out);
  } catch (const std::exception& e) {
    // A handler's failure is this request's error, never the daemon's end.
    reply(json_rpc_error(request_id(req), -32603,
                         std::string("internal error: ") + valid_utf8(e.what())));
  }
}

}  // namespace

// `reply` is copied: a gcode request answers after this call has returned.
void handle_json_request(JsonApiBackend& backend, ClientSession& client, std::string_view line,
                         Subscription& subscription,
                         const std::function<void(const json&)>& reply) {
  handle_request(backend, client, line, subscription, [reply](const Reply& r) {
    if (r.value != nullptr) reply(*r.value);
    else reply(json::parse(r.wire));
  });
}

void handle_json_request_wire(JsonApiBackend& backend, ClientSession& client, std::string_view line,
                              Subscription& subscription,
                              const std::function<void(std::string wire)>& reply) {
  handle_request(backend, client, line, subscription, [reply](const Reply& r) {
    if (r.value != nullptr) reply(to_wire(*r.value));
    else reply(std::string(r.wire));
  });
}

}  // namespace feedloop::daemon
