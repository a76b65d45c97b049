// The recorder thread's side: draining the rings, blocks, files, rotation (see recorder.hpp).
#include "recorder/recorder.hpp"

#include <chrono>
#include <cstring>  // memcpy
#include <filesystem>
#include <system_error>

#include "recorder/log_format.hpp"

namespace feedloop::recorder {
namespace {

int64_t unix_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::chrono::steady_clock::duration seconds(double s) {
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s));
}

template <class T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

}  // namespace

Result<std::unique_ptr<Recorder>> Recorder::create(RecorderOptions options) {
  if (options.joints.size() > static_cast<size_t>(kMaxJoints))
    return Error{"recorder: " + std::to_string(options.joints.size()) + " joints, at most " +
                     std::to_string(kMaxJoints) + " can be recorded", {}};
  if (options.config.enabled) {
    if (options.config.directory.empty()) return Error{"recorder: empty directory", {}};
    if (options.config.directory.find("${") != std::string::npos)
      return Error{"recorder: directory '" + options.config.directory + "' is not expanded", {}};
    std::error_code ec;
    std::filesystem::create_directories(options.config.directory, ec);
    if (ec)
      return Error{"recorder: cannot create directory '" + options.config.directory + "': " + ec.message(), {}};
    if (!(options.config.max_file_size_mb > 0.0)) return Error{"recorder: max_file_size_mb must be > 0", {}};
  }
  return std::unique_ptr<Recorder>(new Recorder(std::move(options)));
}

Recorder::Recorder(RecorderOptions options) : opt_(std::move(options)) {
  const bool on = opt_.config.enabled;
  enabled_.store(on);
  const int joints = static_cast<int>(opt_.joints.size());
  const size_t tiny = 256;  // disabled: the writers are no-ops, keep the rings small
  wait_for_room_.ctx = this;
  wait_for_room_.wake_consumer = [](void* ctx) {
    auto* self = static_cast<Recorder*>(ctx);
    self->drain_now_.store(true, std::memory_order_release);
    self->cv_.notify_one();
  };
  const size_t ring_bytes[kStreams] = {opt_.io_ring_bytes, opt_.planner_ring_bytes,
                                       opt_.servo_ring_bytes};
  for (size_t i = 0; i < static_cast<size_t>(kStreams); ++i)
    writers_[i] = std::make_unique<RecordWriter>(
        on ? ring_bytes[i] : tiny, opt_.max_gcode_text_bytes, joints, &enabled_, &wait_for_room_);
  header_.joints = opt_.joints;
  header_.config_yaml = opt_.config_yaml;
  frame_.reserve(opt_.block_bytes + 1024);
}

Recorder::~Recorder() {
  stop_thread();
  std::lock_guard<std::mutex> lk(mu_);
  drain_locked();
  (void)close_locked();
}

int64_t Recorder::host_now_ns() const { return opt_.clock ? opt_.clock->now_ns() : monotonic_.now_ns(); }

void Recorder::start_thread() {
  std::lock_guard<std::mutex> lk(mu_);
  if (thread_.joinable() || !enabled()) return;
  stop_ = false;
  thread_ = std::thread([this] { run(); });
  wait_for_room_.on.store(wait_for_room_wanted_, std::memory_order_release);
}

void Recorder::set_wait_for_room(bool on) {
  std::lock_guard<std::mutex> lk(mu_);
  wait_for_room_wanted_ = on;
  wait_for_room_.on.store(on && thread_.joinable(), std::memory_order_release);
}

void Recorder::stop_thread() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (!thread_.joinable()) return;
    stop_ = true;
    // No writer waits for a consumer that is stopping.
    wait_for_room_.on.store(false, std::memory_order_release);
  }
  cv_.notify_all();
  thread_.join();
}

void Recorder::run() {
  std::unique_lock<std::mutex> lk(mu_);
  while (!stop_) {
    (void)tick_locked(std::chrono::steady_clock::now(), false, false);  // problems land in stats_.last_error
    cv_.wait_for(lk, seconds(opt_.drain_period_s),
                 [this] { return stop_ || drain_now_.exchange(false, std::memory_order_acq_rel); });
  }
}

Status Recorder::start_print(std::string_view name) {
  if (!enabled()) return Status::Ok();
  std::lock_guard<std::mutex> lk(mu_);
  drain_locked();
  Status st = close_locked();
  print_name_ = std::string(name);
  int64_t stamp = unix_now_ns() / 1'000'000;
  if (stamp <= last_stamp_ms_) stamp = last_stamp_ms_ + 1;  // names sort in creation order
  last_stamp_ms_ = print_stamp_ms_ = stamp;
  Status opened = open_locked(0);
  if (!opened) return opened;
  return st;
}

Status Recorder::end_print() {
  if (!enabled()) return Status::Ok();
  std::lock_guard<std::mutex> lk(mu_);
  drain_locked();
  return close_locked();
}

Status Recorder::poll() {
  std::lock_guard<std::mutex> lk(mu_);
  return tick_locked(std::chrono::steady_clock::now(), false, false);
}

Status Recorder::flush() {
  std::lock_guard<std::mutex> lk(mu_);
  return tick_locked(std::chrono::steady_clock::now(), true, true);
}

RecorderStats Recorder::stats() const {
  std::lock_guard<std::mutex> lk(mu_);
  RecorderStats s = stats_;
  for (int i = 0; i < kStreams; ++i) {
    s.dropped[static_cast<size_t>(i)] = writers_[static_cast<size_t>(i)]->dropped();
    s.rejected += writers_[static_cast<size_t>(i)]->rejected();
    s.waited += writers_[static_cast<size_t>(i)]->waited();
  }
  s.current_path = file_.is_open() ? file_.path() : std::string();
  return s;
}

