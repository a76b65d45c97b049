// `feedloop replay LOG... [--config FILE] [--keep-log DIR]`: re-runs a recorded print through the
// motion stack against the simulator in virtual time and compares it with the recording (moves,
// time anchors, the commanded step stream bit for bit, the encoder residual).
// `feedloop record FILE.gcode --dir DIR [--config FILE] [--name NAME]`: records a simulated print in
// virtual time (the same run a replay makes), e.g. to make a recording to replay.
// recorder/replay.hpp, docs/recorder.md.
#pragma once

#include <string>
#include <vector>

namespace feedloop::cli {

// args: everything after "replay". Exit code: 0 the step stream is bit-identical, 1 it differs,
// 2 usage or an unreadable log / config.
int replay_command(const std::vector<std::string>& args);

// args: everything after "record". 0 ok, 1 lines rejected or a failure, 2 usage.
int record_command(const std::vector<std::string>& args);

}  // namespace feedloop::cli
