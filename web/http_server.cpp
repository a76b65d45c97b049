#include "web/http_server.hpp"

#include <spdlog/spdlog.h>

#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <chrono>
#include <deque>
#include <filesystem>
#include <map>

#include "core/clock.hpp"
#include "web/spooled_body.hpp"

namespace feedloop::web {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
namespace fs = std::filesystem;

// Every session, so that stop() can close them.
struct SessionBase {
  virtual ~SessionBase() = default;
  virtual void close() = 0;
};

struct HttpServer::Shared {
  MoonrakerApi* api = nullptr;
  AccessPolicy access;
  ServerOptions options;
  ServerStats stats;
  std::list<std::weak_ptr<SessionBase>> sessions;  // to close them at stop
  bool stopped = false;
  int64_t last_refusal_log_ns = 0;
};

namespace {
// "/a?x=1&y=%20" -> {x: "1", y: " "}.
std::map<std::string, std::string> query_of(std::string_view target) {
  std::map<std::string, std::string> query;
  const size_t q = target.find('?');
  if (q == std::string_view::npos) return query;
  const std::string_view qs = target.substr(q + 1);
  size_t b = 0;
  while (b < qs.size()) {
    size_t e = qs.find('&', b);
    if (e == std::string_view::npos) e = qs.size();
    const std::string_view kv = qs.substr(b, e - b);
    const size_t eq = kv.find('=');
    if (!kv.empty())
      query[url_decode(kv.substr(0, eq), true)] =
          eq == std::string_view::npos ? "" : url_decode(kv.substr(eq + 1), true);
    b = e + 1;
  }
  return query;
}
}  // namespace

std::string url_decode(std::string_view s, bool plus_is_space) {
  std::string out;
  out.reserve(s.size());
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hex(s[i + 1]) >= 0 && hex(s[i + 2]) >= 0) {
      out += static_cast<char>(hex(s[i + 1]) * 16 + hex(s[i + 2]));
      i += 2;
    } else if (plus_is_space && s[i] == '+') {
      out += ' ';
    } else {
      out += s[i];
    }
  }
  return out;
}

const char* HttpServer::mime_type(std::string_view path) {
  const size_t dot = path.find_last_of('.');
  const std::string_view ext =
      dot == std::string_view::npos ? std::string_view() : path.substr(dot);
  if (ext == ".html" || ext == ".htm") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript";
  if (ext == ".css") return "text/css";
  if (ext == ".json") return "application/json";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".ico") return "image/x-icon";
  if (ext == ".woff2") return "font/woff2";
  if (ext == ".woff") return "font/woff";
  if (ext == ".ttf") return "font/ttf";
  if (ext == ".webmanifest") return "application/manifest+json";
  if (ext == ".wasm") return "application/wasm";
  if (ext == ".txt" || ext == ".gcode") return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

