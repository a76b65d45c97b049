// USB transport. With real libusb (no MCU attached here): opening a VID:PID that is not present
// gives a clear error that names the device and says what to check; reads and writes on a closed
// transport are errors, not crashes. With a fake UsbBackend (a simulated bus whose device is a
// VirtualMcu, in virtual time): no device / other serial / permission denied / interface busy
// errors, an unplug mid-stream (LIBUSB_ERROR_NO_DEVICE) reported as a disconnect naming the
// device, a replug of the same device (steps exactly once), and a replug of a rebooted device
// (the session reports it and re-identifies it).
#include <gtest/gtest.h>
#include <libusb.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "core/clock.hpp"
#include "drivers/device/virtual_mcu.hpp"
#include "drivers/host/mcu_session.hpp"
#include "drivers/stepgen/run_codec.hpp"
#include "drivers/transport/usb_transport.hpp"
#include "tests/common/malloc_counter.hpp"
#include <sys/resource.h>  // getrusage, RUSAGE_THREAD

namespace feedloop::drivers {
namespace {

TEST(Usb, NoDeviceIsAClearError) {
  UsbParams p;
  p.vendor_id = 0xfeed;
  p.product_id = 0x0b0b;
  p.serial = "none";
  UsbTransport t(p);
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  const std::string m = st.error().message;
  std::printf("error: %s\n", m.c_str());
  // Either libusb works and finds no such device, or libusb itself is unavailable here.
  const bool no_device = m.find("no USB device usb feed:0b0b serial none") != std::string::npos &&
                         m.find("plugged in") != std::string::npos;
  const bool no_libusb = m.find("cannot initialise libusb") != std::string::npos;
  EXPECT_TRUE(no_device || no_libusb) << m;
  EXPECT_FALSE(t.connected());
  uint8_t b[4] = {1, 2, 3, 4};
  EXPECT_FALSE(t.write(b, 4).ok());
  EXPECT_FALSE(t.read(b, 4).ok());
}

TEST(Usb, ErrorCountsTheDevicesThatAreThere) {
  auto r = UsbTransport::list_devices();
  if (!r.ok()) GTEST_SKIP() << "libusb unavailable here: " << r.error().message;
  UsbParams p;
  p.vendor_id = 0xfeed;
  p.product_id = 0x0b0c;
  UsbTransport t(p);
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("(" + std::to_string(r->size()) + " USB device(s) present)"), std::string::npos)
      << st.error().message;
}

// ---- A fake USB bus -------------------------------------------------------------------------

struct IdealMotor final : device::MotorPort {
  uint64_t steps = 0;
  void step(double, int) override { ++steps; }
  void set_enabled(double, bool) override {}
  int64_t read_encoder_counts(double) override { return 0; }
};

struct FakeDevice {
  UsbDeviceEntry entry;
  std::string serial;
  bool present = true;
  int generation = 0;          // bumped by an unplug: handles opened before are dead
  int open_error = 0;          // e.g. LIBUSB_ERROR_ACCESS
  int claim_error = 0;         // e.g. LIBUSB_ERROR_BUSY
  device::VirtualMcu* mcu = nullptr;
  std::vector<uint8_t> in;     // bytes the MCU sent, not yet read by the host
};

class FakeUsb final : public UsbBackend {
 public:
  std::vector<FakeDevice*> bus;
  double now = 0.0;            // virtual time, set by the test
  int opens = 0, transfers_after_unplug = 0;

  void unplug(FakeDevice& d) {
    d.present = false;
    ++d.generation;
    d.in.clear();
  }
  void replug(FakeDevice& d, device::VirtualMcu* mcu) {
    d.present = true;
    d.mcu = mcu;
  }

