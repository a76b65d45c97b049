// Reads a flight-recorder log record by record. A damaged or truncated file is not a failure of
// open(): the reader returns every record of the intact blocks before the damage, then stops and
// error() says what is wrong and at which byte offset.
//
//   auto r = LogReader::open("print.flrec");
//   if (!r) { ... r.error().to_string() ... }
//   while (const DecodedRecord* d = r->next()) { std::visit(..., d->record); }
//   if (r->error()) { ... "truncated block at byte offset 123456 ..." ... }
#pragma once

#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "recorder/block_codec.hpp"
#include "recorder/records.hpp"

namespace feedloop::recorder {

class LogReader {
 public:
  // Error when the file cannot be opened or its header is not a valid log header.
  static Result<LogReader> open(const std::string& path);

  const LogHeader& header() const { return header_; }
  const std::string& path() const { return path_; }
  uint64_t file_size() const { return file_size_; }
  uint64_t blocks() const { return blocks_; }

  // The next record, or nullptr at the end of the file or at the first damaged part (error()).
  // The pointer is valid until the next call.
  const DecodedRecord* next();
  const std::optional<Error>& error() const { return error_; }

 private:
  struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  bool read_block();
  void fail(const std::string& message);

  std::string path_;
  std::unique_ptr<std::FILE, FileCloser> file_;
  LogHeader header_;
  uint64_t file_size_ = 0;
  uint64_t offset_ = 0;  // file offset of the next block
  uint64_t blocks_ = 0;
  std::vector<uint8_t> body_;
  std::vector<DecodedRecord> records_;
  size_t next_ = 0;
  bool done_ = false;
  std::optional<Error> error_;
};

}  // namespace feedloop::recorder
