// Client I/O never delays the machine (issue 14): a flooding client is throttled, then dropped
// with a log line naming it, while the other clients are still served; `status` comes from a
// snapshot taken at a bounded rate, the same text for every client, never going back in time.
#include <gtest/gtest.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include <sys/socket.h>  // send, MSG_NOSIGNAL

#include <algorithm>
#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "tests/daemon/daemon_fixture.hpp"
#include "tests/daemon/json_call.hpp"
#include "tests/daemon/line_client.hpp"

namespace feedloop::testing {
namespace {

using nlohmann::json;
using SteadyClock = std::chrono::steady_clock;

// Every log line the daemon writes, kept for the test to read.
class CaptureSink final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  std::string text() {
    std::lock_guard lock(mutex_);
    return text_;
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    text_.append(msg.payload.data(), msg.payload.size());
    text_ += '\n';
  }
  void flush_() override {}

 private:
  std::string text_;
};

constexpr double kApiRate = 200.0;   // the daemon's default for the JSON API
constexpr double kDropAfterS = 1.0;  // shorter than the daemon's 5 s, for the test's sake

class Clients : public DaemonFixture {
 protected:
  void SetUp() override {
    sink_ = std::make_shared<CaptureSink>();
    spdlog::default_logger()->sinks().push_back(sink_);
    DaemonFixture::SetUp();
  }
  void TearDown() override {
    DaemonFixture::TearDown();
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
  }
  void customize_options(daemon::DaemonOptions& o) override {
    o.api_limits.drop_after_s = kDropAfterS;
    o.marlin_limits.drop_after_s = kDropAfterS;
    EXPECT_EQ(o.api_limits.lines_per_s, kApiRate);
  }
  std::shared_ptr<CaptureSink> sink_;
};

const json kStatus = {{"jsonrpc", "2.0"}, {"id", 1}, {"method", "status"}};

// A client that polls status every 10 ms and waits for each reply.
struct Poller {
  uint64_t replies = 0, failures = 0;
  double max_rtt_ms = 0;
};

void poll(const std::string& path, const std::atomic<bool>& stop, Poller& p) {
  LineClient c;
  if (!c.connect_unix(path)) {
    ++p.failures;
    return;
  }
  while (!stop.load()) {
    const auto t0 = SteadyClock::now();
    const json r = call(c, kStatus);
    if (!r.contains("result")) {
      ++p.failures;
      return;
    }
    ++p.replies;
    p.max_rtt_ms = std::max(
        p.max_rtt_ms, std::chrono::duration<double, std::milli>(SteadyClock::now() - t0).count());
    std::this_thread::sleep_until(t0 + std::chrono::milliseconds(10));
  }
}

TEST_F(Clients, AFloodingApiClientIsThrottledThenDroppedAndTheOthersAreServed) {
  // The flooder connects first: it is api#1 in the log.
  LineClient flooder;
  ASSERT_TRUE(flooder.connect_unix(daemon_->api_socket_path()));
  std::atomic<bool> stop{false};
  std::vector<Poller> pollers(5);
  std::vector<std::thread> threads;
  for (Poller& p : pollers)
    threads.emplace_back(poll, daemon_->api_socket_path(), std::cref(stop), std::ref(p));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));

  // Requests written as fast as the socket takes them, replies read on the side.
  const auto t0 = SteadyClock::now();
  std::atomic<bool> closed{false};
  std::atomic<uint64_t> flood_replies{0}, flood_sent{0};
  std::thread reader([&] {
    while (auto line = flooder.read_line(8000)) {
      if (line->find("\"result\"") != std::string::npos) ++flood_replies;
    }
    closed = true;
  });
  const std::string req = kStatus.dump() + "\n";
  std::string batch;
  for (int i = 0; i < 50; ++i) batch += req;
  while (!closed.load() && SteadyClock::now() - t0 < std::chrono::seconds(8)) {
    const ssize_t n = ::send(flooder.fd(), batch.data(), batch.size(), MSG_NOSIGNAL);
    if (n <= 0) break;
    flood_sent += static_cast<uint64_t>(n) / req.size();
  }
  reader.join();
  const double flood_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  stop = true;
  for (auto& t : threads) t.join();

  // Dropped after being throttled for kDropAfterS without a pause (plus a tick and the noise of
  // a shared machine), having been answered at the allowed rate only.
  EXPECT_TRUE(closed.load());
  EXPECT_LT(flood_s, kDropAfterS + 3.0);
  EXPECT_GT(flood_sent.load(), 2 * flood_replies.load()) << "the flood outpaced the limit";
  EXPECT_LE(static_cast<double>(flood_replies.load()), kApiRate + kApiRate * flood_s + 20)
      << "answered faster than " << kApiRate << " requests/s in " << flood_s << " s";
  EXPECT_GE(static_cast<double>(flood_replies.load()), kApiRate)  // the burst at least
      << flood_s << " s";
  const std::string log = sink_->text();
  EXPECT_NE(log.find("api#1 throttled: more than 200 requests/s"), std::string::npos) << log;
  EXPECT_NE(log.find("api#1 dropped: flooding"), std::string::npos) << log;
  for (int i = 2; i <= 6; ++i) {  // the pollers (100 requests/s each) were never throttled
    const std::string name = "api#" + std::to_string(i) + " ";
    EXPECT_EQ(log.find(name + "throttled"), std::string::npos) << log;
    EXPECT_EQ(log.find(name + "dropped"), std::string::npos) << log;
  }
  // Every poller was answered all along: no failure, and most of its 10 ms slots.
  const double slots = (flood_s + 0.2) / 0.010;
  for (const Poller& p : pollers) {
    EXPECT_EQ(p.failures, 0u);
    EXPECT_GT(static_cast<double>(p.replies), 0.3 * slots)
        << "max round trip " << p.max_rtt_ms << " ms";
  }
  // And the daemon still answers a newcomer.
  LineClient late;
  ASSERT_TRUE(late.connect_unix(daemon_->api_socket_path()));
  EXPECT_TRUE(call(late, kStatus).contains("result"));
}

