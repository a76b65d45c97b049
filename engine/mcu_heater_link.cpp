// Heaters and fans over MCU sessions: see mcu_heater_link.hpp.
#include "engine/mcu_heater_link.hpp"

#include <algorithm>
#include <cmath>

#include "drivers/protocol/heater_messages.hpp"
#include "drivers/transport/mock_transport.hpp"

namespace feedloop::engine {

using protocol::MsgType;

drivers::McuSessionParams heater_session_params(const std::string& name) {
  drivers::McuSessionParams p;
  p.name = name;
  p.encoder_period_s = 0.0;
  p.watchdog_s = 0.0;
  p.clock_query_period_s = 1.0;
  return p;
}

McuHeaterLink::McuHeaterLink(std::vector<HeaterMcu> mcus, std::vector<HeaterRoute> heaters,
                             std::vector<HeaterRoute> fans, double host_clock_hz, double io_slice_s)
    : heaters_(std::move(heaters)), fans_(std::move(fans)), host_hz_(host_clock_hz), io_slice_s_(io_slice_s) {
  mcus_.reserve(mcus.size());
  for (HeaterMcu& c : mcus) {
    Mcu m;
    m.cfg = std::move(c);
    if (!m.cfg.shared)
      m.session = std::make_unique<drivers::McuSession>(m.cfg.session, *m.cfg.transport);
    mcus_.push_back(std::move(m));
  }
}

McuHeaterLink::~McuHeaterLink() {
  // The sessions before their transports (a session must not outlive its transport).
  for (Mcu& m : mcus_) m.session.reset();
}

void McuHeaterLink::send(double now_s, const uint8_t* msg, size_t n) {
  if (n < 2) return;
  const auto type = static_cast<MsgType>(msg[0]);
  const std::vector<HeaterRoute>* routes = nullptr;
  if (type == MsgType::kConfigureHeater || type == MsgType::kSetHeater) routes = &heaters_;
  else if (type == MsgType::kSetFan) routes = &fans_;
  if (routes == nullptr || msg[1] >= routes->size()) return;  // not ours to route
  if (type == MsgType::kSetHeater && drop_set_heater_) {
    ++set_heater_dropped_;
    return;
  }
  const HeaterRoute& r = (*routes)[msg[1]];
  Mcu& m = mcus_[static_cast<size_t>(r.mcu)];
  std::vector<uint8_t> v(msg, msg + n);
  v[1] = r.local;
  if (!m.started) {
    m.started = true;
    m.last_poll_s = now_s;
    if (m.session && !m.session->start(now_s).ok() && !fault_)  // (a shared one: the bridge's)
      fault_ = "heater MCU: " + m.session->error()->message;
  }
  forward(m, std::move(v));
}

bool McuHeaterLink::mcu_ready(const Mcu& m) const {
  return m.cfg.shared ? m.cfg.shared->ready() : m.session->ready();
}

void McuHeaterLink::forward(Mcu& m, std::vector<uint8_t> msg) {
  if (!mcu_ready(m)) {  // sent once the MCU is identified (its clock rate known)
    m.held.push_back(std::move(msg));
    return;
  }
  auto queue = [&](const uint8_t* bytes, size_t n) {
    if (!m.cfg.shared) {
      m.session->queue_message(bytes, n);
    } else if (!m.cfg.shared->send_to_mcu(bytes, n) && !fault_) {
      fault_ = "heater MCU '" + m.cfg.name + "': the motion side takes no heater messages (" +
               std::to_string(SharedHeaterPort::kRing) + " waiting; the servo thread stopped?)";
    }
  };
  const uint32_t mcu_hz = m.cfg.shared ? m.cfg.shared->clock_hz() : m.session->mcu_clock_hz();
  if (msg[0] == static_cast<uint8_t>(MsgType::kConfigureHeater)) {
    // Tick counts in the host's heater clock -> the MCU's ticks.
    protocol::ConfigureHeaterMsg c;
    if (!protocol::decode_configure_heater(msg.data(), msg.size(), c)) return;
    const double k = static_cast<double>(mcu_hz) / host_hz_;
    c.sample_period_ticks = static_cast<uint32_t>(
        std::clamp(std::llround(c.sample_period_ticks * k), 1LL, static_cast<long long>(UINT32_MAX)));
    c.confirm_timeout_ticks = static_cast<uint32_t>(
        std::clamp(std::llround(c.confirm_timeout_ticks * k), 0LL, static_cast<long long>(UINT32_MAX)));
    uint8_t buf[32];
    const size_t n = protocol::encode_configure_heater(c, buf, sizeof buf);
    queue(buf, n);
    return;
  }
  queue(msg.data(), msg.size());
}

// The held messages go out once the MCU is identified, if it speaks protocol v3 (else a fault).
void McuHeaterLink::release_held(Mcu& m, uint16_t version) {
  if (m.held.empty()) return;
  if (version < 3) {
    if (!fault_)
      fault_ = "heater MCU '" + m.cfg.name + "' speaks protocol version " +
               std::to_string(version) +
               ": heaters and fans need version 3 (CONFIGURE_HEATER, SET_HEATER, SET_FAN); flash "
               "firmware that matches this host";
    m.held.clear();
    return;
  }
  while (!m.held.empty()) {
    forward(m, std::move(m.held.front()));
    m.held.pop_front();
  }
}

// A motion MCU's heaters: the bridge polls the session; here its state, as published.
void McuHeaterLink::poll_shared(Mcu& m, double) {
  SharedHeaterPort& port = *m.cfg.shared;
  if (port.failed() && !fault_) fault_ = "heater MCU '" + m.cfg.name + "': " + port.fault();
  if (port.ready()) release_held(m, port.version());
  m.last_heard_s = port.last_heard_s();
}

void McuHeaterLink::poll(Mcu& m, double t_s) {
  if (!m.started) return;
  if (m.cfg.shared) {
    poll_shared(m, t_s);
    return;
  }
  const double host_t_s = t_s;
  // After run_devices_only() the devices are ahead: the host wakes up at their time (as a stalled
  // host does: the wire's time went on), then catches up with what they sent.
  t_s = std::max(t_s, devices_ran_to_s_);
  m.last_poll_s = std::max(m.last_poll_s, devices_ran_to_s_ - io_slice_s_);
  if (m.cfg.mock != nullptr && io_slice_s_ > 0) {
    // Every io_slice_s while frames are on their way; with nothing in flight either way, straight
    // to the device's next event (its next ADC sample).
    for (double t = m.last_poll_s;;) {
      double next = t + io_slice_s_;
      if (m.session->idle()) next = std::max(next, m.cfg.mock->mcu().next_event_time());
      if (next >= t_s) break;
      m.session->poll(next);
      t = next;
    }
  }
  m.session->poll(t_s);
  m.last_poll_s = std::max(m.last_poll_s, t_s);
  if (m.session->ready() && !m.held.empty()) {
    release_held(m, m.session->negotiated_version());
    if (fault_) return;
    m.session->poll(t_s);
  }
  const auto& ls = m.session->link_stats();
  const uint64_t in = ls.delivered + ls.duplicates_dropped + ls.out_of_order_dropped;
  if (in != m.frames_in) {
    m.frames_in = in;
    m.last_heard_s = host_t_s;
  }
  // The session's events (MCU errors, reconnects): the latest is kept for the fault message.
  for (std::string& e : m.session->take_events()) last_event_ = std::move(e);
  if (m.session->state() == drivers::McuState::kFailed && !fault_)
    fault_ = "heater MCU: " + (m.session->error() ? m.session->error()->message : std::string("failed"));
}

template <class ToHostS>
void McuHeaterLink::deliver(int mcu_index, const uint8_t* bytes, size_t n_in, ToHostS to_host_s) {
  // The MCU's clock -> host time -> the thermal loop's ticks; its local index -> the loop's.
  auto host_clock = [&](int64_t clock) {
    return static_cast<int64_t>(std::llround(std::max(0.0, to_host_s(clock)) * host_hz_));
  };
  auto global = [&](const std::vector<HeaterRoute>& routes, uint8_t local) {
    for (size_t g = 0; g < routes.size(); ++g)
      if (routes[g].mcu == mcu_index && routes[g].local == local) return static_cast<int>(g);
    return -1;
  };
  uint8_t out[32];
  size_t n = 0;
  if (n_in > 0 && bytes[0] == static_cast<uint8_t>(MsgType::kHeaterReport)) {
    protocol::HeaterReportMsg r;
    if (!protocol::decode_heater_report(bytes, n_in, r)) return;
    const int g = global(heaters_, r.heater);
    if (g < 0) return;
    r.heater = static_cast<uint8_t>(g);
    r.clock = host_clock(r.clock);
    n = protocol::encode_heater_report(r, out, sizeof out);
  } else {
    protocol::HeaterFaultMsg f;
    if (!protocol::decode_heater_fault(bytes, n_in, f)) return;
    const int g = global(heaters_, f.heater);
    if (g < 0) return;
    f.heater = static_cast<uint8_t>(g);
    f.clock = host_clock(f.clock);
    n = protocol::encode_heater_fault(f, out, sizeof out);
  }
  if (n > 0) inbox_.emplace_back(out, out + n);
}

void McuHeaterLink::collect(int mcu_index, double t_s) {
  Mcu& m = mcus_[static_cast<size_t>(mcu_index)];
  if (m.cfg.shared) {  // mapped with the clock the bridge's session had when it arrived
    SharedHeaterPort::Message msg;
    while (m.cfg.shared->take_from_mcu(msg))
      deliver(mcu_index, msg.bytes, msg.n, [&](int64_t clock) {
        return msg.clock_ready ? (static_cast<double>(clock) - msg.offset_ticks) / msg.ticks_per_s
                               : msg.arrival_s;
      });
    return;
  }
  drivers::HeaterPayload buf[16];
  for (;;) {
    const size_t k = m.session->take_heater_messages(buf, 16);
    for (size_t i = 0; i < k; ++i)
      deliver(mcu_index, buf[i].bytes, buf[i].n, [&](int64_t clock) {
        // The clock sync's estimate; the arrival before the first sync.
        const drivers::ClockEstimate& e = m.session->clock();
        return e.ready() ? e.host_time_at(static_cast<double>(clock)) : t_s;
      });
    if (k < 16) break;
  }
}

void McuHeaterLink::advance_to(double t_s) {
  for (size_t i = 0; i < mcus_.size(); ++i) {
    poll(mcus_[i], t_s);
    collect(static_cast<int>(i), t_s);
  }
}

std::string McuHeaterLink::heater_place(int heater) const {
  if (heater < 0 || heater >= num_heaters()) return {};
  const Mcu& m = mcus_[static_cast<size_t>(heaters_[static_cast<size_t>(heater)].mcu)];
  std::string s = ": MCU '" + m.cfg.name + "'";
  if (!last_event_.empty()) s += "; last event: " + last_event_;
  return s;
}

double McuHeaterLink::last_heard_s(int heater) const {
  if (heater < 0 || heater >= num_heaters()) return -1e300;
  const Mcu& m = mcus_[static_cast<size_t>(heaters_[static_cast<size_t>(heater)].mcu)];
  // A simulated MCU that run_devices_only() ran ahead of the host was alive to then: what it sent
  // meanwhile reaches the host as the host's time catches up with it (a real host wakes at the
  // wire's time and finds it all queued).
  return m.cfg.mock != nullptr ? std::max(m.last_heard_s, devices_ran_to_s_) : m.last_heard_s;
}

bool McuHeaterLink::receive(uint8_t* out, size_t& n) {
  if (inbox_.empty()) return false;
  const std::vector<uint8_t>& m = inbox_.front();
  n = std::min<size_t>(m.size(), 32);
  std::copy(m.begin(), m.begin() + static_cast<std::ptrdiff_t>(n), out);
  inbox_.pop_front();
  return true;
}

void McuHeaterLink::run_devices_only(double t_s) {
  devices_ran_to_s_ = std::max(devices_ran_to_s_, t_s);
  for (Mcu& m : mcus_)
    if (m.cfg.mock != nullptr) m.cfg.mock->poll(t_s, 0.0);
}

}  // namespace feedloop::engine