  int init() override { return 0; }
  int list(std::vector<UsbDeviceEntry>& out) override {
    out.clear();
    listed_.clear();
    for (FakeDevice* d : bus)
      if (d->present) {
        out.push_back(d->entry);
        listed_.push_back(d);
      }
    return 0;
  }
  int open(size_t index, UsbHandle* h) override {
    if (index >= listed_.size()) return LIBUSB_ERROR_NOT_FOUND;
    FakeDevice* d = listed_[index];
    if (!d->present) return LIBUSB_ERROR_NO_DEVICE;
    if (d->open_error != 0) return d->open_error;
    handles_.push_back(std::make_unique<Handle>(Handle{d, d->generation, false}));
    *h = reinterpret_cast<UsbHandle>(handles_.back().get());
    ++opens;
    return 0;
  }
  int serial_number(UsbHandle h, uint8_t, std::string& out) override {
    out = handle(h)->dev->serial;
    return 0;
  }
  int claim_interface(UsbHandle h, int) override { return handle(h)->dev->claim_error; }
  void close(UsbHandle h, int) override { handle(h)->closed = true; }
  // Asynchronous transfers: queued here, completed (done() called) by handle_events() in
  // submission order, as a host controller completes them: OUT at once (the device reads) unless
  // out_stalled (a device that stops reading: NAKs forever); IN when the device has sent bytes.
  int submit(UsbHandle h, UsbTransfer& t) override {
    std::lock_guard lock(mutex_);
    Handle* hd = handle(h);
    if (hd->closed) return LIBUSB_ERROR_INVALID_PARAM;
    FakeDevice& d = *hd->dev;
    if (!d.present || hd->generation != d.generation) {
      ++transfers_after_unplug;
      return LIBUSB_ERROR_NO_DEVICE;
    }
    pending_.push_back({&t, hd, false});
    ++submitted;
    return 0;
  }
  void cancel(UsbTransfer& t) override {
    std::lock_guard lock(mutex_);
    for (Pending& p : pending_)
      if (p.t == &t) p.cancelled = true;
  }
  void handle_events(double max_wait_s) override {
    complete_due();
    if (sleep_in_events && max_wait_s > 0.0)  // like libusb: wait for events (there are none)
      std::this_thread::sleep_for(std::chrono::duration<double>(max_wait_s));
  }
  void complete_due() {
    std::lock_guard lock(mutex_);
    scratch_.clear();
    scratch_.swap(pending_);  // both keep their capacity: no allocation in steady use
    for (Pending& p : scratch_) {
      UsbTransfer& t = *p.t;
      FakeDevice& d = *p.h->dev;
      if (p.cancelled) {
        complete(t, UsbTransferStatus::kCancelled, 0);
      } else if (!d.present || p.h->generation != d.generation) {
        ++transfers_after_unplug;
        complete(t, UsbTransferStatus::kNoDevice, 0);
      } else if ((t.endpoint & 0x80) == 0) {  // OUT: frames to the MCU
        if (out_stalled) {
          pending_.push_back(p);
          continue;
        }
        d.mcu->receive(t.buffer, static_cast<size_t>(t.length), now);
        complete(t, UsbTransferStatus::kCompleted, t.length);
      } else {  // IN: what the MCU sent
        d.mcu->run_until(now);
        uint8_t frame[protocol::kMaxFrame];
        size_t n = 0;
        while (d.mcu->pop_frame(frame, n)) d.in.insert(d.in.end(), frame, frame + n);
        if (d.in.empty()) {
          pending_.push_back(p);
          continue;
        }
        const size_t take = std::min(d.in.size(), static_cast<size_t>(t.length));
        std::memcpy(t.buffer, d.in.data(), take);
        d.in.erase(d.in.begin(), d.in.begin() + static_cast<std::ptrdiff_t>(take));
        complete(t, UsbTransferStatus::kCompleted, static_cast<int>(take));
      }
    }
  }
  size_t in_flight() {
    std::lock_guard lock(mutex_);
    return pending_.size();
  }
  std::atomic<bool> out_stalled{false};  // the device stops reading (NAKs every OUT packet)
  bool sleep_in_events = false;          // an I/O thread's handle_events waits as libusb's does
  uint64_t submitted = 0;
  FakeUsb() {
    pending_.reserve(64);
    scratch_.reserve(64);
  }
  std::string error_text(int rc) const override { return std::string(libusb_error_name(rc)); }

