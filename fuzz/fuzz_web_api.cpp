// libFuzzer target for the web API (web/moonraker_api.hpp, web/multipart.hpp): what a browser or
// any client on the network sends. Byte 0 picks the entry: even, the rest is WebSocket messages
// separated by NUL bytes (JSON-RPC requests, batches, anything); odd, the rest is an HTTP request
// cut into method, path?query, content type and body at the first three newlines (uploads
// exercise the multipart parser and the file store on a scratch folder). A fake printer stands in
// for the machine; the database is in memory.
// Besides crashes, sanitizer reports and escaping exceptions, these trap: a WebSocket reply that
// does not parse as JSON or is not a JSON-RPC 2.0 response or batch; more than one reply to a
// message; an HTTP reply that is not exactly one status in 200..599 with a JSON body (or a file).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "fuzz/fuzz_input.hpp"
#include "tests/web/fake_printer.hpp"
#include "web/moonraker_api.hpp"

namespace {

using namespace feedloop;
using fuzz::check;
using nlohmann::json;

struct World {
  World() {
    dir = std::filesystem::temp_directory_path() / ("fuzz_web_api_" + std::to_string(::getpid()));
    files = std::make_unique<web::FileStore>(web::FileStore::open(dir.string()).value());
    db = web::Database::open(":memory:").value();
  }
  ~World() {  // the scratch folder goes with the process (at a normal exit)
    files.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  std::filesystem::path dir;
  std::unique_ptr<web::FileStore> files;
  std::unique_ptr<web::Database> db;
};

void check_rpc(const json& r) {
  check(r.is_object() && r.value("jsonrpc", "") == "2.0");
  if (r.contains("method")) return;  // a notification
  check(r.contains("id"));
  check(r.contains("result") != r.contains("error"));
  if (r.contains("error"))
    check(r["error"]["code"].is_number_integer() && r["error"]["message"].is_string());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static World world;
  if (size == 0) return 0;
  web::testing::FakePrinter printer;
  web::MoonrakerApi api(printer, *world.files, *world.db, web::MoonrakerApi::Options{});
  int replies = 0;
  const uint64_t conn = api.open_connection([&](std::shared_ptr<const std::string> t) {
    const json r = json::parse(*t, nullptr, false);
    check(!r.is_discarded());
    if (r.is_array()) {
      for (const json& e : r) check_rpc(e);
      ++replies;
    } else {
      check_rpc(r);
      if (!r.contains("method")) ++replies;
    }
    return true;
  });
  const std::string_view in(reinterpret_cast<const char*>(data) + 1, size - 1);
  if ((data[0] & 1) == 0) {
    size_t b = 0;
    while (b <= in.size()) {
      size_t e = in.find('\0', b);
      if (e == std::string_view::npos) e = in.size();
      replies = 0;
      api.on_message(conn, in.substr(b, e - b));
      check(replies <= 1);
      api.tick(static_cast<double>(b) * 0.1);
      b = e + 1;
    }
  } else {
    web::HttpRequest req;
    std::string_view rest = in;
    auto cut = [&rest]() {
      const size_t nl = rest.find('\n');
      std::string part(rest.substr(0, nl));
      rest = nl == std::string_view::npos ? std::string_view() : rest.substr(nl + 1);
      return part;
    };
    req.method = cut();
    std::string target = cut();
    const size_t q = target.find('?');
    req.path = target.substr(0, q);
    if (q != std::string::npos) req.query[target.substr(q + 1)] = "";
    req.content_type = cut();
    req.body = std::string(rest);
    int http_replies = 0;
    if (web::MoonrakerApi::is_api_path(req.path)) {
      api.on_http(req, [&](web::HttpReply r) {
        ++http_replies;
        check(r.status >= 200 && r.status < 600);
        if (r.file_path.empty()) check(!json::parse(r.body, nullptr, false).is_discarded());
      });
      check(http_replies == 1);
    }
  }
  return 0;
}
