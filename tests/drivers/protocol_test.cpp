// Wire protocol: framing, CRC, resynchronisation on garbage, the reliable link under loss, and
// the encoder of messages.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "drivers/protocol/frame.hpp"
#include "drivers/protocol/messages.hpp"
#include "drivers/protocol/reliable_link.hpp"

namespace feedloop::protocol {
namespace {

std::vector<uint8_t> make_frame(uint16_t seq, const std::vector<uint8_t>& payload) {
  std::vector<uint8_t> f(kMaxFrame);
  f.resize(encode_frame(f.data(), kFlagData, seq, 0, payload.data(), payload.size()));
  return f;
}

TEST(Crc16, KnownValue) {
  // CRC-16/CCITT-FALSE check value for "123456789".
  const uint8_t s[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(crc16_ccitt(s, 9), 0x29B1);
}

TEST(Frame, RoundTripAnyChunking) {
  std::mt19937_64 rng(1);
  std::vector<uint8_t> stream;
  std::vector<std::vector<uint8_t>> payloads;
  for (int i = 0; i < 200; ++i) {
    std::vector<uint8_t> p(rng() % (kMaxPayload + 1));
    for (auto& b : p) b = static_cast<uint8_t>(rng());
    if (!p.empty() && (i % 3 == 0)) p[0] = kSync;  // sync bytes inside payloads are fine
    payloads.push_back(p);
    const auto f = make_frame(static_cast<uint16_t>(i), p);
    stream.insert(stream.end(), f.begin(), f.end());
  }
  FrameDecoder dec;
  size_t pos = 0, got = 0;
  FrameView v;
  while (pos < stream.size()) {
    const size_t chunk = std::min<size_t>(1 + rng() % 97, stream.size() - pos);
    size_t fed = 0;
    while (fed < chunk) {
      fed += dec.feed(stream.data() + pos + fed, chunk - fed);
      while (dec.next(v)) {
        ASSERT_LT(got, payloads.size());
        EXPECT_EQ(v.seq, got);
        EXPECT_EQ(std::vector<uint8_t>(v.payload, v.payload + v.len), payloads[got]);
        ++got;
      }
    }
    pos += chunk;
  }
  EXPECT_EQ(got, payloads.size());
  EXPECT_EQ(dec.stats().crc_errors, 0u);
}

TEST(Frame, ResyncsAfterGarbageAndCorruption) {
  std::mt19937_64 rng(2);
  std::vector<uint8_t> stream;
  int good = 0;
  for (int i = 0; i < 250; ++i) {
    // Garbage (with sync bytes in it) between frames.
    const int g = static_cast<int>(rng() % 40);
    for (int k = 0; k < g; ++k) stream.push_back((rng() % 4 == 0) ? kSync : static_cast<uint8_t>(rng()));
    auto f = make_frame(static_cast<uint16_t>(i), std::vector<uint8_t>(1 + rng() % 60, static_cast<uint8_t>(i)));
    if (i % 5 == 0) {
      f[1 + rng() % (f.size() - 1)] ^= 0x10;  // corrupted frame: must be rejected
    } else {
      ++good;
    }
    stream.insert(stream.end(), f.begin(), f.end());
  }
  // Later traffic: a fake header in the garbage may wait for up to kMaxFrame more bytes before its
  // CRC fails and the decoder rescans from the byte after its sync.
  stream.insert(stream.end(), kMaxFrame, 0);
  FrameDecoder dec;
  FrameView v;
  int got = 0, wrong = 0;
  for (size_t pos = 0; pos < stream.size();) {
    pos += dec.feed(stream.data() + pos, stream.size() - pos);
    while (dec.next(v)) {
      // A good frame has payload bytes all equal to its seq.
      bool consistent = v.len > 0;
      for (size_t k = 0; k < v.len; ++k) consistent &= (v.payload[k] == static_cast<uint8_t>(v.seq));
      if (consistent && v.seq % 5 != 0) ++got; else ++wrong;
    }
  }
  EXPECT_EQ(got, good);
  EXPECT_EQ(wrong, 0);
  EXPECT_GT(dec.stats().crc_errors + dec.stats().bad_lengths, 0u);
}

// Two links connected by a lossy in-memory channel.
struct Wire final : FrameOutput {
  std::vector<std::vector<uint8_t>> frames;
  void write_frame(const uint8_t* f, size_t n) override { frames.emplace_back(f, f + n); }
};
struct Sink final : PayloadHandler {
  std::vector<std::vector<uint8_t>> got;
  void on_payload(const uint8_t* p, size_t n) override { got.emplace_back(p, p + n); }
};

TEST(ReliableLink, ExactlyOnceInOrderUnderLossDuplicationAndReordering) {
  Wire wa, wb;
  Sink sa, sb;
  ReliableLink a, b;
  LinkParams lp;
  lp.rto_ns = 5'000'000;
  a.configure(lp, &wa, &sa);
  b.configure(lp, &wb, &sb);
  a.reset();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  const int kMessages = 3000;
  int next = 0;
  int64_t now = 0;
  std::vector<std::vector<uint8_t>> held;  // reordered frames
  auto deliver = [&](Wire& from, ReliableLink& to) {
    auto frames = std::move(from.frames);
    from.frames.clear();
    for (auto& f : frames) {
      const double r = u(rng);
      if (r < 0.1) continue;                                  // drop
      if (r < 0.15) f[rng() % f.size()] ^= 0x40;              // corrupt
      if (r > 0.95) { held.push_back(f); continue; }          // reorder: later
      to.on_bytes(f.data(), f.size(), now);
      if (r > 0.9) to.on_bytes(f.data(), f.size(), now);      // duplicate
    }
  };
  for (int step = 0; step < 200000 && sb.got.size() < static_cast<size_t>(kMessages); ++step) {
    now += 1'000'000;  // 1 ms
    while (next < kMessages && a.can_send()) {
      const uint8_t m[4] = {static_cast<uint8_t>(next), static_cast<uint8_t>(next >> 8), 0xAA, 0x55};
      ASSERT_TRUE(a.send(m, sizeof m, now));
      ++next;
    }
    deliver(wa, b);
    deliver(wb, a);
    if (!held.empty() && u(rng) < 0.3) {
      auto f = held.front();
      held.erase(held.begin());
      b.on_bytes(f.data(), f.size(), now);
    }
    a.poll(now);
    b.poll(now);
  }
  ASSERT_EQ(sb.got.size(), static_cast<size_t>(kMessages));
  for (int i = 0; i < kMessages; ++i) EXPECT_EQ(sb.got[i][0] | (sb.got[i][1] << 8), i & 0xFFFF) << i;
  EXPECT_GT(a.stats().retransmitted, 0u);
  EXPECT_GT(b.stats().duplicates_dropped + b.stats().out_of_order_dropped, 0u);
}

// A host that starts a new session (reset) while the device has link state: the RESET frame
// arrives twice (a retransmission) and is delivered once; both sides renumber; then the device
// reboots (a fresh link numbering from 0, no reset of its own) and the host's next session
// reaches it too.
TEST(ReliableLink, SessionRestartsAgainstALiveAndARebootedPeer) {
  Wire wh, wd;
  Sink sh, sd;
  ReliableLink host, dev;
  host.configure({}, &wh, &sh);
  dev.configure({}, &wd, &sd);
  int64_t now = 0;
  auto pass = [&](Wire& from, ReliableLink& to, bool twice) {
    auto frames = std::move(from.frames);
    from.frames.clear();
    for (auto& f : frames) {
      to.on_bytes(f.data(), f.size(), now);
      if (twice) to.on_bytes(f.data(), f.size(), now);
    }
  };
  auto exchange = [&](bool twice) {
    for (int i = 0; i < 4; ++i) {
      now += 1'000'000;
      pass(wh, dev, twice);
      pass(wd, host, twice);
    }
  };
  const uint8_t m1[2] = {1, 1}, m2[2] = {2, 2}, m3[2] = {3, 3};
  // Session 1: some traffic both ways.
  host.reset();
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(host.send(m1, 2, now));
  exchange(false);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(dev.send(m1, 2, now));
  exchange(false);
  ASSERT_EQ(sd.got.size(), 5u);
  ASSERT_EQ(sh.got.size(), 3u);
  // Session 2 against the same device: every frame duplicated on the way.
  host.reset();
  ASSERT_TRUE(host.send(m2, 2, now));
  ASSERT_TRUE(host.send(m2, 2, now));
  exchange(true);
  ASSERT_TRUE(dev.send(m2, 2, now));
  exchange(true);
  EXPECT_EQ(sd.got.size(), 7u);  // the two session-2 messages, once each
  EXPECT_EQ(sh.got.size(), 4u);
  EXPECT_EQ(host.in_flight(), 0);
  EXPECT_EQ(dev.in_flight(), 0);
  // The device reboots: a fresh link. Session 3 reaches it and hears its answer.
  ReliableLink rebooted;
  rebooted.configure({}, &wd, &sd);
  host.reset();
  ASSERT_TRUE(host.send(m3, 2, now));
  now += 1'000'000;
  pass(wh, rebooted, false);
  ASSERT_TRUE(rebooted.send(m3, 2, now));
  for (int i = 0; i < 4; ++i) {
    now += 1'000'000;
    pass(wh, rebooted, false);
    pass(wd, host, false);
  }
  EXPECT_EQ(sd.got.size(), 8u);
  EXPECT_EQ(sd.got.back()[0], 3);
  ASSERT_EQ(sh.got.size(), 5u);
  EXPECT_EQ(sh.got.back()[0], 3);
  EXPECT_EQ(host.in_flight(), 0);
  EXPECT_EQ(rebooted.in_flight(), 0);
}

TEST(Messages, WriterRefusesOverflow) {
  uint8_t buf[4];
  MsgWriter w(buf, sizeof buf);
  w.u8(1).var(1u << 30);
  EXPECT_FALSE(w.ok());
  MsgReader r(buf, 1);
  r.u8();
  r.var();
  EXPECT_FALSE(r.ok());
}

}  // namespace
}  // namespace feedloop::protocol
