// What a file that is not text G-code is, from its first bytes: a compressed file, an archive or
// PrusaSlicer's binary G-code read line by line would yield thousands of "unexpected byte" errors
// and move nothing useful. The readers (batch mode, replay, `feedloop print`, the daemon's print
// jobs) refuse such a file at once with what it is and what to do.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace feedloop::gcode {

// Why a file starting with `head` (its first bytes; 8 are enough) is not text G-code, or nothing
// when its magic number is none of the known ones. Plain text is never refused here.
inline std::optional<std::string> non_gcode_file_kind(std::string_view head) {
  struct Magic {
    std::string_view bytes, what;
  };
  static constexpr Magic kMagics[] = {
      // libbgcode's file header: "GCDE", then the version (PrusaSlicer 2.7 and later).
      {"GCDE", "binary G-code (PrusaSlicer's .bgcode); export text G-code instead (Printer "
               "Settings > General > Supports binary G-code: off) or convert it with bgcode"},
      {"\x1f\x8b", "gzip-compressed; decompress it first (gunzip)"},
      {"\xfd" "7zXZ", "xz-compressed; decompress it first (xz -d)"},
      {"\x28\xb5\x2f\xfd", "zstd-compressed; decompress it first (zstd -d)"},
      {"BZh", "bzip2-compressed; decompress it first (bunzip2)"},
      {"PK\x03\x04", "a ZIP archive (a .3mf project?); slice it and export G-code"},
  };
  for (const Magic& m : kMagics)
    if (head.substr(0, m.bytes.size()) == m.bytes) return "not G-code: " + std::string(m.what);
  return std::nullopt;
}

}  // namespace feedloop::gcode