 private:
  struct Handle {
    FakeDevice* dev;
    int generation;
    bool closed;
  };
  struct Pending {
    UsbTransfer* t;
    Handle* h;
    bool cancelled;
  };
  static void complete(UsbTransfer& t, UsbTransferStatus status, int transferred) {
    t.status = status;
    t.transferred = transferred;
    t.done(t);
  }
  std::mutex mutex_;  // the I/O thread's calls against the test's inspection
  std::vector<Pending> pending_, scratch_;
  static Handle* handle(UsbHandle h) { return reinterpret_cast<Handle*>(h); }
  std::vector<FakeDevice*> listed_;
  std::vector<std::unique_ptr<Handle>> handles_;
};

FakeDevice other_device(uint16_t vid, uint16_t pid, int address) {
  FakeDevice d;
  d.entry = {vid, pid, 1, address, 0};
  return d;
}

// Virtual time: the transport does its I/O in poll() on the test's thread (no I/O thread), so
// the fake bus and its VirtualMcu run deterministically at the test's `now`.
UsbParams mcu_params_usb() {
  UsbParams p;  // 1d50:614e
  p.serial = "FL-1";
  p.io.io_thread = false;
  return p;
}

TEST(UsbFake, NoDeviceNamesVidPidSerialAndCountsTheBus) {
  auto fake = std::make_unique<FakeUsb>();
  FakeDevice hub = other_device(0x1d6b, 0x0002, 1), mouse = other_device(0x046d, 0xc077, 4);
  fake->bus = {&hub, &mouse};
  UsbTransport t(mcu_params_usb(), std::move(fake));
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  const std::string m = st.error().message;
  std::printf("error: %s\n", m.c_str());
  EXPECT_NE(m.find("no USB device usb 1d50:614e serial FL-1 found (2 USB device(s) present)"), std::string::npos) << m;
  EXPECT_NE(m.find("plugged in"), std::string::npos) << m;
  EXPECT_FALSE(t.connected());
}

TEST(UsbFake, OtherSerialNumberIsSaid) {
  auto fake = std::make_unique<FakeUsb>();
  FakeDevice other = other_device(0x1d50, 0x614e, 5);
  other.entry.serial_index = 3;
  other.serial = "FL-2";
  fake->bus = {&other};
  UsbTransport t(mcu_params_usb(), std::move(fake));
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("with serial 'FL-1' (1 device(s) with that VID:PID have other serial numbers)"),
            std::string::npos)
      << st.error().message;
}

TEST(UsbFake, PermissionDeniedSuggestsTheUdevRule) {
  auto fake = std::make_unique<FakeUsb>();
  FakeDevice d = other_device(0x1d50, 0x614e, 7);
  d.open_error = LIBUSB_ERROR_ACCESS;
  fake->bus = {&d};
  UsbParams p = mcu_params_usb();
  p.serial.clear();
  UsbTransport t(p, std::move(fake));
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  const std::string m = st.error().message;
  std::printf("error: %s\n", m.c_str());
  EXPECT_NE(m.find("cannot open usb 1d50:614e at bus 1 address 7: LIBUSB_ERROR_ACCESS"), std::string::npos) << m;
  EXPECT_NE(m.find("permission denied: install a udev rule for 1d50:614e"), std::string::npos) << m;
}

TEST(UsbFake, BusyInterfaceNamesTheOtherProgram) {
  auto fake = std::make_unique<FakeUsb>();
  FakeDevice d = other_device(0x1d50, 0x614e, 7);
  d.claim_error = LIBUSB_ERROR_BUSY;
  fake->bus = {&d};
  UsbParams p = mcu_params_usb();
  p.serial.clear();
  UsbTransport t(p, std::move(fake));
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("cannot claim interface 0 of usb 1d50:614e at bus 1 address 7: LIBUSB_ERROR_BUSY; "
                                    "another program is using the MCU"),
            std::string::npos)
      << st.error().message;
}

