// feedloop: the command-line tool.
//
//   feedloop print FILE          stream a G-code file to a running feedloopd
//   feedloop batch FILE          the pipeline in virtual time against an ideal plant
//   feedloop log info|export     flight-recorder logs
//   feedloop replay LOG          re-run a recorded print against the simulator, compare
//   feedloop record FILE         record a simulated print in virtual time
//   feedloop help                this text
#include <cstdio>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "cli/batch_command.hpp"
#include "cli/calibrate_command.hpp"
#include "cli/ident_command.hpp"
#include "cli/log_command.hpp"
#include "cli/model_command.hpp"
#include "cli/print_command.hpp"
#include "cli/replay_command.hpp"

namespace {

void usage(std::FILE* out) {
  std::fputs(
      "usage: feedloop COMMAND [ARGS]\n"
      "commands:\n"
      "  print FILE [--socket PATH] [--window N]   stream G-code to a running feedloopd\n"
      "  batch FILE [--config CFG] [--json OUT]    whole pipeline in virtual time, no hardware\n"
      "  log info LOG...                           summarise flight-recorder logs\n"
      "  log export LOG... --csv FILE [--rate-hz N]  recorder logs -> trace CSV v1\n"
      "  replay LOG... [--config F] [--keep-log DIR]  re-run a recorded print in virtual time, "
      "compare\n"
      "  record FILE --dir DIR [--config F]         record a simulated print in virtual time\n"
      "  ident fit --trace F.csv --out DIR         identify an axis: baseline, effects, report\n"
      "  ident excite --axis x|y --out F.csv       simulated excitation trace (tests, demos)\n"
      "  calibrate [--axes x,y] [--out DIR]        calibrate a running feedloopd's machine from "
      "its data\n"
      "  model frf [--config F] --pos X,Y,Z --out F.csv [--virtual-work]   delta FRFs (Eq. 29)\n"
      "run 'feedloop COMMAND --help' for a command's options\n",
      out);
}

int dispatch(const std::string& cmd, const std::vector<std::string>& args) {
  if (cmd == "print") return feedloop::cli::print_command(args);
  if (cmd == "batch") return feedloop::cli::batch_command(args);
  if (cmd == "log") return feedloop::cli::log_command(args);
  if (cmd == "replay") return feedloop::cli::replay_command(args);
  if (cmd == "record") return feedloop::cli::record_command(args);
  if (cmd == "ident") return feedloop::cli::ident_command(args);
  if (cmd == "calibrate") return feedloop::cli::calibrate_command(args);
  if (cmd == "model") return feedloop::cli::model_command(args);
  if (cmd == "help" || cmd == "--help" || cmd == "-h") {
    usage(stdout);
    return 0;
  }
  std::fprintf(stderr, "feedloop: unknown command '%s'\n", cmd.c_str());
  usage(stderr);
  return 2;
}

}  // namespace

// Commands report what they can foresee as errors; what escapes them (memory running out on a
// huge input) still ends with a message and a status, not an abort.
int main(int argc, char** argv) {
  if (argc < 2) {
    usage(stderr);
    return 2;
  }
  const std::string cmd = argv[1];
  try {
    return dispatch(cmd, std::vector<std::string>(argv + 2, argv + argc));
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "feedloop %s: out of memory\n", cmd.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "feedloop %s: internal error: %s\n", cmd.c_str(), e.what());
  }
  return 1;
}
