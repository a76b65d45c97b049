// External plant v1 (DESIGN.md "External plant v1"): axes of the simulated printer driven by a
// plant that runs in another process, so that feedloop can be tested against a model the project
// did not write.
//
//   feedloop -> plant (stdin):   "feedloop-plant 1 axes=x,y period_s=0.0001\n"   (handshake)
//   plant -> feedloop (stdout):  "ready\n"
//   every period, in lock-step:  "t_s u_1 ... u_n\n"  ->  "y_1 ... y_n\n"
//   end: feedloop closes the plant's stdin; the plant exits.
//
// t_s is the MCU time at the end of the period (the simulation's time line, which starts at 0), u_i
// the commanded motor position of the i-th axis in mm (steps executed x mm per step, the staircase
// value at t_s), y_i the carriage position in mm at t_s before the encoder. The encoder's
// quantisation, noise and sampling delay are applied here, as configured, exactly as for the
// built-in plant (sim/encoder.hpp). The first period ends at t_s = period_s with every axis at rest
// at its start position.
//
// A plant that exits, answers a malformed line or stays silent for answer_timeout_s (5 s, the
// contract's figure) latches fault() with a message; the printer's bridge then stops the machine.
// After a fault nothing more is exchanged and the axes hold their last positions.
//
// Owner: the thread that advances the simulation (the bridge's servo thread). The exchange blocks
// on the plant (lock-step): in virtual time feedloop waits for every answer; in real time a plant
// that cannot keep up shows as late servo ticks. Nothing here allocates after start().
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "drivers/device/motor_port.hpp"
#include "sim/encoder.hpp"

namespace feedloop::sim {

struct ExternalAxisParams {
  std::string name;            // as in the config: x, y, z, e, or A, B, C for delta carriages
  double mm_per_step = 0.0;    // commanded motion per step (the config's steps_per_mm)
  double start_mm = 0.0;       // where the axis starts: u = y = start_mm at t = 0
  EncoderParams encoder;       // applied to y (resolution, noise, sampling delay)
  uint64_t seed = 1;           // encoder noise
};

struct ExternalPlantParams {
  std::string command;                // run with /bin/sh -c; stderr goes to feedloop's stderr
  std::vector<ExternalAxisParams> axes;
  double period_s = 100e-6;
  double answer_timeout_s = 5.0;      // contract: silence for 5 s stops the machine
  double handshake_timeout_s = 5.0;   // for 'ready' (an interpreter may take a while to start)
};

class ExternalPlant;

// One listed axis: the virtual MCU's motor port. Steps are counted into u; encoder reads return
// the plant's y through the encoder model.
class ExternalAxisPort final : public device::MotorPort {
 public:
  void step(double t_s, int direction) override;
  void set_enabled(double t_s, bool enabled) override;
  int64_t read_encoder_counts(double t_s) override;

  double commanded_mm() const { return start_mm_ + static_cast<double>(steps_) * mm_per_step_; }
  double carriage_mm() const { return y_mm_; }
  double encoder_mm_per_count() const { return encoder_.mm_per_count(); }

 private:
  friend class ExternalPlant;
  ExternalAxisPort(ExternalPlant& owner, const ExternalAxisParams& p, double period_s);

  ExternalPlant* owner_;
  double mm_per_step_;
  double start_mm_;
  int64_t steps_ = 0;
  double y_mm_;          // the plant's latest answer
  LinearEncoder encoder_;
  History history_;      // y at the period ends, for the sampling delay
  double delay_s_;
};

class ExternalPlant {
 public:
  // Starts the command and completes the handshake (waits up to answer_timeout_s for `ready`).
  static Result<std::unique_ptr<ExternalPlant>> start(const ExternalPlantParams& p);
  ~ExternalPlant();  // closes the plant's stdin, waits up to 1 s for it to exit, then kills it
  ExternalPlant(const ExternalPlant&) = delete;
  ExternalPlant& operator=(const ExternalPlant&) = delete;

  int axis_count() const { return static_cast<int>(ports_.size()); }
  ExternalAxisPort& port(int i) { return *ports_[static_cast<size_t>(i)]; }

  // Exchanges one line per period whose end is at or before t_s. No-op after a fault.
  void advance_to(double t_s);

  // Empty while the plant is healthy; otherwise what went wrong, with the period's time.
  bool faulted() const { return !fault_.empty(); }
  const std::string& fault() const { return fault_; }
  uint64_t periods() const { return periods_; }

 private:
  explicit ExternalPlant(const ExternalPlantParams& p);
  bool write_all(const char* data, size_t n);
  // Reads one '\n'-terminated line into line_ (without the '\n'); false on EOF, timeout or error
  // (fault_ set).
  bool read_line(const char* waiting_for, double timeout_s);
  void set_fault(const std::string& message);
  void exchange_period();

  ExternalPlantParams params_;
  std::vector<std::unique_ptr<ExternalAxisPort>> ports_;
  pid_t pid_ = -1;
  int to_plant_ = -1;    // the plant's stdin
  int from_plant_ = -1;  // the plant's stdout
  double next_end_s_ = 0.0;  // end of the next period to exchange
  uint64_t periods_ = 0;
  std::string fault_;
  // Fixed buffers (sized at construction): the line written, the bytes read, the line parsed.
  std::vector<char> out_;
  std::vector<char> in_;
  size_t in_len_ = 0;
  std::vector<char> line_;
};

}  // namespace feedloop::sim
