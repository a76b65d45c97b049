#include "daemon/json_api.hpp"

#include <algorithm>  // std::clamp

#include "core/result.hpp"

namespace feedloop::daemon {

using nlohmann::json;

json json_rpc_error(const json& id, int code, const std::string& message) {
  return json{{"jsonrpc", "2.0"}, {"id", id}, {"error", {{"code", code}, {"message", message}}}};
}

json json_rpc_notification(const std::string& method, json params) {
  return json{{"jsonrpc", "2.0"}, {"method", method}, {"params", std::move(params)}};
}

namespace {

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
    if (name == "status") sub.status = on;
    else if (name == "events") sub.events = on;
    else return Error{"unknown topic '" + name + "' (known: status, events)"};
  }
  return Status::Ok();
}

}  // namespace

void handle_json_request(JsonApiBackend& backend, ClientSession& client, std::string_view line,
                         Subscription& subscription,
                         const std::function<void(const json&)>& reply) {
  json req;
  try {
    req = json::parse(line);
  } catch (const json::parse_error& e) {
    // e.byte is the 1-based position of the error in the line; keep the library's reason only.
    std::string why = e.what();
    if (const size_t p = why.find("column "); p != std::string::npos) {
      if (const size_t colon = why.find(": ", p); colon != std::string::npos) why = why.substr(colon + 2);
    }
    reply(json_rpc_error(nullptr, -32700,
                         "parse error at column " + std::to_string(e.byte) + ": " + why));
    return;
  }
  if (!req.is_object() || req.value("jsonrpc", "") != "2.0" || !req.contains("method") ||
      !req["method"].is_string()) {
    reply(json_rpc_error(req.is_object() && req.contains("id") ? req["id"] : json(nullptr), -32600,
                         "invalid request: expected {\"jsonrpc\":\"2.0\",\"method\":...,\"id\":...}"));
    return;
  }
  const bool notification = !req.contains("id");
  const json id = notification ? json(nullptr) : req["id"];
  const std::string method = req["method"].get<std::string>();
  const json params = req.value("params", json::object());
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
    respond(result_of(id, backend.status()));
  } else if (method == "subscribe" || method == "unsubscribe") {
    const bool on = method == "subscribe";
    Subscription next = subscription;
    if (Status s = read_topics(params, next, on); !s) {
      respond(json_rpc_error(id, -32602, s.error().message));
      return;
    }
    if (on && params.contains("interval_ms")) {
      if (!params["interval_ms"].is_number()) {
        respond(json_rpc_error(id, -32602, "'interval_ms' must be a number"));
        return;
      }
      next.interval_ms = std::clamp(params["interval_ms"].get<int>(), 20, 60000);
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
                       [reply, id, notification](json result, std::string error) {
                         if (notification) return;
                         if (!error.empty()) reply(json_rpc_error(id, -32000, error));
                         else reply(result_of(id, std::move(result)));
                       });
  } else if (method == "emergency_stop") {
    std::string reason = "requested over the JSON API";
    if (params.contains("reason") && params["reason"].is_string()) reason = params["reason"];
    backend.emergency_stop(reason);
    respond(result_of(id, {{"stopped", true}}));
  } else {
    respond(json_rpc_error(id, -32601, "unknown method '" + method +
                                           "' (known: info, status, subscribe, unsubscribe, "
                                           "gcode, emergency_stop)"));
  }
}

}  // namespace feedloop::daemon