namespace {

// feedloop's page: under /server/ because the UIs' service workers answer every other page path
// with their own index.html (Mainsail's leaves /server, /printer, /api... to the network).
constexpr std::string_view kPagePrefix = "/server/feedloop/page/";

std::string static_file_in(const ServerOptions& o, std::string_view raw_path) {
  std::string path = url_decode(raw_path, false);
  if (path.find('\0') != std::string::npos || path.find("/../") != std::string::npos ||
      (path.size() >= 3 && path.compare(path.size() - 3, 3, "/..") == 0) ||
      path.find('\\') != std::string::npos)
    return {};
  std::string dir;
  std::string rest;
  auto under = [&](std::string_view prefix) {
    return path.size() >= prefix.size() && path.compare(0, prefix.size(), prefix) == 0;
  };
  if (under(kPagePrefix)) {
    const std::string_view uplot = "uplot/";
    rest = path.substr(kPagePrefix.size());
    if (rest.compare(0, uplot.size(), uplot) == 0) {
      dir = o.uplot_dir;
      rest = rest.substr(uplot.size());
    } else {
      dir = o.page_dir;
    }
    if (dir.empty()) return {};
  } else if (!o.ui_dir.empty()) {
    dir = o.ui_dir;
    rest = path.substr(1);
  } else {
    return {};
  }
  if (rest.empty() || rest.back() == '/') rest += "index.html";
  std::error_code ec;
  const fs::path p = fs::path(dir) / rest;
  if (fs::is_regular_file(p, ec)) return p.string();
  // Mainsail's router runs in history mode: a page path (no extension in its last part) is
  // index.html. An asset that is missing stays a 404.
  const std::string last =
      rest.substr(rest.find_last_of('/') == std::string::npos ? 0 : rest.find_last_of('/') + 1);
  if (last.find('.') == std::string::npos) {
    const fs::path index = fs::path(dir) / "index.html";
    if (fs::is_regular_file(index, ec)) return index.string();
  }
  return {};
}

http::response<http::string_body> text_response(unsigned version, bool keep_alive,
                                                http::status status, std::string content_type,
                                                std::string body) {
  http::response<http::string_body> res{status, version};
  res.set(http::field::server, "feedloop");
  res.set(http::field::content_type, content_type);
  res.set(http::field::cache_control, "no-cache");
  res.keep_alive(keep_alive);
  res.body() = std::move(body);
  res.prepare_payload();
  return res;
}

http::response<http::string_body> redirect(unsigned version, bool keep_alive,
                                           const std::string& to) {
  http::response<http::string_body> res{http::status::moved_permanently, version};
  res.set(http::field::server, "feedloop");
  res.set(http::field::location, to);
  res.keep_alive(keep_alive);
  res.prepare_payload();
  return res;
}

std::string error_json(int status, const std::string& message) {
  return nlohmann::json{{"error", {{"code", status}, {"message", message}}}}.dump(
      -1, ' ', false, nlohmann::json::error_handler_t::replace);
}

// ---- WebSocket ------------------------------------------------------------------------------

class WsSession final : public SessionBase, public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket socket, std::shared_ptr<HttpServer::Shared> shared)
      : ws_(std::move(socket)), shared_(std::move(shared)) {}

  template <class Request>
  void start(const Request& req) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(shared_->options.max_ws_message_bytes);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "feedloop"); }));
    ws_.async_accept(req,
                     [self = shared_from_this()](beast::error_code ec) { self->on_accept(ec); });
  }

  bool enqueue(std::shared_ptr<const std::string> text) {
    if (closed_) return false;
    if (queued_bytes_ + text->size() > shared_->options.max_ws_queue_bytes) {
      ++shared_->stats.slow_readers_dropped;
      spdlog::warn("web: dropping WebSocket client {}: it does not read ({} bytes unsent)", remote_,
                   queued_bytes_);
      close();
      return false;
    }
    queued_bytes_ += text->size();
    queue_.push_back(std::move(text));
    if (!writing_) write_next();
    return true;
  }

  void close() override {
    if (closed_) return;
    closed_ = true;
    if (conn_ != 0) {
      const uint64_t c = conn_;
      conn_ = 0;
      // Not from inside the API's own send loop: the API erases the connection itself there.
      asio::post(ws_.get_executor(), [shared = shared_, c] {
        if (!shared->stopped) shared->api->close_connection(c);
      });
    }
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
    beast::get_lowest_layer(ws_).close();
  }

 private:
  void on_accept(beast::error_code ec) {
    if (ec || shared_->stopped) {
      ++shared_->stats.bad_requests;
      return;
    }
    beast::error_code rec;
    const auto ep = beast::get_lowest_layer(ws_).socket().remote_endpoint(rec);
    remote_ = rec ? std::string("?") : ep.address().to_string() + ":" + std::to_string(ep.port());
    std::weak_ptr<WsSession> weak = shared_from_this();
    conn_ = shared_->api->open_connection([weak](std::shared_ptr<const std::string> text) {
      auto s = weak.lock();
      return s && s->enqueue(std::move(text));
    });
    read();
  }

  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, size_t) {
      if (ec) {
        if (ec == websocket::error::message_too_big) {
          ++self->shared_->stats.bad_requests;
          spdlog::warn("web: closing WebSocket client {}: a message over {} bytes", self->remote_,
                       self->shared_->options.max_ws_message_bytes);
        }
        self->close();
        return;
      }
      ++self->shared_->stats.ws_messages;
      const std::string text = beast::buffers_to_string(self->buffer_.data());
      self->buffer_.consume(self->buffer_.size());
      if (self->conn_ != 0 && !self->shared_->stopped) {
        try {
          self->shared_->api->on_message(self->conn_, text);
        } catch (const std::exception& e) {
          spdlog::error("web: internal error on a WebSocket message: {}", e.what());
        }
      }
      if (!self->closed_) self->read();
    });
  }

  void write_next() {
    if (queue_.empty() || closed_) {
      writing_ = false;
      return;
    }
    writing_ = true;
    ws_.text(true);
    ws_.async_write(asio::buffer(*queue_.front()),
                    [self = shared_from_this()](beast::error_code ec, size_t) {
                      if (ec) {
                        self->writing_ = false;
                        self->close();
                        return;
                      }
                      self->queued_bytes_ -= self->queue_.front()->size();
                      self->queue_.pop_front();
                      self->write_next();
                    });
  }

  websocket::stream<beast::tcp_stream> ws_;
  std::shared_ptr<HttpServer::Shared> shared_;
  beast::flat_buffer buffer_;
  std::deque<std::shared_ptr<const std::string>> queue_;
  size_t queued_bytes_ = 0;
  bool writing_ = false;
  bool closed_ = false;
  uint64_t conn_ = 0;
  std::string remote_;
};

