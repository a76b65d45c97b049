// Records <-> bytes of one block of a log (docs/recorder.md, "Blocks" and "Records"). Each record
// is a tag byte (type, joint, direction) and fields delta-coded against a prediction made from the
// previous record of the same kind (and joint) in the same block; the prediction state starts
// from zero in every block, so a block decodes on its own. Used by the recorder thread (encode)
// and the reader (decode); never on the real-time side.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include "core/result.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

// Prediction state shared by the encoder and the decoder (both update it identically).
struct CodecState {
  int64_t host_ns = 0;
  int64_t unix_ns = 0;
  // moves
  uint64_t move_index = 0;
  int64_t move_line = 0;
  double move_start_s = 0.0, move_duration_s = 0.0;
  std::array<double, 4> move_end_mm{};
  double move_v_exit = 0.0, move_v_cruise = 0.0, move_accel = 0.0;
  bool have_move = false;
  // per joint
  struct Joint {
    double seg_t0 = 0.0, seg_dur = 0.0, c0 = 0.0, c1 = 0.0, c2 = 0.0, c3 = 0.0;
    int64_t step_clock = 0;     // predicted start of the next run (end of the previous)
    int64_t step_interval = 0;  // predicted first interval of the next run
    int64_t step_add = 0;
    int64_t enc_clock = 0, enc_dt = 0, enc_counts = 0;
    int64_t lr_clock = 0, lr_dt = 0, lr_y = 0, lr_u = 0;  // loop reports
    uint64_t lr_ticks = 0, lr_misses = 0, lr_rejects = 0, lr_slips = 0;
  };
  std::array<Joint, kMaxJoints> joints{};
};

class BlockEncoder {
 public:
  BlockEncoder() { body_.reserve(1 << 16); }
  void reset() {
    body_.clear();
    state_ = CodecState{};
    records_ = 0;
  }
  void gcode_line(int64_t time_ns, GcodeSource source, uint32_t original_length, std::string_view text);
  void move(const MoveRecord& m);
  void segment(const SegmentRecord& s);
  void step_run(const StepRunRecord& r);
  void encoder(const EncoderRecord& e);
  void origin(const OriginRecord& o);
  void loop_report(const LoopReportRecord& r);
  void event(EventKind kind, int64_t time_ns, int32_t joint, double value, std::string_view text);
  void drops(const DropRecord& d);
  void time_sync(const TimeSyncRecord& t);
  void any(const Record& r);  // dispatches on the variant (tests, tools)

  size_t records() const { return records_; }
  const std::vector<uint8_t>& body() const { return body_; }
  // Appends the framed block (marker, length, count, CRC, body) to `out`.
  void frame(std::vector<uint8_t>& out) const;

 private:
  std::vector<uint8_t> body_;
  CodecState state_;
  size_t records_ = 0;
};

inline constexpr uint8_t kBlockMarker = 0xB7;
inline constexpr uint64_t kMaxBlockBytes = 64ull << 20;  // larger length fields are corruption
inline constexpr size_t kMaxTextBytes = 1 << 20;

// One decoded record and where its encoding starts in the file.
struct DecodedRecord {
  Record record;
  uint64_t offset = 0;  // byte offset of the tag byte in the file
  uint32_t size = 0;    // encoded size in bytes
};

// Decodes a CRC-checked block body. `body_offset` is the body's byte offset in the file (for error
// messages). Appends to `out` every record before the first malformed one; Error on malformation.
Status decode_block(const uint8_t* body, size_t size, uint64_t body_offset, uint64_t expected_records,
                    std::vector<DecodedRecord>& out);

uint32_t crc32(const uint8_t* data, size_t size);

}  // namespace feedloop::recorder
