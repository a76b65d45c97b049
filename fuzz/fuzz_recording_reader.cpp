// libFuzzer target for the flight-recorder reader: the input is a log file (docs/recorder.md,
// "File format") behind one mode byte. Mode bit 0 set: the harness first rewrites the header's
// and every block's CRC-32 to match their bytes, so mutations reach the header and record
// decoders instead of stopping at a CRC check. The file goes through LogReader (every record),
// summarize_log + format_summary (`feedloop log info`) and read_step_streams (what a replay
// compares).
// Besides crashes, sanitizer reports and escaping exceptions, these trap: a record outside the
// file; a damaged file without a message; summarize_log and LogReader disagreeing on the number
// of records or on whether the file is damaged; a step stream of a joint the header lacks.
#include <unistd.h>  // getpid

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "fuzz/fuzz_input.hpp"
#include "recorder/block_codec.hpp"
#include "recorder/log_format.hpp"
#include "recorder/log_reader.hpp"
#include "recorder/log_summary.hpp"
#include "recorder/step_stream.hpp"

namespace {

using namespace feedloop;
using fuzz::check;

// Reads a LEB128 varint at data[pos..size); false when it runs off the end.
bool read_varint(const std::vector<uint8_t>& d, size_t& pos, uint64_t& v) {
  v = 0;
  for (int shift = 0; shift < 64 && pos < d.size(); shift += 7) {
    const uint8_t b = d[pos++];
    v |= static_cast<uint64_t>(b & 0x7F) << shift;
    if (!(b & 0x80)) return true;
  }
  return false;
}

void put_crc(std::vector<uint8_t>& d, size_t at, size_t body, size_t len) {
  const uint32_t crc = recorder::crc32(d.data() + body, len);
  for (int i = 0; i < 4; ++i) d[at + i] = static_cast<uint8_t>(crc >> (8 * i));
}

// Makes the header's and each block's CRC match their bytes, as far as the layout goes.
void fix_crcs(std::vector<uint8_t>& d) {
  if (d.size() < recorder::kFixedHeaderBytes) return;
  const size_t n = d[12] | (d[13] << 8) | (d[14] << 16) | (static_cast<size_t>(d[15]) << 24);
  size_t pos = recorder::kFixedHeaderBytes + n;
  if (pos + 4 > d.size()) return;
  put_crc(d, pos, recorder::kFixedHeaderBytes, n);
  pos += 4;
  while (pos < d.size() && d[pos] == recorder::kBlockMarker) {
    ++pos;
    uint64_t len = 0, count = 0;
    if (!read_varint(d, pos, len) || !read_varint(d, pos, count)) return;
    const size_t crc_at = pos;
    if (len > d.size() || crc_at + 4 + len > d.size()) return;
    put_crc(d, crc_at, crc_at + 4, len);
    pos = crc_at + 4 + len;
  }
}

// The file the input is written to (on tmpfs when there is one).
const std::string& scratch_path() {
  static const std::string path = [] {
    std::error_code ec;
    std::filesystem::path dir = "/dev/shm";
    if (!std::filesystem::is_directory(dir, ec)) dir = std::filesystem::temp_directory_path();
    return (dir / ("fuzz_recording_reader." + std::to_string(::getpid()) + ".flrec")).string();
  }();
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  std::vector<uint8_t> file(data + 1, data + size);
  if (data[0] & 1) fix_crcs(file);
  const std::string& path = scratch_path();
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    check(f != nullptr);
    check(std::fwrite(file.data(), 1, file.size(), f) == file.size() || file.empty());
    std::fclose(f);
  }

  auto reader = recorder::LogReader::open(path);
  auto summary = recorder::summarize_log(path);
  check(reader.ok() == summary.ok());
  if (!reader) {
    check(!reader.error().message.empty());
    return 0;
  }
  uint64_t records = 0;
  while (const recorder::DecodedRecord* r = reader->next()) {
    check(r->offset < file.size() && r->size >= 1 && r->offset + r->size <= file.size());
    ++records;
  }
  if (reader->error()) check(!reader->error()->message.empty());
  check(summary->records == records);
  check(summary->damage.has_value() == reader->error().has_value());
  check(!recorder::format_summary(*summary).empty());

  auto streams = recorder::read_step_streams({path});
  if (streams) check(streams->runs.size() == streams->joints.size());
  return 0;
}
