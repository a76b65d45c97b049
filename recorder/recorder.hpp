// The flight recorder: three real-time writers (I/O, planner, servo; record_writer.hpp) and the
// recorder thread that drains their rings into a compact binary log (docs/recorder.md).
//
//   auto rec = Recorder::create(options);     // allocates the rings, creates the directory
//   rec->start_thread();                       // or call poll() yourself (batch mode, tests)
//   rec->start_print("benchy");                // opens <stamp>_benchy_p000.flrec
//   rec->writer(Stream::servo).step_run(...);  // from the servo thread; never blocks
//   rec->end_print();                          // drains, writes, fdatasyncs, closes
//
// Durability: blocks are written (write(2)) at least every write_period_s and fdatasync'ed at
// least every sync_period_s, so a crash of the process loses at most write_period_s and a power
// cut at most write_period_s + sync_period_s (< 1 s with the defaults). Rotation: a print's file
// is continued in part p+1 when the next block would take it beyond max_file_size_mb; the oldest
// logs of the directory beyond keep_files are deleted. Records drained while no print is open are
// discarded (counted).
#pragma once

#include <array>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "config/machine_config.hpp"
#include "core/clock.hpp"
#include "core/result.hpp"
#include "recorder/block_codec.hpp"
#include "recorder/log_files.hpp"
#include "recorder/record_writer.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

struct RecorderOptions {
  config::RecorderConfig config;  // `directory` must already be expanded (no ${...})
  std::string config_yaml;        // written into every file header
  std::vector<JointInfo> joints;  // in the engine's joint order (at most kMaxJoints)
  size_t io_ring_bytes = 1 << 20;
  size_t planner_ring_bytes = 4 << 20;
  size_t servo_ring_bytes = 8 << 20;
  size_t max_gcode_text_bytes = 4096;
  double drain_period_s = 0.02;   // the recorder thread wakes this often
  double write_period_s = 0.1;    // a block reaches the file at least this often
  double sync_period_s = 0.5;     // fdatasync at least this often
  size_t block_bytes = 64 << 10;  // a block is written once its body reaches this size
  const Clock* clock = nullptr;   // host time of TimeSync records; nullptr: CLOCK_MONOTONIC
};

struct RecorderStats {
  uint64_t records_written = 0;
  uint64_t records_discarded = 0;  // drained while no print was open
  uint64_t blocks_written = 0;
  uint64_t bytes_written = 0;      // all files, headers included
  uint64_t files_opened = 0;
  uint64_t files_deleted = 0;
  uint64_t syncs = 0;
  std::array<uint64_t, kStreams> dropped{};  // ring full
  uint64_t rejected = 0;                     // bad joint index
  uint64_t waited = 0;                       // pushes that waited for room (virtual time)
  std::string current_path;                  // empty: no print open
  std::string last_error;                    // last I/O problem (the print goes on unrecorded)
};

class Recorder {
 public:
  static Result<std::unique_ptr<Recorder>> create(RecorderOptions options);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  bool enabled() const { return enabled_.load(std::memory_order_relaxed); }
  RecordWriter& writer(Stream s) { return *writers_[static_cast<size_t>(s)]; }
  const LogHeader& header_template() const { return header_; }

  // The recorder thread (drains every drain_period_s). Without it, call poll().
  void start_thread();
  void stop_thread();
  // Virtual time: a writer whose ring is full wakes the recorder thread and waits for room
  // instead of dropping the record (record_writer.hpp). Takes effect only while the recorder
  // thread runs (stop_thread() switches it off, so no writer waits for a consumer that is gone).
  void set_wait_for_room(bool on);

  // Opens a new log for a print (ending the current one first). Records already in the rings go
  // to the previous file (or are discarded when none was open).
  Status start_print(std::string_view name);
  Status end_print();
  // One round of the recorder thread's work: drain, write a block when due, sync when due.
  Status poll();
  // Drains, writes and fdatasyncs now.
  Status flush();

  RecorderStats stats() const;

 private:
  explicit Recorder(RecorderOptions options);
  using SteadyTime = std::chrono::steady_clock::time_point;

  void run();
  Status tick_locked(SteadyTime now, bool force_write, bool force_sync);
  void drain_locked();
  Status write_block_locked(SteadyTime now);
  Status open_locked(uint32_t part);
  Status close_locked();
  void begin_block_locked();
  int64_t host_now_ns() const;

  RecorderOptions opt_;
  LogHeader header_;  // joints and config; name/part/times filled per file
  std::atomic<bool> enabled_{false};
  WaitForRoom wait_for_room_;           // shared by the writers
  bool wait_for_room_wanted_ = false;   // set_wait_for_room(); applied while the thread runs
  std::atomic<bool> drain_now_{false};  // a waiting writer asks for a drain
  std::array<std::unique_ptr<RecordWriter>, kStreams> writers_;
  MonotonicClock monotonic_;

  mutable std::mutex mu_;  // protects everything below
  std::condition_variable cv_;
  std::thread thread_;
  bool stop_ = false;
  LogFile file_;
  std::string print_name_;
  int64_t print_stamp_ms_ = 0;
  int64_t last_stamp_ms_ = 0;
  uint32_t part_ = 0;
  uint64_t file_blocks_ = 0;
  uint64_t unsynced_bytes_ = 0;
  BlockEncoder enc_;
  std::vector<uint8_t> frame_;
  std::array<uint64_t, kStreams> logged_drops_{};  // writer drop counters last written
  std::array<uint64_t, kStreams> drops_base_{};    // ... when the current file was opened
  SteadyTime last_write_{}, last_sync_{};
  RecorderStats stats_;
};

}  // namespace feedloop::recorder