Status Recorder::tick_locked(SteadyTime now, bool force_write, bool force_sync) {
  drain_locked();
  Status st;
  if (force_write || now - last_write_ >= seconds(opt_.write_period_s)) st = write_block_locked(now);
  if (file_.is_open() && unsynced_bytes_ > 0 && (force_sync || now - last_sync_ >= seconds(opt_.sync_period_s))) {
    Status s = file_.sync();
    last_sync_ = now;
    unsynced_bytes_ = 0;
    ++stats_.syncs;
    if (!s) {
      stats_.last_error = s.error().to_string();
      st = s;
    }
  }
  return st;
}

void Recorder::begin_block_locked() {
  if (enc_.records() == 0) enc_.time_sync(TimeSyncRecord{host_now_ns(), unix_now_ns()});
}

void Recorder::drain_locked() {
  const bool keep = file_.is_open();
  for (int si = 0; si < kStreams; ++si) {
    RecordWriter& w = *writers_[static_cast<size_t>(si)];
    w.ring().drain([&](uint8_t type, const uint8_t* p, size_t n) {
      if (!keep) {
        ++stats_.records_discarded;
        return;
      }
      begin_block_locked();
      switch (static_cast<RecordType>(type)) {
        case RecordType::gcode_line: {
          const auto h = load<GcodeLineHead>(p);
          enc_.gcode_line(h.time_ns, static_cast<GcodeSource>(h.source), h.original_length,
                          std::string_view(reinterpret_cast<const char*>(p + sizeof h), n - sizeof h));
          break;
        }
        case RecordType::move: enc_.move(load<MoveRecord>(p)); break;
        case RecordType::segment: enc_.segment(load<SegmentRecord>(p)); break;
        case RecordType::step_run: enc_.step_run(load<StepRunRecord>(p)); break;
        case RecordType::encoder: enc_.encoder(load<EncoderRecord>(p)); break;
        case RecordType::origin: enc_.origin(load<OriginRecord>(p)); break;
        case RecordType::loop_report: enc_.loop_report(load<LoopReportRecord>(p)); break;
        case RecordType::event: {
          const auto h = load<EventHead>(p);
          enc_.event(static_cast<EventKind>(h.kind), h.time_ns, h.joint, h.value,
                     std::string_view(reinterpret_cast<const char*>(p + sizeof h), n - sizeof h));
          break;
        }
        default: break;  // the writers push nothing else
      }
      if (enc_.body().size() >= opt_.block_bytes) (void)write_block_locked(std::chrono::steady_clock::now());
    });
    const uint64_t dropped = w.dropped();
    if (dropped != logged_drops_[static_cast<size_t>(si)] && keep) {
      begin_block_locked();
      enc_.drops(DropRecord{static_cast<Stream>(si), dropped - drops_base_[static_cast<size_t>(si)]});
      logged_drops_[static_cast<size_t>(si)] = dropped;
    }
  }
}

Status Recorder::write_block_locked(SteadyTime now) {
  last_write_ = now;
  if (enc_.records() == 0 || !file_.is_open()) {
    enc_.reset();
    return Status::Ok();
  }
  frame_.clear();
  enc_.frame(frame_);
  const size_t records = enc_.records();
  enc_.reset();
  const auto max_bytes = static_cast<uint64_t>(opt_.config.max_file_size_mb * 1024.0 * 1024.0);
  if (file_blocks_ > 0 && file_.size() + frame_.size() > max_bytes) {
    Status st = close_locked();
    if (st) st = open_locked(part_ + 1);
    if (!st) return st;
  }
  Status st = file_.append(frame_.data(), frame_.size());
  if (!st) {
    stats_.last_error = st.error().to_string();
    file_.close();
    return st;
  }
  ++file_blocks_;
  ++stats_.blocks_written;
  stats_.records_written += records;
  stats_.bytes_written += frame_.size();
  unsynced_bytes_ += frame_.size();
  return Status::Ok();
}

Status Recorder::open_locked(uint32_t part) {
  part_ = part;
  file_blocks_ = 0;
  header_.print_name = print_name_;
  header_.part = part;
  header_.start_unix_ns = unix_now_ns();
  header_.start_host_ns = host_now_ns();
  const std::string path =
      (std::filesystem::path(opt_.config.directory) / log_file_name(print_stamp_ms_, print_name_, part)).string();
  Status st = file_.create(path);
  if (st) {
    std::vector<uint8_t> head;
    encode_header(header_, head);
    st = file_.append(head.data(), head.size());
    if (st) st = file_.sync();  // the header is on disk before any block
  }
  if (!st) {
    stats_.last_error = st.error().to_string();
    file_.close();
    return st;
  }
  ++stats_.files_opened;
  stats_.bytes_written += file_.size();
  last_sync_ = std::chrono::steady_clock::now();
  unsynced_bytes_ = 0;
  for (size_t si = 0; si < kStreams; ++si) logged_drops_[si] = drops_base_[si] = writers_[si]->dropped();
  stats_.files_deleted += static_cast<uint64_t>(prune_logs(opt_.config.directory, opt_.config.keep_files, path));
  return Status::Ok();
}

Status Recorder::close_locked() {
  if (!file_.is_open()) return Status::Ok();
  Status st = write_block_locked(std::chrono::steady_clock::now());
  Status s = file_.sync();
  ++stats_.syncs;
  unsynced_bytes_ = 0;
  file_.close();
  if (!s) stats_.last_error = s.error().to_string();
  return st ? s : st;
}

}  // namespace feedloop::recorder
