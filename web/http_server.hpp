// The web server: HTTP/1.1 and WebSocket (Boost.Beast) on the daemon's Asio I/O thread. It serves
// the UI's static files (Mainsail at /, index.html for unknown page paths), feedloop's page at
// /server/feedloop/page/ (uPlot at /server/feedloop/page/uplot/; under /server/ so that the UIs'
// service workers leave it alone, and behind the same access check as the API), and the Moonraker
// API (web/moonraker_api.hpp) over HTTP routes and /websocket. Nothing here touches the machine's
// threads: the API reads snapshots and submits G-code through the daemon like any client.
//
// Hostile input is bounded: at most max_connections at once (more are closed at accept), request
// headers 16 KiB, request bodies 1 MiB (uploads max_upload_bytes, spooled to an unnamed file in
// upload_dir as they arrive, never held in memory), WebSocket messages max_ws_message_bytes, a
// read must finish within 30 s (an upload: each 64 KiB of it), and each WebSocket has a bounded
// send queue: a client that does not read (its queue over max_ws_queue_bytes) is dropped with a log
// line instead of growing the daemon's memory.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>

#include <list>
#include <memory>
#include <string>

#include "core/result.hpp"
#include "web/access.hpp"
#include "web/moonraker_api.hpp"

namespace feedloop::web {

struct ServerOptions {
  std::string address = "127.0.0.1";
  int port = 7125;  // 0: any free port (tests)
  std::string ui_dir, page_dir, uplot_dir;
  size_t max_connections = 64;
  size_t max_body_bytes = 1 << 20;
  size_t max_upload_bytes = 256u << 20;
  std::string upload_dir;  // where uploads are spooled while they arrive ("": the system's /tmp)
  size_t max_ws_message_bytes = 1 << 20;
  size_t max_ws_queue_bytes = 4u << 20;
  int read_timeout_s = 30;
  int tick_ms = 50;
};

struct ServerStats {
  uint64_t accepted = 0;
  uint64_t refused_over_limit = 0;
  uint64_t unauthorized = 0;
  uint64_t slow_readers_dropped = 0;
  uint64_t http_requests = 0;
  uint64_t ws_messages = 0;
  uint64_t bad_requests = 0;  // malformed HTTP or WebSocket input, oversized messages
  size_t open_sessions = 0;
};

class HttpServer {
 public:
  HttpServer(boost::asio::io_context& io, MoonrakerApi& api, AccessPolicy access,
             ServerOptions options);
  ~HttpServer();
  Status start();
  void stop();
  uint16_t port() const { return bound_port_; }
  const ServerStats& stats() const { return stats_; }

  // The file a static path maps to ("" when none): used by the sessions and the tests.
  std::string static_file(std::string_view path) const;
  static const char* mime_type(std::string_view path);

  // Internal: the sessions' shared state.
  struct Shared;

 private:
  void accept();
  void arm_tick();

  MoonrakerApi& api_;
  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::steady_timer timer_;
  std::shared_ptr<Shared> shared_;
  ServerStats& stats_;
  uint16_t bound_port_ = 0;
  bool running_ = false;
};

// "%41b%20c" -> "Ab c"; `plus_is_space` for query strings. Invalid escapes are kept as they are.
std::string url_decode(std::string_view s, bool plus_is_space);

}  // namespace feedloop::web