// A session over UsbTransport on the fake bus, in virtual time.
struct UsbRig {
  IdealMotor motor_a, motor_b;
  std::unique_ptr<device::VirtualMcu> a, b;  // b: the same MCU after a reboot
  FakeDevice dev;
  FakeUsb* fake = nullptr;
  std::unique_ptr<UsbTransport> transport;
  std::unique_ptr<McuSession> session;
  double now = 0.0;

  UsbRig() {
    device::VirtualMcuParams vp;
    vp.drift_ppm = 30.0;
    std::snprintf(vp.name, sizeof vp.name, "usb-x");
    a = std::make_unique<device::VirtualMcu>(vp, &motor_a);
    vp.offset_s = 7.0;  // rebooted: its clock restarted
    b = std::make_unique<device::VirtualMcu>(vp, &motor_b);
    dev.entry = {0x1d50, 0x614e, 1, 9, 3};
    dev.serial = "FL-1";
    dev.mcu = a.get();
    auto f = std::make_unique<FakeUsb>();
    fake = f.get();
    fake->bus = {&dev};
    transport = std::make_unique<UsbTransport>(mcu_params_usb(), std::move(f));
    McuSessionParams sp;
    sp.name = "x";
    session = std::make_unique<McuSession>(sp, *transport);
  }
  void advance(double until) {
    while (now < until) {
      now += 1e-4;
      fake->now = now;
      session->poll(now);
    }
  }
  template <class Pred>
  bool advance_until(Pred pred, double timeout_s) {
    const double end = now + timeout_s;
    while (now < end && !pred()) advance(now + 1e-3);
    return pred();
  }
  bool start() {
    if (!session->start(now).ok()) return false;
    if (!advance_until([&] { return session->ready(); }, 1.0)) return false;
    advance(now + 0.5);  // clock sync
    return true;
  }
  // Queues `batches` batches of 100 steps each at 2 kHz, back to back, starting 0.2 s from now;
  // returns the expected step count and hash.
  std::pair<uint64_t, uint64_t> queue_motion(int batches) {
    uint64_t steps = 0, hash = device::kStepHashSeed;
    const auto ticks = [&](double t) { return static_cast<int64_t>(session->clock().clock_at(t)); };
    int64_t p = ticks(now + 0.2);
    const int64_t interval = ticks(now + 0.2 + 500e-6) - p;
    for (int i = 0; i < batches; ++i) {
      uint8_t body[64];
      stepgen::RunEncoder enc;
      enc.begin(body, sizeof body, static_cast<uint64_t>(p));
      const stepgen::StepRun run{interval, 0, 100, static_cast<int8_t>(i % 2 == 0 ? 1 : -1)};
      enc.append(run);
      for (uint32_t k = 1; k <= run.count; ++k) hash = device::step_hash_update(hash, stepgen::run_step_clock(p, run, k), run.direction);
      steps += run.count;
      const int64_t end = stepgen::run_end_clock(p, run);
      session->queue_steps({0, body, enc.size(), 1, run.count, p, end});
      p = end;
    }
    return {steps, hash};
  }
};

