// The web server on a socket (web/http_server.hpp) with a fake printer: static files with
// Mainsail's fallback, the WebSocket API, and hostile clients (a malformed HTTP request, a huge
// WebSocket message, a huge body, more connections than allowed, a reader that never reads):
// each is refused or dropped, and the server goes on answering. The I/O loop's largest delay
// during the load is printed (timing is not asserted; bench/ holds the figures).
#include <gtest/gtest.h>

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <ifaddrs.h>
#include <malloc.h>
#include <netinet/in.h>
#include <poll.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "tests/web/fake_printer.hpp"
#include "web/http_server.hpp"

namespace feedloop::web {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using nlohmann::json;

struct Server {
  explicit Server(int read_timeout_s = 30, const std::string& address = "127.0.0.1") {
    dir =
        std::filesystem::temp_directory_path() / ("web_server_test_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir / "ui" / "assets");
    std::ofstream(dir / "ui" / "index.html") << "<html>mainsail</html>";
    std::ofstream(dir / "ui" / "assets" / "app.js") << "console.log(1)";
    files = std::make_unique<FileStore>(*FileStore::open((dir / "files").string()));
    db = Database::open(":memory:").value();
    api = std::make_unique<MoonrakerApi>(printer, *files, *db, MoonrakerApi::Options{});
    ServerOptions o;
    o.port = 0;
    o.ui_dir = (dir / "ui").string();
    o.max_connections = 32;
    o.max_ws_queue_bytes = 256 * 1024;
    o.read_timeout_s = read_timeout_s;
    o.address = address;
    server = std::make_unique<HttpServer>(io, *api, *AccessPolicy::create({}, "key"), o);
    EXPECT_TRUE(server->start());
    // The I/O loop's delay: a 1 ms timer, its worst lateness.
    arm_probe();
    thread = std::thread([this] { io.run(); });
  }
  ~Server() {
    asio::post(io, [this] {
      server->stop();
      probe.cancel();
    });
    io.stop();
    thread.join();
    std::filesystem::remove_all(dir);
  }
  void arm_probe() {
    const auto due = std::chrono::steady_clock::now() + std::chrono::milliseconds(1);
    probe.expires_at(due);
    probe.async_wait([this, due](const boost::system::error_code& ec) {
      if (ec) return;
      const double late_ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - due).count();
      if (late_ms > max_late_ms) max_late_ms = late_ms;
      arm_probe();
    });
  }
  // Runs fn on the I/O thread and waits.
  template <class F>
  auto on_io(F fn) {
    std::promise<decltype(fn())> p;
    asio::post(io, [&] { p.set_value(fn()); });
    return p.get_future().get();
  }
  std::filesystem::path dir;
  asio::io_context io;
  asio::steady_timer probe{io};
  std::atomic<double> max_late_ms{0.0};
  testing::FakePrinter printer;
  std::unique_ptr<FileStore> files;
  std::unique_ptr<Database> db;
  std::unique_ptr<MoonrakerApi> api;
  std::unique_ptr<HttpServer> server;
  std::thread thread;
};

http::response<http::string_body> get(uint16_t port, const std::string& target) {
  asio::io_context ctx;
  beast::tcp_stream s(ctx);
  s.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
  http::request<http::empty_body> req{http::verb::get, target, 11};
  req.set(http::field::host, "127.0.0.1");
  http::write(s, req);
  beast::flat_buffer b;
  http::response<http::string_body> res;
  http::read(s, b, res);
  return res;
}

struct WsClient {
  explicit WsClient(uint16_t port) : ws(ctx) {
    beast::get_lowest_layer(ws).connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    ws.handshake("127.0.0.1", "/websocket");
  }
  // Sends a request and reads until its reply (skipping notifications).
  json call(const std::string& method, const json& params, int id) {
    ws.write(asio::buffer(
        json{{"jsonrpc", "2.0"}, {"method", method}, {"params", params}, {"id", id}}.dump()));
    for (;;) {
      beast::flat_buffer b;
      ws.read(b);
      json j = json::parse(beast::buffers_to_string(b.data()));
      if (j.is_object() && j.contains("id") && j["id"] == id) return j;
    }
  }
  asio::io_context ctx;
  websocket::stream<beast::tcp_stream> ws;
};

TEST(WebServer, ServesTheUiWithMainsailsFallbackAndTheApi) {
  Server s;
  const uint16_t port = s.server->port();
  auto r = get(port, "/");
  EXPECT_EQ(r.result_int(), 200);
  EXPECT_EQ(r.body(), "<html>mainsail</html>");
  r = get(port, "/console");  // a page path of the history-mode router
  EXPECT_EQ(r.body(), "<html>mainsail</html>");
  r = get(port, "/assets/app.js");
  EXPECT_EQ(r[http::field::content_type], "text/javascript");
  EXPECT_EQ(get(port, "/assets/missing.js").result_int(), 404);
  EXPECT_EQ(get(port, "/../../etc/passwd").result_int(), 404);
  r = get(port, "/server/info");
  EXPECT_EQ(json::parse(r.body())["result"]["klippy_state"], "ready");
  r = get(port, "/printer/objects/query?extruder=target");
  EXPECT_EQ(json::parse(r.body())["result"]["status"]["extruder"].size(), 1u);
  EXPECT_EQ(get(port, "/server/nothing/here").result_int(), 404);
  WsClient c(port);
  EXPECT_EQ(
      c.call("server.connection.identify", {{"client_name", "test"}}, 0)["result"]["connection_id"],
      1);
}

// A multipart upload of `gcode` as "name", as a browser sends it (Content-Length).
std::string upload_request(const std::string& name, const std::string& gcode, bool chunked) {
  http::request<http::string_body> req{http::verb::post, "/server/files/upload", 11};
  req.set(http::field::host, "x");
  req.set(http::field::content_type, "multipart/form-data; boundary=XyZ");
  req.body() = "--XyZ\r\nContent-Disposition: form-data; name=\"file\"; filename=\"" + name +
               "\"\r\nContent-Type: application/octet-stream\r\n\r\n" + gcode + "\r\n--XyZ--\r\n";
  req.chunked(chunked);
  req.prepare_payload();
  std::ostringstream out;
  out << req;
  return out.str();
}

std::string some_gcode(size_t bytes) {
  std::string gcode;
  while (gcode.size() < bytes) gcode += "G1 X10.5 Y20.25 E0.0123 F1800\n";
  return gcode;
}

// An upload is spooled to an unnamed file as it arrives (web/spooled_body.hpp): a slow upload is
// not cut by the read deadline (each 64 KiB gets its own), a stalled one holds no heap for the
// length it announced, and a chunked one is taken as well.
TEST(WebServer, AnUploadIsSpooledToDiskWithADeadlinePerChunk) {
  Server s(/*read_timeout_s=*/2);  // 1.7 s of slack for a stalled test process
  const uint16_t port = s.server->port();
  auto reply_to = [](tcp::socket& sock) {
    beast::flat_buffer b;
    http::response<http::string_body> res;
    boost::system::error_code ec;
    http::read(sock, b, res, ec);
    return res;
  };
  // 3 MiB sent over 3.6 s in 256 KiB pieces, against a 2 s read deadline.
  {
    const std::string gcode = some_gcode(3u << 20);
    const std::string wire = upload_request("slow.gcode", gcode, false);
    asio::io_context ctx;
    tcp::socket sock(ctx);
    sock.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    const auto start = std::chrono::steady_clock::now();
    boost::system::error_code wec;
    for (size_t at = 0; at < wire.size() && !wec; at += 256 * 1024) {
      asio::write(sock,
                  asio::buffer(wire.data() + at, std::min<size_t>(256 * 1024, wire.size() - at)),
                  wec);
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
    const auto res = reply_to(sock);
    EXPECT_EQ(res.result_int(), 201) << res.body();
    EXPECT_GT(std::chrono::steady_clock::now() - start, std::chrono::seconds(3));
    std::error_code fec;
    EXPECT_EQ(std::filesystem::file_size(s.dir / "files" / "gcodes" / "slow.gcode", fec),
              gcode.size());
  }
  // A client that asks to be told to go on (libcurl for bodies over 1 MiB, so a slicer's upload)
  // is told so before it sends the body (it waited a second for it).
  {
    const std::string wire = upload_request("expect.gcode", some_gcode(100000), false);
    const size_t body_at = wire.find("\r\n\r\n") + 4;
    asio::io_context ctx;
    tcp::socket sock(ctx);
    sock.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    asio::write(sock, asio::buffer(wire.substr(0, body_at - 2) + "Expect: 100-continue\r\n\r\n"));
    std::string interim(64, '\0');
    pollfd readable{sock.native_handle(), POLLIN, 0};
    interim.resize(::poll(&readable, 1, 3000) == 1 ? sock.read_some(asio::buffer(interim)) : 0);
    EXPECT_EQ(interim.rfind("HTTP/1.1 100 Continue\r\n", 0), 0u) << interim;
    asio::write(sock, asio::buffer(wire.substr(body_at)));
    EXPECT_EQ(reply_to(sock).result_int(), 201);
  }
  // Chunked transfer encoding.
  {
    const std::string gcode = some_gcode(200000);
    asio::io_context ctx;
    tcp::socket sock(ctx);
    sock.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    asio::write(sock, asio::buffer(upload_request("chunked.gcode", gcode, true)));
    const auto res = reply_to(sock);
    EXPECT_EQ(res.result_int(), 201) << res.body();
    std::error_code fec;
    EXPECT_EQ(std::filesystem::file_size(s.dir / "files" / "gcodes" / "chunked.gcode", fec),
              gcode.size());
  }
  // 200 MiB announced, 16 MiB sent, then nothing: the heap grows by a chunk, not by the length
  // (Beast's string body reserved all 200 MiB at the first body byte). glibc's count of what
  // malloc handed out; a sanitizer's allocator does not keep it.
  {
    const auto heap_bytes = [] {
      const struct mallinfo2 m = ::mallinfo2();
      return static_cast<double>(m.uordblks + m.hblkhd);
    };
    const double before = heap_bytes();
    asio::io_context ctx;
    tcp::socket sock(ctx);
    sock.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    asio::write(sock, asio::buffer(std::string("POST /server/files/upload HTTP/1.1\r\nHost: x\r\n"
                                               "Content-Type: multipart/form-data; boundary=XyZ\r\n"
                                               "Content-Length: 209715200\r\n\r\n")));
    const std::string piece(1 << 20, 'G');
    for (int i = 0; i < 16; ++i) asio::write(sock, asio::buffer(piece));
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the server reads it all
    const double grown_mib = (heap_bytes() - before) / (1 << 20);
    std::printf("heap grown by a stalled 200 MiB upload after 16 MiB: %.2f MiB\n", grown_mib);
#if !defined(__SANITIZE_ADDRESS__)
    EXPECT_LT(grown_mib, 8.0);
#endif
    // Stalled: the read deadline (2 s here) closes it.
    const auto res = reply_to(sock);
    EXPECT_NE(res.result_int(), 201);
  }
  // Nothing of the spooled bodies is left among the files, and the server goes on.
  size_t entries = 0;
  for (const auto& e : std::filesystem::directory_iterator(s.dir / "files" / "gcodes")) {
    ++entries;
    EXPECT_NE(e.path().filename().string().rfind(".upload", 0), 0u) << e.path();
  }
  EXPECT_EQ(entries, 3u);
  EXPECT_EQ(get(port, "/server/info").result_int(), 200);
}

// This machine's first IPv4 address that is not loopback ("" when it has none).
std::string non_loopback_ipv4() {
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return {};
  std::string found;
  for (ifaddrs* a = list; a != nullptr && found.empty(); a = a->ifa_next) {
    if (a->ifa_addr == nullptr || a->ifa_addr->sa_family != AF_INET) continue;
    const auto* in = reinterpret_cast<const sockaddr_in*>(a->ifa_addr);
    const auto addr = asio::ip::address_v4(ntohl(in->sin_addr.s_addr));
    if (!addr.is_loopback()) found = addr.to_string();
  }
  ::freeifaddrs(list);
  return found;
}

// A client outside the trusted ranges without the API key (web/access.hpp) is refused: an upload
// before any of its body is stored, and OctoPrint's routes too; with the key it is taken.
TEST(WebServer, AnUntrustedClientIsRefusedBeforeItsUploadIsStored) {
  const std::string address = non_loopback_ipv4();
  if (address.empty()) GTEST_SKIP() << "no non-loopback IPv4 address to connect from";
  Server s(30, "0.0.0.0");
  const uint16_t port = s.server->port();
  auto post_upload = [&](const std::string& target, const std::string& key) {
    asio::io_context ctx;
    beast::tcp_stream st(ctx);
    st.connect(tcp::endpoint(asio::ip::make_address(address), port));
    http::request<http::string_body> req{http::verb::post, target, 11};
    req.set(http::field::host, address);
    if (!key.empty()) req.set("X-Api-Key", key);
    req.set(http::field::content_type, "multipart/form-data; boundary=XyZ");
    req.body() =
        "--XyZ\r\nContent-Disposition: form-data; name=\"file\"; filename=\"u.gcode\"\r\n\r\n" +
        some_gcode(2u << 20) + "\r\n--XyZ--\r\n";
    req.prepare_payload();
    boost::system::error_code ec;
    http::write(st, req, ec);  // the server may close before the whole body went
    beast::flat_buffer b;
    http::response<http::string_body> res;
    http::read(st, b, res, ec);
    return static_cast<int>(res.result_int());
  };
  EXPECT_EQ(post_upload("/server/files/upload", ""), 401);
  // Refused at its header: the answer comes before any of the body is sent.
  {
    asio::io_context ctx;
    tcp::socket sock(ctx);
    sock.connect(tcp::endpoint(asio::ip::make_address(address), port));
    asio::write(sock, asio::buffer(std::string("POST /api/files/local HTTP/1.1\r\nHost: x\r\n"
                                               "Content-Type: multipart/form-data; boundary=XyZ\r\n"
                                               "Content-Length: 2000000\r\n\r\n")));
    std::string reply(64, '\0');
    pollfd readable{sock.native_handle(), POLLIN, 0};
    reply.resize(::poll(&readable, 1, 3000) == 1 ? sock.read_some(asio::buffer(reply)) : 0);
    EXPECT_EQ(reply.rfind("HTTP/1.1 401", 0), 0u) << reply;
  }
  EXPECT_EQ(post_upload("/api/files/local", "wrong"), 401);
  EXPECT_FALSE(std::filesystem::exists(s.dir / "files" / "gcodes" / "u.gcode"));
  EXPECT_EQ(post_upload("/api/files/local", "key"), 201);
  EXPECT_TRUE(std::filesystem::exists(s.dir / "files" / "gcodes" / "u.gcode"));
  EXPECT_EQ(s.on_io([&] { return s.server->stats().unauthorized; }), 3u);
}

TEST(WebServer, HostileClientsAreRefusedAndTheServerGoesOn) {
  Server s;
  const uint16_t port = s.server->port();
  // Malformed HTTP.
  {
    asio::io_context ctx;
    tcp::socket sock(ctx);
    sock.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    asio::write(sock, asio::buffer(std::string("GARBAGE \x01\x02 HTTP/9\r\n\r\n")));
    std::string reply(64, '\0');
    boost::system::error_code ec;
    const size_t n = sock.read_some(asio::buffer(reply), ec);
    EXPECT_EQ(reply.substr(0, std::min<size_t>(n, 12)), "HTTP/1.1 400");
  }
  // A body over the limit.
  {
    asio::io_context ctx;
    beast::tcp_stream st(ctx);
    st.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    http::request<http::string_body> req{http::verb::post, "/server/database/item", 11};
    req.set(http::field::content_type, "application/json");
    req.body() = std::string(3 << 20, 'x');
    req.prepare_payload();
    boost::system::error_code ec;
    http::write(st, req, ec);
    beast::flat_buffer b;
    http::response<http::string_body> res;
    http::read(st, b, res, ec);
    EXPECT_EQ(res.result_int(), 413);
  }
  // An upload beyond the 1 MiB a request body may have (a sliced part is megabytes), with a
  // Content-Length as a browser sends it: the parser checks that length while it reads the header,
  // so the upload's own limit must already hold then (it answered 413 before).
  {
    asio::io_context ctx;
    beast::tcp_stream st(ctx);
    st.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    std::string gcode;
    while (gcode.size() < (3u << 20)) gcode += "G1 X10.5 Y20.25 E0.0123 F1800\n";
    http::request<http::string_body> req{http::verb::post, "/server/files/upload", 11};
    req.set(http::field::content_type, "multipart/form-data; boundary=XyZ");
    req.body() =
        "--XyZ\r\nContent-Disposition: form-data; name=\"file\"; filename=\"big.gcode\"\r\n"
        "Content-Type: application/octet-stream\r\n\r\n" +
        gcode + "\r\n--XyZ--\r\n";
    req.prepare_payload();
    ASSERT_EQ(req[http::field::content_length], std::to_string(req.body().size()));
    boost::system::error_code ec;
    http::write(st, req, ec);
    beast::flat_buffer b;
    http::response<http::string_body> res;
    http::read(st, b, res, ec);
    EXPECT_EQ(res.result_int(), 201) << res.body();
    std::error_code fec;
    EXPECT_EQ(std::filesystem::file_size(s.dir / "files" / "gcodes" / "big.gcode", fec),
              gcode.size());
  }
  // Beyond the upload's limit (256 MiB by default), announced by its Content-Length: refused at
  // the header, before any of the body is read.
  {
    asio::io_context ctx;
    tcp::socket sock(ctx);
    sock.connect(tcp::endpoint(asio::ip::make_address("127.0.0.1"), port));
    asio::write(sock, asio::buffer(std::string("POST /server/files/upload HTTP/1.1\r\nHost: x\r\n"
                                               "Content-Type: multipart/form-data; boundary=XyZ\r\n"
                                               "Content-Length: 300000000\r\n\r\n")));
    std::string reply(64, '\0');
    boost::system::error_code ec;
    const size_t n = sock.read_some(asio::buffer(reply), ec);
    EXPECT_EQ(reply.substr(0, std::min<size_t>(n, 12)), "HTTP/1.1 413");
  }
  // A WebSocket message over 1 MiB closes that socket only. Reads until the close: a notification
  // the server broadcast before it read the message may come first (a loaded machine's order).
  {
    WsClient big(port);
    boost::system::error_code ec;
    big.ws.write(asio::buffer(std::string(2 << 20, ' ')), ec);
    int messages_before_close = 0;
    for (; !ec && messages_before_close < 1000; ++messages_before_close) {
      beast::flat_buffer b;
      big.ws.read(b, ec);
      if (!ec) {
        const json j = json::parse(beast::buffers_to_string(b.data()), nullptr, false);
        EXPECT_FALSE(j.is_object() && j.contains("id")) << "a reply to the oversized message";
      }
    }
    EXPECT_TRUE(ec);
  }
  // More connections than allowed: the extra ones are closed at once.
  std::vector<std::unique_ptr<WsClient>> many;
  for (int i = 0; i < 40; ++i) {
    try {
      many.push_back(std::make_unique<WsClient>(port));
    } catch (const std::exception&) {
    }
  }
  EXPECT_LE(many.size(), 32u);
  many.clear();
  // Closed on this side; the server sees them go on its own thread (a new client before that is
  // refused over the limit).
  const auto gone_by = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (s.on_io([&] { return s.server->stats().open_sessions; }) > 0 &&
         std::chrono::steady_clock::now() < gone_by)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(s.on_io([&] { return s.server->stats().open_sessions; }), 0u);
  // A reader that never reads: it subscribes, floods requests and does not read the replies.
  {
    WsClient slow(port);
    const std::string req = json{
        {"jsonrpc", "2.0"},
        {"method", "printer.objects.query"},
        {"params", {{"objects", {{"configfile", nullptr}, {"feedloop_servo", nullptr}}}}},
        {"id", 1}}.dump();
    boost::system::error_code ec;
    for (int i = 0;
         i < 20000 && !ec && s.on_io([&] { return s.server->stats().slow_readers_dropped; }) == 0;
         ++i)
      slow.ws.write(asio::buffer(req), ec);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const ServerStats st = s.on_io([&] { return s.server->stats(); });
  EXPECT_GE(st.refused_over_limit, 8u);
  EXPECT_GE(st.slow_readers_dropped, 1u);
  EXPECT_GE(st.bad_requests, 2u);
  // And it still answers.
  WsClient after(port);
  EXPECT_EQ(after.call("server.info", json::object(), 3)["result"]["klippy_connected"], true);
  EXPECT_EQ(get(port, "/").result_int(), 200);
  std::printf(
      "web load: accepted %llu, refused %llu, slow readers dropped %llu, bad requests %llu, "
      "I/O loop max delay %.2f ms\n",
      static_cast<unsigned long long>(st.accepted),
      static_cast<unsigned long long>(st.refused_over_limit),
      static_cast<unsigned long long>(st.slow_readers_dropped),
      static_cast<unsigned long long>(st.bad_requests), s.max_late_ms.load());
}

}  // namespace
}  // namespace feedloop::web