TEST_F(Clients, AFloodingMarlinClientIsThrottledThenDroppedWhileAnotherPrints) {
  LineClient flooder;  // socket#1: M105 without waiting for its ok
  ASSERT_TRUE(flooder.connect_unix(daemon_->socket_path()));
  LineClient printer;  // socket#2: moves, one ok at a time
  ASSERT_TRUE(printer.connect_unix(daemon_->socket_path()));
  const auto t0 = SteadyClock::now();
  std::atomic<bool> closed{false};
  std::atomic<uint64_t> oks{0};
  std::thread reader([&] {
    while (auto line = flooder.read_line(8000))
      if (line->rfind("ok", 0) == 0) ++oks;
    closed = true;
  });
  std::thread writer([&] {
    std::string batch;
    for (int i = 0; i < 200; ++i) batch += "M105\n";
    while (!closed.load() && SteadyClock::now() - t0 < std::chrono::seconds(8))
      if (::send(flooder.fd(), batch.data(), batch.size(), MSG_NOSIGNAL) <= 0) break;
  });
  // Machine commands are paced by the machine's queue, not by the rate limit: the printer's 200
  // moves are all accepted while the flood goes on.
  int accepted = 0;
  for (int i = 0; i < 200; ++i) {
    ASSERT_TRUE(printer.send_line("G1 X" + std::to_string(10 + (i % 2) * 0.2) + " F6000"));
    if (printer.read_until("ok", 10000)) ++accepted;
  }
  writer.join();
  reader.join();
  const double flood_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  EXPECT_EQ(accepted, 200);
  EXPECT_TRUE(closed.load());
  EXPECT_LE(static_cast<double>(oks.load()), 1000.0 + 1000.0 * flood_s + 50);
  const std::string log = sink_->text();
  EXPECT_NE(log.find("socket#1 throttled: more than 1000 requests/s"), std::string::npos) << log;
  EXPECT_NE(log.find("socket#1 dropped: flooding"), std::string::npos) << log;
  EXPECT_EQ(log.find("socket#2 throttled"), std::string::npos) << log;
  ASSERT_TRUE(printer.send_line("M114"));
  EXPECT_TRUE(printer.read_line());
}