TEST(UsbFake, UnplugMidStreamAndReplugOfTheSameDeviceLosesNoStep) {
  UsbRig rig;
  ASSERT_TRUE(rig.start()) << (rig.session->error() ? rig.session->error()->message : "not ready");
  rig.session->set_enabled(true);
  const auto [steps, hash] = rig.queue_motion(30);  // 3000 steps over 1.5 s
  rig.advance(rig.now + 0.25);
  // A short glitch (the device keeps its state): 150 ms without the device.
  rig.fake->unplug(rig.dev);
  ASSERT_TRUE(rig.advance_until([&] { return rig.session->state() == McuState::kDisconnected; }, 0.01));
  EXPECT_FALSE(rig.transport->connected());
  rig.advance(rig.now + 0.15);
  rig.fake->replug(rig.dev, rig.a.get());
  ASSERT_TRUE(rig.advance_until([&] { return rig.session->state() == McuState::kReady; }, 0.5));
  rig.advance(rig.now + 2.0);
  rig.session->request_status();
  rig.advance(rig.now + 0.1);
  const auto events = rig.session->take_events();
  for (const auto& e : events) std::printf("event: %s\n", e.c_str());
  ASSERT_GE(events.size(), 2u);
  EXPECT_NE(events[0].find("MCU 'x' (usb 1d50:614e serial FL-1) disconnected: usb 1d50:614e serial FL-1 unplugged"),
            std::string::npos)
      << events[0];
  EXPECT_NE(events[1].find("reconnected"), std::string::npos) << events[1];
  ASSERT_TRUE(rig.session->last_status().has_value());
  std::printf("same device: %llu steps sent, %llu executed; %d opens\n", (unsigned long long)steps,
              (unsigned long long)rig.session->last_status()->steps_executed, rig.fake->opens);
  EXPECT_EQ(rig.motor_a.steps, steps);
  EXPECT_EQ(rig.session->last_status()->step_hash, hash);
  EXPECT_EQ(rig.fake->opens, 2);  // reopened once the device was back
}

