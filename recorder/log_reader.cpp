// LogReader: file header, then block after block (see log_reader.hpp, docs/recorder.md).
#include "recorder/log_reader.hpp"

#include <cerrno>
#include <cstring>  // strerror

#include "recorder/log_format.hpp"

namespace feedloop::recorder {

Result<LogReader> LogReader::open(const std::string& path) {
  LogReader r;
  r.path_ = path;
  r.file_.reset(std::fopen(path.c_str(), "rb"));
  if (!r.file_) return Error{std::string("cannot open log: ") + std::strerror(errno), {path, 0, 0}};
  std::FILE* f = r.file_.get();
  if (std::fseek(f, 0, SEEK_END) == 0) {
    const long end = std::ftell(f);
    r.file_size_ = end > 0 ? static_cast<uint64_t>(end) : 0;
  }
  std::fseek(f, 0, SEEK_SET);
  uint8_t fixed[kFixedHeaderBytes];
  const size_t got = std::fread(fixed, 1, sizeof fixed, f);
  // A read error (a directory, EIO) is not a short file: say which.
  if (std::ferror(f))
    return Error{std::string("cannot read log: ") + std::strerror(errno), {path, 0, 0}};
  auto body_len = parse_fixed_header(fixed, got);
  if (!body_len) return Error{body_len.error().message, {path, 0, 0}};
  std::vector<uint8_t> body(static_cast<size_t>(*body_len) + 4);
  const size_t got_body = std::fread(body.data(), 1, body.size(), f);
  if (std::ferror(f))
    return Error{std::string("cannot read log: ") + std::strerror(errno), {path, 0, 0}};
  if (got_body < body.size())
    return Error{"truncated file header at byte offset " + std::to_string(kFixedHeaderBytes + got_body) +
                     " (the header needs " + std::to_string(kFixedHeaderBytes + body.size()) + " bytes)",
                 {path, 0, 0}};
  const uint16_t version = static_cast<uint16_t>(fixed[8] | (fixed[9] << 8));
  auto header = parse_header_body(body.data(), body.size(), version);
  if (!header) return Error{header.error().message, {path, 0, 0}};
  r.header_ = std::move(*header);
  r.offset_ = kFixedHeaderBytes + body.size();
  return r;
}

void LogReader::fail(const std::string& message) {
  error_ = Error{message, {path_, 0, 0}};
  done_ = true;
}

const DecodedRecord* LogReader::next() {
  while (next_ >= records_.size()) {
    if (done_ || !read_block()) return nullptr;
  }
  return &records_[next_++];
}

// Reads and decodes the block at offset_; false at the end of the file or on damage.
bool LogReader::read_block() {
  records_.clear();
  next_ = 0;
  std::FILE* f = file_.get();
  const uint64_t block_offset = offset_;
  const int marker = std::fgetc(f);
  const std::string at = " at byte offset " + std::to_string(block_offset);
  // A read error ends the reading as an error, never as the file's end or a crash's cut.
  auto read_failed = [&] {
    if (!std::ferror(f)) return false;
    fail(std::string("cannot read log") + at + ": " + std::strerror(errno));
    return true;
  };
  if (marker == EOF) {
    if (read_failed()) return false;
    done_ = true;  // clean end
    return false;
  }
  if (marker != kBlockMarker) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%02x", marker);
    fail(std::string("bad block marker ") + hex + at + " (the file is damaged from here on)");
    return false;
  }
  // Block header: varint body length, varint record count, u32 CRC.
  uint8_t head[24];
  size_t n = 0;
  auto read_varint = [&](uint64_t& v) {
    v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      const int c = std::fgetc(f);
      if (c == EOF) return false;
      head[n++] = static_cast<uint8_t>(c);
      v |= static_cast<uint64_t>(c & 0x7F) << shift;
      if (!(c & 0x80)) return true;
    }
    return false;
  };
  uint64_t body_len = 0, count = 0;
  uint8_t crc_bytes[4];
  if (!read_varint(body_len) || !read_varint(count) || std::fread(crc_bytes, 1, 4, f) != 4) {
    if (read_failed()) return false;
    fail("truncated block header" + at + " (the file ends at byte " + std::to_string(file_size_) +
         "; the recording was cut short, e.g. by a crash)");
    return false;
  }
  if (body_len > kMaxBlockBytes || count > body_len) {
    fail("implausible block length " + std::to_string(body_len) + at + " (the file is damaged from here on)");
    return false;
  }
  const uint64_t body_offset = block_offset + 1 + n + 4;
  body_.resize(static_cast<size_t>(body_len));
  const size_t got = std::fread(body_.data(), 1, body_.size(), f);
  if (got < body_.size()) {
    if (read_failed()) return false;
    fail("truncated block" + at + ": its body needs " + std::to_string(body_len) + " bytes, the file has " +
         std::to_string(got) + " (the recording was cut short, e.g. by a crash)");
    return false;
  }
  const uint32_t crc = static_cast<uint32_t>(crc_bytes[0] | (crc_bytes[1] << 8) | (crc_bytes[2] << 16) |
                                             (static_cast<uint32_t>(crc_bytes[3]) << 24));
  if (crc != crc32(body_.data(), body_.size())) {
    fail("block" + at + " fails its CRC check (bytes " + std::to_string(body_offset) + ".." +
         std::to_string(body_offset + body_len) + " are damaged)");
    return false;
  }
  Status st = decode_block(body_.data(), body_.size(), body_offset, count, records_);
  offset_ = body_offset + body_len;
  ++blocks_;
  if (!st) fail(st.error().message);  // records before the malformed one are still returned
  return true;
}

}  // namespace feedloop::recorder
