// Encoding and decoding of the records of one block (docs/recorder.md, "Records").
#include "recorder/block_codec.hpp"

#include <boost/crc.hpp>  // boost::crc_32_type (CRC-32/ISO-HDLC, as zlib)

#include <string>

#include "recorder/varint.hpp"

namespace feedloop::recorder {
namespace {

// Wrapping integer arithmetic: garbage in a damaged file must not be undefined behaviour.
int64_t wadd(int64_t a, int64_t b) { return static_cast<int64_t>(static_cast<uint64_t>(a) + static_cast<uint64_t>(b)); }
int64_t wsub(int64_t a, int64_t b) { return static_cast<int64_t>(static_cast<uint64_t>(a) - static_cast<uint64_t>(b)); }
int64_t wmul(int64_t a, int64_t b) { return static_cast<int64_t>(static_cast<uint64_t>(a) * static_cast<uint64_t>(b)); }

uint8_t tag(RecordType t, int joint = 0, bool negative = false) {
  return static_cast<uint8_t>(static_cast<uint8_t>(t) | ((joint & 7) << 4) | (negative ? 0x80 : 0));
}

// Step run update of the prediction: the next run starts where this one ended, with the interval
// that continues this one's law (step_run.hpp: interval grows by `add` after each step).
void after_run(CodecState::Joint& j, int64_t start_clock, const stepgen::StepRun& r) {
  const int64_t k = r.count;
  j.step_clock = wadd(wadd(start_clock, wmul(k, r.interval_ticks)), wmul(r.add_ticks, wmul(k, k - 1) / 2));
  j.step_interval = wadd(r.interval_ticks, wmul(r.add_ticks, k));
  j.step_add = r.add_ticks;
}

}  // namespace

uint32_t crc32(const uint8_t* data, size_t size) {
  boost::crc_32_type crc;
  crc.process_bytes(data, size);
  return crc.checksum();
}

void BlockEncoder::gcode_line(int64_t time_ns, GcodeSource source, uint32_t original_length,
                              std::string_view text) {
  ByteWriter w(body_);
  w.u8(tag(RecordType::gcode_line));
  w.u8(static_cast<uint8_t>(source));
  w.svarint(wsub(time_ns, state_.host_ns));
  state_.host_ns = time_ns;
  w.varint(original_length >= text.size() ? original_length - text.size() : 0);
  w.str(text);
  ++records_;
}

void BlockEncoder::move(const MoveRecord& m) {
  CodecState& s = state_;
  ByteWriter w(body_);
  w.u8(tag(RecordType::move));
  const uint64_t predicted_index = s.have_move ? s.move_index + 1 : 0;
  w.svarint(static_cast<int64_t>(m.index - predicted_index));
  w.svarint(static_cast<int64_t>(m.line) - s.move_line);
  w.f64x(s.move_start_s + s.move_duration_s, m.start_time_s);  // a move starts where the last ended
  w.f64x(s.move_duration_s, m.duration_s);
  for (int i = 0; i < 4; ++i) w.f64x(s.move_end_mm[i], m.start_mm[i]);
  for (int i = 0; i < 4; ++i) w.f64x(m.start_mm[i], m.end_mm[i]);  // axes that do not move: 1 byte
  w.f64x(s.move_v_exit, m.v_entry_mm_s);
  w.f64x(s.move_v_cruise, m.v_cruise_mm_s);
  w.f64x(s.move_v_exit, m.v_exit_mm_s);
  w.f64x(s.move_accel, m.accel_mm_s2);
  s.have_move = true;
  s.move_index = m.index;
  s.move_line = m.line;
  s.move_start_s = m.start_time_s;
  s.move_duration_s = m.duration_s;
  s.move_end_mm = m.end_mm;
  s.move_v_exit = m.v_exit_mm_s;
  s.move_v_cruise = m.v_cruise_mm_s;
  s.move_accel = m.accel_mm_s2;
  ++records_;
}

void BlockEncoder::segment(const SegmentRecord& r) {
  CodecState::Joint& j = state_.joints[static_cast<size_t>(r.joint & 7)];
  const JointSegment& g = r.segment;
  ByteWriter w(body_);
  w.u8(tag(RecordType::segment, r.joint));
  w.f64x(j.seg_t0 + j.seg_dur, g.t0_s);
  w.f64x(j.seg_dur, g.duration_s);
  w.f64x(j.c0, g.c0_mm);
  w.f64x(j.c1, g.c1_mm_s);
  w.f64x(j.c2, g.c2_mm_s2);
  w.f64x(j.c3, g.c3_mm_s3);
  j.seg_t0 = g.t0_s;
  j.seg_dur = g.duration_s;
  j.c0 = g.c0_mm;
  j.c1 = g.c1_mm_s;
  j.c2 = g.c2_mm_s2;
  j.c3 = g.c3_mm_s3;
  ++records_;
}

void BlockEncoder::step_run(const StepRunRecord& r) {
  CodecState::Joint& j = state_.joints[static_cast<size_t>(r.joint & 7)];
  ByteWriter w(body_);
  w.u8(tag(RecordType::step_run, r.joint, r.run.direction < 0));
  w.svarint(wsub(r.start_clock, j.step_clock));
  w.svarint(wsub(r.run.interval_ticks, j.step_interval));
  w.svarint(wsub(r.run.add_ticks, j.step_add));
  w.varint(r.run.count);
  after_run(j, r.start_clock, r.run);
  ++records_;
}

void BlockEncoder::encoder(const EncoderRecord& e) {
  CodecState::Joint& j = state_.joints[static_cast<size_t>(e.joint & 7)];
  ByteWriter w(body_);
  w.u8(tag(RecordType::encoder, e.joint));
  const int64_t dt = wsub(e.clock, j.enc_clock);
  w.svarint(wsub(dt, j.enc_dt));  // delta of delta: a steady sample rate costs 1 byte
  w.svarint(wsub(e.counts, j.enc_counts));
  j.enc_dt = dt;
  j.enc_clock = e.clock;
  j.enc_counts = e.counts;
  ++records_;
}

void BlockEncoder::origin(const OriginRecord& o) {
  CodecState::Joint& j = state_.joints[static_cast<size_t>(o.joint & 7)];
  ByteWriter w(body_);
  w.u8(tag(RecordType::origin, o.joint));
  w.svarint(wsub(o.clock, j.step_clock));
  w.svarint(o.position_steps);
  j.step_clock = o.clock;
  ++records_;
}

void BlockEncoder::loop_report(const LoopReportRecord& r) {
  CodecState::Joint& j = state_.joints[static_cast<size_t>(r.joint & 7)];
  ByteWriter w(body_);
  w.u8(tag(RecordType::loop_report, r.joint));
  const int64_t dt = wsub(r.clock, j.lr_clock);
  w.svarint(wsub(dt, j.lr_dt));  // delta of delta: reports every N ticks cost 1 byte
  w.u8(r.state);
  w.svarint(r.e_nm);
  w.svarint(wsub(r.y_nm, j.lr_y));
  w.svarint(wsub(r.correction_nm, j.lr_u));
  w.varint(r.tick_cost);
  // Counters: their increase since the joint's previous report (wrapping: a reconfigured loop
  // starts again from 0).
  w.varint(r.ticks - j.lr_ticks);
  w.varint(r.deadline_misses - j.lr_misses);
  w.varint(r.encoder_rejects - j.lr_rejects);
  w.varint(r.slips - j.lr_slips);
  j.lr_dt = dt;
  j.lr_clock = r.clock;
  j.lr_y = r.y_nm;
  j.lr_u = r.correction_nm;
  j.lr_ticks = r.ticks;
  j.lr_misses = r.deadline_misses;
  j.lr_rejects = r.encoder_rejects;
  j.lr_slips = r.slips;
  ++records_;
}

void BlockEncoder::event(EventKind kind, int64_t time_ns, int32_t joint, double value, std::string_view text) {
  ByteWriter w(body_);
  w.u8(tag(RecordType::event));
  w.u8(static_cast<uint8_t>(kind));
  w.svarint(wsub(time_ns, state_.host_ns));
  state_.host_ns = time_ns;
  w.svarint(joint);
  w.f64x(0.0, value);
  w.str(text);
  ++records_;
}

void BlockEncoder::drops(const DropRecord& d) {
  ByteWriter w(body_);
  w.u8(tag(RecordType::drops));
  w.u8(static_cast<uint8_t>(d.stream));
  w.varint(d.dropped_total);
  ++records_;
}

void BlockEncoder::time_sync(const TimeSyncRecord& t) {
  ByteWriter w(body_);
  w.u8(tag(RecordType::time_sync));
  w.svarint(wsub(t.host_ns, state_.host_ns));
  w.svarint(wsub(t.unix_ns, state_.unix_ns));
  state_.host_ns = t.host_ns;
  state_.unix_ns = t.unix_ns;
  ++records_;
}

void BlockEncoder::any(const Record& r) {
  std::visit(
      [this](const auto& v) {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, GcodeLineRecord>) gcode_line(v.time_ns, v.source, v.original_length, v.text);
        else if constexpr (std::is_same_v<T, MoveRecord>) move(v);
        else if constexpr (std::is_same_v<T, SegmentRecord>) segment(v);
        else if constexpr (std::is_same_v<T, StepRunRecord>) step_run(v);
        else if constexpr (std::is_same_v<T, EncoderRecord>) encoder(v);
        else if constexpr (std::is_same_v<T, OriginRecord>) origin(v);
        else if constexpr (std::is_same_v<T, EventRecord>) event(v.kind, v.time_ns, v.joint, v.value, v.text);
        else if constexpr (std::is_same_v<T, DropRecord>) drops(v);
        else if constexpr (std::is_same_v<T, LoopReportRecord>) loop_report(v);
        else time_sync(v);
      },
      r);
}