TEST(UsbFake, ReplugOfARebootedDeviceIsReportedAndReidentified) {
  UsbRig rig;
  ASSERT_TRUE(rig.start()) << (rig.session->error() ? rig.session->error()->message : "not ready");
  rig.session->set_enabled(true);
  rig.queue_motion(30);
  rig.advance(rig.now + 0.5);
  const uint64_t executed_before = rig.motor_a.steps;
  rig.fake->unplug(rig.dev);
  rig.advance(rig.now + 0.1);
  ASSERT_EQ(rig.session->state(), McuState::kDisconnected);
  // Absent for 1 s: the session keeps retrying (every 250 ms) and stays disconnected.
  rig.advance(rig.now + 1.0);
  EXPECT_EQ(rig.session->state(), McuState::kDisconnected);
  EXPECT_EQ(rig.fake->opens, 1);
  // Back, rebooted (power cycled with the cable): its link state and queue are gone.
  rig.fake->replug(rig.dev, rig.b.get());
  const double back = rig.now;
  ASSERT_TRUE(rig.advance_until([&] { return rig.session->state() == McuState::kFailed; }, 3.0));
  const std::string msg = rig.session->error()->message;
  std::printf("%llu steps executed before the unplug; %.0f ms after the replug: %s\n",
              (unsigned long long)executed_before, (rig.now - back) * 1e3, msg.c_str());
  EXPECT_NE(msg.find("MCU 'x' (usb 1d50:614e serial FL-1)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("restarted"), std::string::npos) << msg;
  EXPECT_LT(rig.now - back, 1.5);
  // The session re-identifies the rebooted device and streams again.
  ASSERT_TRUE(rig.start()) << (rig.session->error() ? rig.session->error()->message : "not ready");
  rig.session->set_enabled(true);
  const auto [steps, hash] = rig.queue_motion(10);
  rig.advance(rig.now + 1.0);
  rig.session->request_status();
  rig.advance(rig.now + 0.1);
  ASSERT_TRUE(rig.session->last_status().has_value());
  EXPECT_TRUE(rig.b->status().identified);
  EXPECT_EQ(rig.motor_b.steps, steps);
  EXPECT_EQ(rig.session->last_status()->steps_executed, steps);
  EXPECT_EQ(rig.session->last_status()->step_hash, hash);
}

// The caller's side of the USB transport with its I/O thread, against a device that stops
// reading (every OUT transfer stays pending, as NAKed packets do): the OUT transfers fill, the
// send queue fills, and try_write() keeps returning at once with kFull (counted) — without
// blocking (no voluntary context switch of the calling thread) and without allocating (either
// thread). When the device reads again, the queue drains and frames are taken again.
TEST(UsbRealTime, DeviceThatStopsReadingGivesBackPressureWithoutBlockingOrAllocating) {
  IdealMotor motor;
  device::VirtualMcuParams vp;
  std::snprintf(vp.name, sizeof vp.name, "usb-x");
  device::VirtualMcu mcu(vp, &motor);
  FakeDevice dev;
  dev.entry = {0x1d50, 0x614e, 1, 9, 3};
  dev.serial = "FL-1";
  dev.mcu = &mcu;
  auto f = std::make_unique<FakeUsb>();
  FakeUsb* fake = f.get();
  fake->bus = {&dev};
  fake->sleep_in_events = true;
  fake->out_stalled = true;
  UsbParams p;
  p.serial = "FL-1";  // an I/O thread (the default)
  UsbTransport t(p, std::move(f));
  ASSERT_TRUE(t.open().ok()) << t.error_text();
  MonotonicClock clock;
  uint8_t frame[protocol::kMaxFrame];
  for (size_t i = 0; i < sizeof frame; ++i) frame[i] = static_cast<uint8_t>(i * 3);
  constexpr int kCalls = 20000;
  std::vector<double> us;
  us.reserve(kCalls);
  uint64_t queued = 0, full = 0, other = 0;
  rusage r0{}, r1{};
  ::getrusage(RUSAGE_THREAD, &r0);
#ifdef FEEDLOOP_COUNT_MALLOC
  g_mallocs.store(0);
  g_counting.store(true);
#endif
  const int64_t start_ns = clock.now_ns();
  for (int i = 0; i < kCalls; ++i) {
    const int64_t a = clock.now_ns();
    const TxResult r = t.try_write(frame, sizeof frame);
    us.push_back(static_cast<double>(clock.now_ns() - a) * 1e-3);
    if (r == TxResult::kQueued) ++queued;
    else if (r == TxResult::kFull) ++full;
    else ++other;
    while (clock.now_ns() < start_ns + (i + 1) * 50'000) {
    }
  }
#ifdef FEEDLOOP_COUNT_MALLOC
  g_counting.store(false);
  const long mallocs = g_mallocs.load();
#endif
  ::getrusage(RUSAGE_THREAD, &r1);
  const TransportStats s = t.io_stats();
  std::sort(us.begin(), us.end());
  const double median = us[us.size() / 2], p99 = us[us.size() * 99 / 100], max = us.back();
  std::printf("%d try_write calls, device not reading: %llu queued, %llu refused; OUT transfers pending %d, I/O "
              "thread found them all busy %llu times; median %.2f us, p99 %.2f us, max %.1f us; context switches: "
              "%ld voluntary, %ld involuntary\n",
              kCalls, (unsigned long long)queued, (unsigned long long)full, UsbTransport::kOutTransfers,
              (unsigned long long)s.tx_blocked, median, p99, max, r1.ru_nvcsw - r0.ru_nvcsw,
              r1.ru_nivcsw - r0.ru_nivcsw);
  EXPECT_EQ(other, 0u);
  EXPECT_GT(full, 1000u);
  EXPECT_EQ(s.tx_full, full);
  EXPECT_GT(s.tx_blocked, 0u);
  EXPECT_EQ(r1.ru_nvcsw - r0.ru_nvcsw, 0);
  EXPECT_LT(median, 5.0);
  EXPECT_LT(p99, 20.0);
  EXPECT_LT(max, 50'000.0);
#ifdef FEEDLOOP_COUNT_MALLOC
  EXPECT_EQ(mallocs, 0) << "allocations during the calls (either thread)";
#endif
  // The device reads again: within 100 ms the queue has room.
  fake->out_stalled = false;
  const int64_t t0 = clock.now_ns();
  TxResult again = TxResult::kFull;
  while (again == TxResult::kFull && clock.now_ns() - t0 < 100'000'000) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));
    again = t.try_write(frame, sizeof frame);
  }
  EXPECT_EQ(again, TxResult::kQueued);
  EXPECT_TRUE(t.connected());
}

}  // namespace
}  // namespace feedloop::drivers