// ---- HTTP -----------------------------------------------------------------------------------

class HttpSession final : public SessionBase, public std::enable_shared_from_this<HttpSession> {
 public:
  static constexpr size_t kHeaderLimitBytes = 16 * 1024;  // a request's header (docs/web.md)
  static constexpr size_t kUploadChunkBytes = 64 * 1024;  // an upload is read and spooled in these

  HttpSession(tcp::socket socket, std::shared_ptr<HttpServer::Shared> shared)
      : stream_(std::move(socket)), shared_(std::move(shared)) {}

  void start() { read(); }
  void close() override {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
    stream_.close();
  }

 private:
  void read() {
    upload_parser_.reset();
    spool_.reset();
    parser_.emplace();
    parser_->header_limit(kHeaderLimitBytes);
    // The parser checks a Content-Length against its limit while it reads the header, before
    // on_header can tell an upload from another request: it reads with the larger limit, and
    // on_header applies the request's own.
    parser_->body_limit(
        std::max(shared_->options.max_body_bytes, shared_->options.max_upload_bytes));
    stream_.expires_after(std::chrono::seconds(shared_->options.read_timeout_s));
    http::async_read_header(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](beast::error_code ec, size_t) { self->on_header(ec); });
  }

  void on_header(beast::error_code ec) {
    if (ec) return fail(ec);
    const auto& req = parser_->get();
    const std::string_view target(req.target().data(), req.target().size());
    const bool upload = MoonrakerApi::is_upload_path(target.substr(0, target.find('?')));
    const size_t limit =
        upload ? shared_->options.max_upload_bytes : shared_->options.max_body_bytes;
    if (const auto length = parser_->content_length(); length && *length > limit)
      return fail(http::error::body_limit);
    parser_->body_limit(limit);  // a chunked body counts against it as it is read
    if (parser_->is_done()) return on_request();
    // An upload from a client that may not upload is refused before any of its body is stored.
    if (upload && !authorized(req, query_of(target))) return refuse_unauthorized(req.version());
    // A client that asked to be told to go on (libcurl does for bodies over 1 MiB, so slicers'
    // uploads) waited a second for it before sending the body.
    if (beast::iequals(req[http::field::expect], "100-continue")) {
      auto go_on = std::make_shared<http::response<http::empty_body>>(http::status::continue_,
                                                                      req.version());
      return http::async_write(
          stream_, *go_on,
          [self = shared_from_this(), go_on, upload, limit](beast::error_code ec2, size_t) {
            if (ec2) return self->fail(ec2);
            self->read_body(upload, limit);
          });
    }
    read_body(upload, limit);
  }

  void read_body(bool upload, size_t limit) {
    if (upload) return start_upload(limit);
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, size_t) {
                       if (ec) return self->fail(ec);
                       self->on_request();
                     });
  }

  // An upload's body goes to a temporary file (web/spooled_body.hpp), read in chunks, each with
  // its own read deadline: memory stays one chunk whatever the announced length, and a large file
  // over a slow link is not cut by a deadline meant for one request's header.
  void start_upload(size_t limit) {
    auto spool = SpooledBody::create(shared_->options.upload_dir);
    if (!spool) return refuse_upload(spool.error().message);
    spool_ = std::move(*spool);
    upload_parser_.emplace(std::move(*parser_));
    upload_parser_->body_limit(limit);
    if (!chunk_) chunk_ = std::make_unique<char[]>(kUploadChunkBytes);
    read_upload_chunk();
  }

  void read_upload_chunk() {
    auto& body = upload_parser_->get().body();
    body.data = chunk_.get();
    body.size = kUploadChunkBytes;
    body.more = true;
    stream_.expires_after(std::chrono::seconds(shared_->options.read_timeout_s));
    http::async_read(stream_, buffer_, *upload_parser_,
                     [self = shared_from_this()](beast::error_code ec, size_t) {
                       if (ec == http::error::need_buffer) ec = {};
                       if (ec) return self->fail(ec);
                       const size_t got =
                           kUploadChunkBytes - self->upload_parser_->get().body().size;
                       if (Status s = self->spool_->append(self->chunk_.get(), got); !s)
                         return self->refuse_upload(s.error().message);
                       if (self->upload_parser_->is_done()) return self->on_request();
                       self->read_upload_chunk();
                     });
  }

  // The API's access check (web/access.hpp): the X-Api-Key header, or ?token= in the URL.
  bool authorized(const http::request_header<>& req,
                  const std::map<std::string, std::string>& query) {
    beast::error_code ec;
    const auto remote = stream_.socket().remote_endpoint(ec);
    std::string key(req["X-Api-Key"]);
    if (key.empty()) {
      if (auto it = query.find("token"); it != query.end()) key = it->second;
    }
    return !ec && shared_->access.allowed(remote.address(), key);
  }

  void refuse_unauthorized(unsigned version) {
    ++shared_->stats.unauthorized;
    send(text_response(version, false, http::status::unauthorized, "application/json",
                       error_json(401, "Unauthorized")));
  }

  // The server could not keep an upload (no temporary file, disk full): 507, and the connection
  // closes (the rest of the body is not read).
  void refuse_upload(const std::string& message) {
    spdlog::warn("web: {}", message);
    send(text_response(11, false, http::status::insufficient_storage, "application/json",
                       error_json(507, message)));
  }

  void fail(beast::error_code ec) {
    if (ec != http::error::end_of_stream && ec != asio::error::operation_aborted &&
        ec != beast::error::timeout && ec != asio::error::eof &&
        ec != asio::error::connection_reset) {
      ++shared_->stats.bad_requests;
      if (ec == http::error::body_limit || ec == http::error::header_limit) {
        auto res = text_response(11, false, http::status::payload_too_large, "application/json",
                                 error_json(413, "request too large"));
        return send(std::move(res));
      }
      auto res = text_response(11, false, http::status::bad_request, "application/json",
                               error_json(400, ec.message()));
      return send(std::move(res));
    }
    close();
  }

  void on_request() {
    ++shared_->stats.http_requests;
    stream_.expires_never();
    // An upload's header is in its own parser (start_upload moved the first parser's into it).
    auto& req = upload_parser_ ? upload_parser_->get().base() : parser_->get().base();
    const std::string target(req.target());
    const size_t q = target.find('?');
    HttpRequest r;
    r.method = std::string(req.method_string());
    r.path = url_decode(target.substr(0, q), false);
    r.query = query_of(target);
    const unsigned version = req.version();
    const bool keep_alive = upload_parser_ ? upload_parser_->keep_alive() : parser_->keep_alive();
    const bool api = MoonrakerApi::is_api_path(r.path);
    if (api && !authorized(req, r.query)) return refuse_unauthorized(version);
    if (r.path.rfind(kPagePrefix, 0) == 0 ||
        r.path == kPagePrefix.substr(0, kPagePrefix.size() - 1)) {
      if (r.path.size() < kPagePrefix.size())
        return send(redirect(version, keep_alive, std::string(kPagePrefix)));
      const std::string file = static_file_in(shared_->options, r.path);
      if (file.empty())
        return send(text_response(version, keep_alive, http::status::not_found, "text/plain",
                                  "not found\n"));
      return send_file(version, keep_alive, file, HttpServer::mime_type(file));
    }
    if (r.path == "/websocket" && !upload_parser_) {
      if (!websocket::is_upgrade(req)) {
        return send(text_response(version, keep_alive, http::status::bad_request,
                                  "application/json",
                                  error_json(400, "expected a WebSocket upgrade")));
      }
      auto ws = std::make_shared<WsSession>(stream_.release_socket(), shared_);
      shared_->sessions.push_back(std::weak_ptr<SessionBase>(ws));
      ws->start(parser_->release());
      return;
    }
    if (api) {
      r.content_type = std::string(req[http::field::content_type]);
      if (spool_) {
        auto bytes = spool_->bytes();
        if (!bytes) return refuse_upload(bytes.error().message);
        r.spooled = *bytes;
      } else {
        r.body = std::move(parser_->get().body());
      }
      // The reply may come later (a G-code script answers when the machine has run it). Until
      // then the session is held by a wait on its socket (watch_while_deferred), not by the
      // callback: a client that goes away frees its connection slot at once, whatever the script
      // still does (64 dropped `G4 P30000` requests held every slot for half an hour), and a
      // reply that finds the session gone is dropped.
      const uint64_t request = ++request_count_;
      std::weak_ptr<HttpSession> weak = shared_from_this();
      try {
        shared_->api->on_http(r, [weak, request, version, keep_alive](HttpReply reply) {
          auto self = weak.lock();
          if (!self) return;
          self->replied_ = request;
          if (!reply.file_path.empty())
            return self->send_file(version, keep_alive, reply.file_path, reply.content_type);
          self->send(text_response(version, keep_alive, static_cast<http::status>(reply.status),
                                   reply.content_type, std::move(reply.body)));
        });
      } catch (const std::exception& e) {
        send(text_response(version, keep_alive, http::status::internal_server_error,
                           "application/json",
                           error_json(500, std::string("internal error: ") + e.what())));
        replied_ = request;
      }
      if (replied_ != request) watch_while_deferred(request);
      return;
    }
    if (req.method() != http::verb::get && req.method() != http::verb::head)
      return send(text_response(version, keep_alive, http::status::method_not_allowed, "text/plain",
                                "method not allowed\n"));
    const std::string file = static_file_in(shared_->options, r.path);
    if (file.empty())
      return send(
          text_response(version, keep_alive, http::status::not_found, "text/plain", "not found\n"));
    send_file(version, keep_alive, file, HttpServer::mime_type(file));
  }

  void send_file(unsigned version, bool keep_alive, const std::string& path,
                 const std::string& content_type) {
    http::file_body::value_type body;
    beast::error_code ec;
    body.open(path.c_str(), beast::file_mode::scan, ec);
    if (ec || fs::is_directory(path))
      return send(text_response(version, keep_alive, http::status::not_found, "application/json",
                                error_json(404, "File not found")));
    http::response<http::file_body> res{std::piecewise_construct, std::make_tuple(std::move(body)),
                                        std::make_tuple(http::status::ok, version)};
    res.set(http::field::server, "feedloop");
    res.set(http::field::content_type, content_type);
    // index.html and config.json change with the build; the hashed assets do not.
    res.set(http::field::cache_control,
            path.find("/assets/") != std::string::npos ? "max-age=86400" : "no-cache");
    res.keep_alive(keep_alive);
    res.prepare_payload();
    send(std::move(res));
  }

  // While a reply is deferred: waits for the socket to become readable. Readable with nothing to
  // read is the client gone (end of stream): the session closes and, once the wait's handler
  // returns, is freed. Bytes of a next request (pipelining) are taken into the read buffer, up to
  // the header limit, and the wait goes on.
  void watch_while_deferred(uint64_t request) {
    stream_.socket().async_wait(
        tcp::socket::wait_read, [self = shared_from_this(), request](beast::error_code ec) {
          if (ec || self->replied_ == request || !self->stream_.socket().is_open()) return;
          beast::error_code ec2;
          const size_t available = self->stream_.socket().available(ec2);
          if (ec2 || available == 0 || self->buffer_.size() + available > kHeaderLimitBytes)
            return self->close();
          const size_t n = self->stream_.socket().read_some(self->buffer_.prepare(available), ec2);
          if (ec2) return self->close();
          self->buffer_.commit(n);
          self->watch_while_deferred(request);
        });
  }

  template <class Response>
  void send(Response&& res) {
    auto sp = std::make_shared<std::decay_t<Response>>(std::forward<Response>(res));
    const bool close_after = !sp->keep_alive();
    stream_.expires_after(std::chrono::seconds(shared_->options.read_timeout_s));
    http::async_write(stream_, *sp,
                      [self = shared_from_this(), sp, close_after](beast::error_code ec, size_t) {
                        if (ec || close_after) return self->close();
                        self->read();
                      });
  }

  beast::tcp_stream stream_;
  std::shared_ptr<HttpServer::Shared> shared_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::optional<http::request_parser<http::buffer_body>> upload_parser_;  // while uploading
  std::unique_ptr<SpooledBody> spool_;                                    // the upload's body
  std::unique_ptr<char[]> chunk_;  // kUploadChunkBytes, allocated at a session's first upload
  uint64_t request_count_ = 0;  // API requests on this connection
  uint64_t replied_ = 0;        // the last of them whose reply was sent
};

}  // namespace

