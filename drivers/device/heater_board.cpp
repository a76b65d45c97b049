#include "drivers/device/heater_board.hpp"

namespace feedloop::device {

HeaterBoard::HeaterBoard(HeaterPort* const* heaters, int num_heaters, FanPort* const* fans,
                         int num_fans, double clock_hz)
    : clock_hz_(clock_hz > 0 ? clock_hz : 1e6) {
  nh_ = num_heaters < 0 ? 0 : (num_heaters > kMaxHeaters ? kMaxHeaters : num_heaters);
  nf_ = num_fans < 0 ? 0 : (num_fans > kMaxFans ? kMaxFans : num_fans);
  for (int i = 0; i < nh_; ++i) h_[i].port = heaters[i];
  for (int i = 0; i < nf_; ++i) fans_[i] = fans[i];
}

void HeaterBoard::push(const uint8_t* p, size_t n) {
  if (out_count_ == kMaxOut || n > kMsgCap) {
    ++dropped_;
    return;
  }
  const int slot = (out_head_ + out_count_) % kMaxOut;
  for (size_t i = 0; i < n; ++i) out_[slot][i] = p[i];
  out_len_[slot] = n;
  ++out_count_;
}

bool HeaterBoard::pop_message(uint8_t* out, size_t& n) {
  if (out_count_ == 0) return false;
  n = out_len_[out_head_];
  for (size_t i = 0; i < n; ++i) out[i] = out_[out_head_][i];
  out_head_ = (out_head_ + 1) % kMaxOut;
  --out_count_;
  return true;
}

void HeaterBoard::apply(int i, uint16_t duty, int64_t clock) {
  Heater& h = h_[i];
  if (duty > h.cfg.max_duty) duty = h.cfg.max_duty;
  h.st.duty = duty;
  if (h.port) h.port->set_duty(t_of(clock), static_cast<double>(duty) / 65535.0);
}

void HeaterBoard::trip(int i, protocol::HeaterFaultReason why, int64_t clock, uint16_t adc) {
  Heater& h = h_[i];
  apply(i, 0, clock);
  h.st.faulted = true;
  h.st.fault = why;
  uint8_t buf[kMsgCap];
  const size_t n = protocol::encode_heater_fault(
      protocol::HeaterFaultMsg{static_cast<uint8_t>(i), why, clock, adc}, buf, sizeof buf);
  if (n) push(buf, n);
}

void HeaterBoard::all_off(int64_t now_clock) {
  for (int i = 0; i < nh_; ++i) apply(i, 0, now_clock);
}

bool HeaterBoard::on_message(const uint8_t* p, size_t n, int64_t now_clock) {
  if (n == 0) return false;
  switch (static_cast<protocol::MsgType>(p[0])) {
    case protocol::MsgType::kConfigureHeater: {
      protocol::ConfigureHeaterMsg m;
      if (!protocol::decode_configure_heater(p, n, m)) return false;
      if (m.heater >= nh_) return false;
      Heater& h = h_[m.heater];
      if (m.sample_period_ticks == 0 || m.samples_per_report == 0 || m.adc_min >= m.adc_max) {
        trip(m.heater, protocol::HeaterFaultReason::kBadConfig, now_clock, 0);
        return true;
      }
      h.cfg = m;
      h.st = HeaterState{};
      h.st.configured = true;
      h.st.last_confirm_clock = now_clock;
      h.next_sample_clock = now_clock + m.sample_period_ticks;
      h.sum = 0;
      h.nsum = 0;
      apply(m.heater, 0, now_clock);
      return true;
    }
    case protocol::MsgType::kSetHeater: {
      protocol::SetHeaterMsg m;
      if (!protocol::decode_set_heater(p, n, m)) return false;
      if (m.heater >= nh_) return false;
      Heater& h = h_[m.heater];
      if (!h.st.configured || h.st.faulted) return true;  // stays off until reconfigured
      h.st.last_confirm_clock = now_clock;
      apply(m.heater, m.duty, now_clock);
      return true;
    }
    case protocol::MsgType::kSetFan: {
      protocol::SetFanMsg m;
      if (!protocol::decode_set_fan(p, n, m)) return false;
      if (m.fan >= nf_) return false;
      if (fans_[m.fan])
        fans_[m.fan]->set_duty(t_of(now_clock), static_cast<double>(m.duty) / 65535.0);
      return true;
    }
    default:
      return false;
  }
}

void HeaterBoard::run(int64_t now_clock) {
  for (int i = 0; i < nh_; ++i) {
    Heater& h = h_[i];
    if (!h.st.configured || h.st.faulted) continue;
    while (h.next_sample_clock <= now_clock && !h.st.faulted) {
      const int64_t c = h.next_sample_clock;
      h.next_sample_clock += h.cfg.sample_period_ticks;
      // Watchdog first: a heater on without a recent confirmation goes off.
      if (h.st.duty > 0 && h.cfg.confirm_timeout_ticks > 0 &&
          c - h.st.last_confirm_clock > static_cast<int64_t>(h.cfg.confirm_timeout_ticks)) {
        trip(i, protocol::HeaterFaultReason::kWatchdog, c, h.st.last_adc);
        break;
      }
      const uint16_t adc = h.port ? h.port->read_adc(t_of(c)) : 0;
      h.st.last_adc = adc;
      if (adc < h.cfg.adc_min || adc > h.cfg.adc_max) {
        trip(i, protocol::HeaterFaultReason::kAdcRange, c, adc);
        break;
      }
      h.sum += adc;
      if (++h.nsum >= h.cfg.samples_per_report) {
        uint8_t buf[kMsgCap];
        const protocol::HeaterReportMsg r{static_cast<uint8_t>(i), c,
                                          static_cast<uint16_t>(h.sum / h.nsum), h.st.duty};
        const size_t n = protocol::encode_heater_report(r, buf, sizeof buf);
        if (n) push(buf, n);
        h.sum = 0;
        h.nsum = 0;
      }
    }
  }
}

int64_t HeaterBoard::next_event_clock() const {
  int64_t next = INT64_MAX;
  for (int i = 0; i < nh_; ++i)
    if (h_[i].st.configured && !h_[i].st.faulted && h_[i].next_sample_clock < next)
      next = h_[i].next_sample_clock;
  return next;
}

}  // namespace feedloop::device