void BlockEncoder::frame(std::vector<uint8_t>& out) const {
  ByteWriter w(out);
  w.u8(kBlockMarker);
  w.varint(body_.size());
  w.varint(records_);
  w.u32le(crc32(body_.data(), body_.size()));
  out.insert(out.end(), body_.begin(), body_.end());
}

Status decode_block(const uint8_t* body, size_t size, uint64_t body_offset, uint64_t expected_records,
                    std::vector<DecodedRecord>& out) {
  CodecState s;
  ByteReader r(body, size);
  uint64_t n = 0;
  while (!r.at_end()) {
    const uint64_t offset = body_offset + r.pos();
    const size_t start = r.pos();
    const uint8_t t = r.u8();
    const int joint = (t >> 4) & 7;
    const auto type = static_cast<RecordType>(t & 0x0F);
    Record rec;
    switch (type) {
      case RecordType::gcode_line: {
        GcodeLineRecord g;
        g.source = static_cast<GcodeSource>(r.u8());
        g.time_ns = wadd(s.host_ns, r.svarint());
        s.host_ns = g.time_ns;
        const uint64_t cut = r.varint();
        g.text = r.str(kMaxTextBytes);
        g.original_length = static_cast<uint32_t>(g.text.size() + cut);
        rec = std::move(g);
        break;
      }
      case RecordType::move: {
        MoveRecord m;
        m.index = static_cast<uint64_t>(r.svarint()) + (s.have_move ? s.move_index + 1 : 0);
        m.line = static_cast<int32_t>(wadd(s.move_line, r.svarint()));
        m.start_time_s = r.f64x(s.move_start_s + s.move_duration_s);
        m.duration_s = r.f64x(s.move_duration_s);
        for (int i = 0; i < 4; ++i) m.start_mm[i] = r.f64x(s.move_end_mm[i]);
        for (int i = 0; i < 4; ++i) m.end_mm[i] = r.f64x(m.start_mm[i]);
        m.v_entry_mm_s = r.f64x(s.move_v_exit);
        m.v_cruise_mm_s = r.f64x(s.move_v_cruise);
        m.v_exit_mm_s = r.f64x(s.move_v_exit);
        m.accel_mm_s2 = r.f64x(s.move_accel);
        s.have_move = true;
        s.move_index = m.index;
        s.move_line = m.line;
        s.move_start_s = m.start_time_s;
        s.move_duration_s = m.duration_s;
        s.move_end_mm = m.end_mm;
        s.move_v_exit = m.v_exit_mm_s;
        s.move_v_cruise = m.v_cruise_mm_s;
        s.move_accel = m.accel_mm_s2;
        rec = m;
        break;
      }
      case RecordType::segment: {
        CodecState::Joint& j = s.joints[static_cast<size_t>(joint)];
        SegmentRecord g;
        g.joint = joint;
        g.segment.t0_s = r.f64x(j.seg_t0 + j.seg_dur);
        g.segment.duration_s = r.f64x(j.seg_dur);
        g.segment.c0_mm = r.f64x(j.c0);
        g.segment.c1_mm_s = r.f64x(j.c1);
        g.segment.c2_mm_s2 = r.f64x(j.c2);
        g.segment.c3_mm_s3 = r.f64x(j.c3);
        j.seg_t0 = g.segment.t0_s;
        j.seg_dur = g.segment.duration_s;
        j.c0 = g.segment.c0_mm;
        j.c1 = g.segment.c1_mm_s;
        j.c2 = g.segment.c2_mm_s2;
        j.c3 = g.segment.c3_mm_s3;
        rec = g;
        break;
      }
      case RecordType::step_run: {
        CodecState::Joint& j = s.joints[static_cast<size_t>(joint)];
        StepRunRecord g;
        g.joint = joint;
        g.start_clock = wadd(j.step_clock, r.svarint());
        g.run.interval_ticks = wadd(j.step_interval, r.svarint());
        g.run.add_ticks = static_cast<int32_t>(wadd(j.step_add, r.svarint()));
        g.run.count = static_cast<uint32_t>(r.varint());
        g.run.direction = (t & 0x80) ? -1 : 1;
        after_run(j, g.start_clock, g.run);
        rec = g;
        break;
      }
      case RecordType::encoder: {
        CodecState::Joint& j = s.joints[static_cast<size_t>(joint)];
        EncoderRecord e;
        e.joint = joint;
        const int64_t dt = wadd(j.enc_dt, r.svarint());
        e.clock = wadd(j.enc_clock, dt);
        e.counts = wadd(j.enc_counts, r.svarint());
        j.enc_dt = dt;
        j.enc_clock = e.clock;
        j.enc_counts = e.counts;
        rec = e;
        break;
      }
      case RecordType::origin: {
        CodecState::Joint& j = s.joints[static_cast<size_t>(joint)];
        OriginRecord o;
        o.joint = joint;
        o.clock = wadd(j.step_clock, r.svarint());
        o.position_steps = r.svarint();
        j.step_clock = o.clock;
        rec = o;
        break;
      }
      case RecordType::loop_report: {
        CodecState::Joint& j = s.joints[static_cast<size_t>(joint)];
        LoopReportRecord l;
        l.joint = joint;
        const int64_t dt = wadd(j.lr_dt, r.svarint());
        l.clock = wadd(j.lr_clock, dt);
        l.state = r.u8();
        l.e_nm = r.svarint();
        l.y_nm = wadd(j.lr_y, r.svarint());
        l.correction_nm = wadd(j.lr_u, r.svarint());
        const uint64_t cost = r.varint();
        l.tick_cost = cost > UINT32_MAX ? UINT32_MAX : static_cast<uint32_t>(cost);
        l.ticks = j.lr_ticks + r.varint();
        l.deadline_misses = j.lr_misses + r.varint();
        l.encoder_rejects = j.lr_rejects + r.varint();
        l.slips = j.lr_slips + r.varint();
        j.lr_dt = dt;
        j.lr_clock = l.clock;
        j.lr_y = l.y_nm;
        j.lr_u = l.correction_nm;
        j.lr_ticks = l.ticks;
        j.lr_misses = l.deadline_misses;
        j.lr_rejects = l.encoder_rejects;
        j.lr_slips = l.slips;
        if (l.state > 3)
          return Error{"unknown device loop state " + std::to_string(l.state) + " at byte offset " + std::to_string(offset), {}};
        rec = l;
        break;
      }
      case RecordType::event: {
        EventRecord e;
        const uint8_t kind = r.u8();
        e.kind = static_cast<EventKind>(kind);
        e.time_ns = wadd(s.host_ns, r.svarint());
        s.host_ns = e.time_ns;
        e.joint = static_cast<int32_t>(r.svarint());
        e.value = r.f64x(0.0);
        e.text = r.str(kMaxTextBytes);
        if (kind >= kEventKinds)
          return Error{"unknown event kind " + std::to_string(kind) + " at byte offset " + std::to_string(offset), {}};
        rec = std::move(e);
        break;
      }
      case RecordType::drops: {
        DropRecord d;
        const uint8_t stream = r.u8();
        d.stream = static_cast<Stream>(stream);
        d.dropped_total = r.varint();
        if (stream >= kStreams)
          return Error{"unknown stream " + std::to_string(stream) + " at byte offset " + std::to_string(offset), {}};
        rec = d;
        break;
      }
      case RecordType::time_sync: {
        TimeSyncRecord ts;
        ts.host_ns = wadd(s.host_ns, r.svarint());
        ts.unix_ns = wadd(s.unix_ns, r.svarint());
        s.host_ns = ts.host_ns;
        s.unix_ns = ts.unix_ns;
        rec = ts;
        break;
      }
      default:
        return Error{"unknown record type " + std::to_string(t & 0x0F) + " at byte offset " + std::to_string(offset), {}};
    }
    if (r.failed())
      return Error{std::string("malformed ") + record_type_name(type) + " record at byte offset " + std::to_string(offset), {}};
    out.push_back(DecodedRecord{std::move(rec), offset, static_cast<uint32_t>(r.pos() - start)});
    ++n;
  }
  if (n != expected_records)
    return Error{"block at byte offset " + std::to_string(body_offset) + " holds " + std::to_string(n) +
                     " records, its header says " + std::to_string(expected_records), {}};
  return Status::Ok();
}

}  // namespace feedloop::recorder
