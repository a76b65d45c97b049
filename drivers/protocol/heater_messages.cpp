#include "drivers/protocol/heater_messages.hpp"

namespace feedloop::protocol {
namespace {
size_t done(const MsgWriter& w) {
  return w.ok() ? w.size() : 0;
}
bool start(MsgReader& r, MsgType t) {
  return r.u8() == static_cast<uint8_t>(t) && r.ok();
}
bool finish(const MsgReader& r) {
  return r.ok() && r.at_end();
}
}  // namespace

size_t encode_configure_heater(const ConfigureHeaterMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kConfigureHeater))
      .u8(m.heater)
      .var(m.sample_period_ticks)
      .u16(m.samples_per_report)
      .u16(m.adc_min)
      .u16(m.adc_max)
      .var(m.confirm_timeout_ticks)
      .u16(m.max_duty);
  return done(w);
}
bool decode_configure_heater(const uint8_t* p, size_t n, ConfigureHeaterMsg& out) {
  MsgReader r(p, n);
  if (!start(r, MsgType::kConfigureHeater)) return false;
  out.heater = r.u8();
  const uint64_t period = r.var();
  out.samples_per_report = r.u16();
  out.adc_min = r.u16();
  out.adc_max = r.u16();
  const uint64_t timeout = r.var();
  out.max_duty = r.u16();
  if (period > 0xFFFFFFFFu || timeout > 0xFFFFFFFFu) return false;
  out.sample_period_ticks = static_cast<uint32_t>(period);
  out.confirm_timeout_ticks = static_cast<uint32_t>(timeout);
  return finish(r);
}

size_t encode_set_heater(const SetHeaterMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kSetHeater)).u8(m.heater).u16(m.duty);
  return done(w);
}
bool decode_set_heater(const uint8_t* p, size_t n, SetHeaterMsg& out) {
  MsgReader r(p, n);
  if (!start(r, MsgType::kSetHeater)) return false;
  out.heater = r.u8();
  out.duty = r.u16();
  return finish(r);
}

size_t encode_set_fan(const SetFanMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kSetFan)).u8(m.fan).u16(m.duty);
  return done(w);
}
bool decode_set_fan(const uint8_t* p, size_t n, SetFanMsg& out) {
  MsgReader r(p, n);
  if (!start(r, MsgType::kSetFan)) return false;
  out.fan = r.u8();
  out.duty = r.u16();
  return finish(r);
}

size_t encode_heater_report(const HeaterReportMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kHeaterReport))
      .u8(m.heater)
      .var(static_cast<uint64_t>(m.clock))
      .u16(m.adc)
      .u16(m.duty);
  return done(w);
}
bool decode_heater_report(const uint8_t* p, size_t n, HeaterReportMsg& out) {
  MsgReader r(p, n);
  if (!start(r, MsgType::kHeaterReport)) return false;
  out.heater = r.u8();
  out.clock = static_cast<int64_t>(r.var());
  out.adc = r.u16();
  out.duty = r.u16();
  return finish(r);
}

size_t encode_heater_fault(const HeaterFaultMsg& m, uint8_t* buf, size_t cap) {
  MsgWriter w(buf, cap);
  w.u8(static_cast<uint8_t>(MsgType::kHeaterFault))
      .u8(m.heater)
      .u8(static_cast<uint8_t>(m.reason))
      .var(static_cast<uint64_t>(m.clock))
      .u16(m.adc);
  return done(w);
}
bool decode_heater_fault(const uint8_t* p, size_t n, HeaterFaultMsg& out) {
  MsgReader r(p, n);
  if (!start(r, MsgType::kHeaterFault)) return false;
  out.heater = r.u8();
  out.reason = static_cast<HeaterFaultReason>(r.u8());
  out.clock = static_cast<int64_t>(r.var());
  out.adc = r.u16();
  return finish(r);
}

}  // namespace feedloop::protocol