HttpServer::HttpServer(asio::io_context& io, MoonrakerApi& api, AccessPolicy access,
                       ServerOptions options)
    : api_(api),
      acceptor_(io),
      timer_(io),
      shared_(std::make_shared<Shared>()),
      stats_(shared_->stats) {
  shared_->api = &api;
  shared_->access = std::move(access);
  shared_->options = std::move(options);
}

HttpServer::~HttpServer() {
  stop();
}

std::string HttpServer::static_file(std::string_view path) const {
  return static_file_in(shared_->options, path);
}

Status HttpServer::start() {
  beast::error_code ec;
  const auto addr = asio::ip::make_address(shared_->options.address, ec);
  if (ec) return Error{"web.address: '" + shared_->options.address + "' is not an IP address"};
  const tcp::endpoint ep(addr, static_cast<uint16_t>(shared_->options.port));
  acceptor_.open(ep.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(ep, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    return Error{"web: cannot listen on " + shared_->options.address + ":" +
                 std::to_string(shared_->options.port) + ": " + ec.message()};
  bound_port_ = acceptor_.local_endpoint().port();
  running_ = true;
  accept();
  arm_tick();
  return Status::Ok();
}

void HttpServer::stop() {
  if (!running_) return;
  running_ = false;
  shared_->stopped = true;
  beast::error_code ignored;
  acceptor_.close(ignored);
  timer_.cancel();
  for (auto& w : shared_->sessions)
    if (auto s = w.lock()) s->close();
  shared_->sessions.clear();
}

void HttpServer::arm_tick() {
  timer_.expires_after(std::chrono::milliseconds(shared_->options.tick_ms));
  timer_.async_wait([this](const beast::error_code& ec) {
    if (ec || !running_) return;
    // Drop expired session entries and count the open ones.
    shared_->sessions.remove_if([](const std::weak_ptr<SessionBase>& w) { return w.expired(); });
    stats_.open_sessions = shared_->sessions.size();
    try {
      api_.tick(seconds_from_ns(MonotonicClock().now_ns()));
    } catch (const std::exception& e) {
      spdlog::error("web: internal error in the periodic update: {}", e.what());
    }
    arm_tick();
  });
}

void HttpServer::accept() {
  acceptor_.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (!running_) return;
    if (!ec) {
      ++stats_.accepted;
      shared_->sessions.remove_if([](const std::weak_ptr<SessionBase>& w) { return w.expired(); });
      if (shared_->sessions.size() >= shared_->options.max_connections) {
        ++stats_.refused_over_limit;
        const int64_t now = MonotonicClock().now_ns();
        if (now - shared_->last_refusal_log_ns > 10 * kNsPerS) {
          spdlog::warn("web: refusing connections: {} open (web max_connections)",
                       shared_->sessions.size());
          shared_->last_refusal_log_ns = now;
        }
        beast::error_code ignored;
        socket.close(ignored);
      } else {
        auto s = std::make_shared<HttpSession>(std::move(socket), shared_);
        shared_->sessions.push_back(std::weak_ptr<SessionBase>(s));
        s->start();
      }
    }
    accept();
  });
}

}  // namespace feedloop::web
