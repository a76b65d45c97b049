// libFuzzer target for the G-code front end: the input bytes are a stream that goes through
// LineSplitter -> parse_line -> HostProtocol, as on a client channel. The first byte picks the
// options (line cap, '\r' as line end, deferred ok) and the chunk size the stream is fed in.
// Besides memory errors (ASan) and UB (UBSan), the invariants below trap as findings:
// bounded buffering, no half-filled command after an error, finite and allowed parameters on
// every validated command, replies of bounded size.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "gcode/code_table.hpp"
#include "gcode/host_protocol.hpp"
#include "gcode/line_splitter.hpp"
#include "gcode/parser.hpp"

namespace {

using namespace feedloop;
using namespace feedloop::gcode;

void check(bool ok) {
  if (!ok) __builtin_trap();
}

void check_command(const Command& c) {
  if (c.empty()) {
    check(!c.has_any_parameter());
    return;
  }
  check(c.letter == 'G' || c.letter == 'M' || c.letter == 'T');
  check(c.code >= 0);
  for (char p = 'A'; p <= 'Z'; ++p) {
    if (c.has_value(p)) check(std::isfinite(c.get(p)));
    if (c.has_value(p)) check(c.has(p));
  }
  if (c.unknown) return;
  // Klipper's SET_PRESSURE_ADVANCE, translated into M900 (gcode/parser.cpp): its own parameters,
  // ADVANCE -> K and SMOOTH_TIME -> S, checked by its own parser, not by M900's row of the table.
  if (c.letter == 'M' && c.code == 900 && c.text == "SET_PRESSURE_ADVANCE") {
    for (char p = 'A'; p <= 'Z'; ++p) check(!c.has(p) || p == 'K' || p == 'S');
    return;
  }
  // Object labels (Klipper's forms, Marlin's and RepRapFirmware's M486), translated into M486
  // with the form as subcode (gcode/command.hpp): flags C (CURRENT=1) and R (RESET=1) only, and
  // an object's name with the index S of the object it starts (RepRapFirmware); the name valid
  // UTF-8 text, for a name without the characters that would end an EXCLUDE_OBJECT NAME= value.
  if (c.letter == 'M' && c.code == 486) {
    check(c.subcode >= kObjectDefine && c.subcode <= kObjectName);
    for (char p = 'A'; p <= 'Z'; ++p)
      check(!c.has(p) || ((p == 'C' || p == 'R') && !c.has_value(p)) ||
            (p == 'S' && c.subcode == kObjectName && c.get('S') >= 0));
    check(c.subcode != kObjectStart || !c.text.empty());
    if (c.subcode == kObjectName) {
      check(!c.text.empty());
      for (const char ch : c.text)
        check(ch != ' ' && ch != '\t' && ch != ';' && ch != '*' && ch != '"' && ch != '\'');
    }
    return;
  }
  const CodeRule* rule = find_code_rule(c.letter, c.code);
  check(rule != nullptr);
  for (char p = 'A'; p <= 'Z'; ++p) {
    if (!c.has(p)) continue;
    bool allowed = false;
    for (const ParamRule& r : rule->params) allowed |= r.letter == p;
    check(allowed);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t mode = data[0];
  const std::string_view stream(reinterpret_cast<const char*>(data + 1), size - 1);
  const size_t cap = (mode & 1) ? 4096 : LineSplitter::kDefaultMaxLineBytes;
  LineSplitter splitter(cap, (mode & 2) != 0);
  HostProtocol::Options opts;
  opts.defer_ok = (mode & 4) != 0;
  HostProtocol protocol("fuzz", opts);
  const size_t chunk = 1 + (static_cast<size_t>(mode >> 3) * 37) % 4099;

  Command parsed;
  Command executed;
  Reply reply;
  const SourceLocation where{"fuzz", 1, 0};
  auto on_line = [&](const SplitLine& line) {
    check(line.too_long ? line.length_bytes > cap : line.text.size() <= cap);
    reply.clear();
    if (line.too_long) {
      check(protocol.on_too_long(line, reply) == HostProtocol::Action::kNone);
      check(reply.text.size() < 256);
      return;
    }
    Status st = parse_line(line.text, where, parsed);
    if (st.ok()) {
      check_command(parsed);
    } else {
      check(parsed.empty() && parsed.text.empty());
      check(st.error().where.column >= 1 && !st.error().message.empty());
    }
    const HostProtocol::Action a = protocol.on_line(line.text, reply, executed);
    if (a == HostProtocol::Action::kExecute) {
      check(!executed.empty());
      check_command(executed);
      if (opts.defer_ok) HostProtocol::acknowledge(reply);
    }
    check(reply.text.size() <= 2 * line.text.size() + 1024);
  };
  for (size_t i = 0; i < stream.size(); i += chunk) {
    splitter.feed(stream.substr(i, chunk), on_line);
    check(splitter.buffered_bytes() <= cap);
  }
  splitter.finish(on_line);
  return 0;
}