TEST_F(Clients, StatusRepliesAreConsistentSnapshotsTakenAtABoundedRate) {
  // Motion, so that the figures change from one snapshot to the next.
  LineClient printer;
  ASSERT_TRUE(printer.connect_unix(daemon_->socket_path()));
  for (int i = 0; i < 30; ++i) {
    ASSERT_TRUE(printer.send_line("G1 X" + std::to_string(10 + (i % 2) * 20) + " Y" +
                                  std::to_string(10 + i) + " F6000"));
    ASSERT_TRUE(printer.read_until("ok", 10000));
  }
  // Four clients ask as fast as their replies come back.
  struct Seen {
    uint64_t seq;
    std::string result;  // the reply's result, as sent
    uint64_t cycles, executed;
  };
  std::vector<std::vector<Seen>> seen(4);
  std::vector<std::thread> threads;
  const auto t0 = SteadyClock::now();
  for (auto& s : seen) {
    threads.emplace_back([&, out = &s] {
      LineClient c;
      if (!c.connect_unix(daemon_->api_socket_path())) return;
      while (SteadyClock::now() - t0 < std::chrono::milliseconds(1000)) {
        std::string raw;
        const json r = call(c, kStatus, &raw);
        if (!r.contains("result")) return;
        const json& st = r["result"];
        // The result's text as it went out: between "result": and the closing brace.
        const size_t at = raw.find("\"result\":");
        out->push_back(Seen{
            st["snapshot"]["seq"].get<uint64_t>(), raw.substr(at + 9, raw.size() - at - 10),
            st["servo"]["cycles"].get<uint64_t>(), st["commands"]["executed"].get<uint64_t>()});
      }
    });
  }
  for (auto& t : threads) t.join();
  const double elapsed_s = std::chrono::duration<double>(SteadyClock::now() - t0).count();

  std::map<uint64_t, const Seen*> by_seq;
  size_t replies = 0;
  for (const auto& s : seen) {
    ASSERT_GT(s.size(), 10u);
    replies += s.size();
    for (size_t i = 0; i < s.size(); ++i) {
      if (i > 0) {
        EXPECT_GE(s[i].seq, s[i - 1].seq) << "a client saw an older snapshot after a newer one";
      }
      auto [it, fresh] = by_seq.emplace(s[i].seq, &s[i]);
      // One snapshot, one text: every client got the same bytes.
      if (!fresh) {
        EXPECT_EQ(it->second->result, s[i].result) << "snapshot " << s[i].seq;
      }
    }
  }
  // Snapshots in order are in time order.
  const Seen* prev = nullptr;
  for (const auto& [seq, s] : by_seq) {
    if (prev) {
      EXPECT_GE(s->cycles, prev->cycles) << "snapshot " << seq;
      EXPECT_GE(s->executed, prev->executed) << "snapshot " << seq;
    }
    prev = s;
  }
  // Taken at most every 10 ms however often the clients ask (plus the first, plus one after each
  // command that completed meanwhile), and shared.
  const double completed =
      static_cast<double>(by_seq.rbegin()->second->executed - by_seq.begin()->second->executed);
  const double max_snapshots = elapsed_s / 0.010 + 2 + completed;
  EXPECT_LE(static_cast<double>(by_seq.size()), max_snapshots)
      << replies << " replies in " << elapsed_s << " s";
  EXPECT_GT(replies, by_seq.size()) << "no reply shared a snapshot";
  const json first = json::parse(by_seq.begin()->second->result);
  EXPECT_EQ(first["snapshot"]["period_ms"], 10);

  // A status asked after an answer shows what was answered, though the snapshot is younger than
  // its period: a Marlin command's `ok`, a JSON gcode request's result.
  LineClient api;
  ASSERT_TRUE(api.connect_unix(daemon_->api_socket_path()));
  for (int i = 0; i < 5; ++i) {
    const uint64_t before = call(api, kStatus)["result"]["commands"]["executed"].get<uint64_t>();
    ASSERT_TRUE(printer.send_line("G1 X" + std::to_string(12 + i) + " F6000"));
    ASSERT_TRUE(printer.read_until("ok", 10000));
    EXPECT_EQ(call(api, kStatus)["result"]["commands"]["executed"].get<uint64_t>(), before + 1);
  }
  for (int i = 0; i < 3; ++i) {
    const std::string text = "hello " + std::to_string(i);
    const json done = call(api, {{"jsonrpc", "2.0"},
                                 {"id", 2},
                                 {"method", "gcode"},
                                 {"params", {{"script", "M117 " + text}}}});
    ASSERT_TRUE(done.contains("result")) << done.dump();
    const json after = call(api, kStatus);
    EXPECT_EQ(after["result"]["message"], text) << after.dump();
  }
}

}  // namespace
}  // namespace feedloop::testing
