// The thermal loop's heaters and fans over real MCU links (protocol v3 in frames,
// drivers/protocol/heater_messages.hpp): per MCU a host McuSession on its Transport; the heaters'
// and fans' indices of the thermal loop mapped to each MCU's own; CONFIGURE_HEATER's tick counts
// rescaled to the MCU's clock; the MCU's HEATER_REPORT / HEATER_FAULT clocks mapped to host time by
// the session's clock sync (before the first sync: the arrival time) and handed to the thermal loop
// in its own clock (ThermalOptions::mcu_clock_hz ticks per host second).
//   ThermalLoop --SET_HEATER--> McuHeaterLink --> McuSession --frames--> Transport --> MCU
//   (simulation: MockTransport --> VirtualMcu --> HeaterBoard --> ThermalPlant)
// A heater on a motion MCU (one board for both) goes through that MCU's session on the servo
// thread instead: HeaterMcu::shared, engine/shared_heater_port.hpp.
// Messages wait until their MCU is identified; an MCU that speaks protocol v1/v2 (no heaters) or
// whose session fails is the link's fault() (the thermal loop turns it into a thermal fault).
// Owner: the thermal loop (its mutex); not real-time (the thermal thread).
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/host/mcu_session.hpp"
#include "drivers/transport.hpp"
#include "engine/shared_heater_port.hpp"
#include "engine/thermal_loop.hpp"

namespace feedloop::drivers {
class MockTransport;
}
namespace feedloop::device {
class HeaterBoard;
class VirtualMcu;
}  // namespace feedloop::device
namespace feedloop::engine {

// What a simulated heater MCU owns besides its transport (the virtual MCU, its heater board and
// plants); engine/simulated_printer.cpp implements it (and gives the plants to the tests through
// simulated_thermal_plant / simulated_part_fan: engine/ names no sim:: type outside the factory).
class SimulatedHeaterDevice {
 public:
  virtual ~SimulatedHeaterDevice() = default;
  virtual const device::HeaterBoard& board() const = 0;  // the device's own view (tests)
  virtual device::VirtualMcu& vmcu() = 0;
};

struct HeaterMcu {
  std::string name;
  std::unique_ptr<SimulatedHeaterDevice> sim;  // simulation only (declared first: outlives the transport)
  std::unique_ptr<drivers::Transport> transport;
  drivers::MockTransport* mock = nullptr;      // simulation only
  drivers::McuSessionParams session;           // name, link; encoder and watchdog off
  // A motion MCU's own link instead (no transport, no session here): its session is the servo
  // thread's (McuBridge), the messages cross through this port (shared_heater_port.hpp).
  std::shared_ptr<SharedHeaterPort> shared;
};

// A heater MCU's session: no motors (no encoder stream), no motion watchdog (the heaters have
// their own 3 s rule); a clock query a second (as Klipper's clocksync): report times need
// milliseconds, not the steps' microseconds (and the fit is most of a simulated link's cost).
drivers::McuSessionParams heater_session_params(const std::string& name);

struct HeaterRoute {
  int mcu = 0;        // index into the link's MCUs
  uint8_t local = 0;  // the heater's (fan's) index on that MCU
};

class McuHeaterLink final : public HeaterLink {
 public:
  // heaters[i] / fans[i]: where the thermal loop's heater / fan i lives. host_clock_hz: the
  // thermal loop's ticks per second (ThermalOptions::mcu_clock_hz). io_slice_s: in-process (mock)
  // links are polled at this granularity within advance_to() (the link's 25 ms retransmit timeout
  // needs acknowledgements well within it); real transports have their own I/O threads.
  McuHeaterLink(std::vector<HeaterMcu> mcus, std::vector<HeaterRoute> heaters,
                std::vector<HeaterRoute> fans, double host_clock_hz, double io_slice_s = 2e-3);
  ~McuHeaterLink() override;

  void send(double now_s, const uint8_t* msg, size_t n) override;
  void advance_to(double t_s) override;
  bool receive(uint8_t* out, size_t& n) override;
  std::optional<std::string> fault() const override { return fault_; }
  // ": MCU 'board' (its last event)" for messages.
  std::string heater_place(int heater) const override;
  double last_heard_s(int heater) const override;

  int num_heaters() const { return static_cast<int>(heaters_.size()); }
  int num_fans() const { return static_cast<int>(fans_.size()); }
  int mcu_count() const { return static_cast<int>(mcus_.size()); }
  // The MCU's own session; not for a motion MCU's (shared(i)), whose session the bridge owns.
  drivers::McuSession& session(int i) { return *mcus_[static_cast<size_t>(i)].session; }
  SharedHeaterPort* shared(int i) { return mcus_[static_cast<size_t>(i)].cfg.shared.get(); }
  drivers::MockTransport* mock(int i) { return mcus_[static_cast<size_t>(i)].cfg.mock; }
  SimulatedHeaterDevice* sim(int i) { return mcus_[static_cast<size_t>(i)].cfg.sim.get(); }
  const HeaterRoute& heater_route(int heater) const { return heaters_[static_cast<size_t>(heater)]; }
  const HeaterRoute& fan_route(int fan) const { return fans_[static_cast<size_t>(fan)]; }

  // Fault injection (tests): SET_HEATER from the host is dropped before its session (the host's
  // re-confirmations lost while the link itself stays up).
  void drop_heater_commands(bool on) { drop_set_heater_ = on; }
  // Simulation (tests): the MCUs (and their plants) run to t_s while the host side does nothing
  // (a stalled host: no session poll, no heartbeat, nothing read); the host side's next polls
  // then run at that time at least (a stalled host wakes up to the wire's time).
  void run_devices_only(double t_s);
  uint64_t set_heater_dropped() const { return set_heater_dropped_; }
  // The latest event of any heater MCU's session (an MCU error report, a reconnect); "" when none.
  const std::string& last_event() const { return last_event_; }

 private:
  struct Mcu {
    HeaterMcu cfg;
    std::unique_ptr<drivers::McuSession> session;
    std::deque<std::vector<uint8_t>> held;  // host messages waiting for the MCU to be ready
    bool started = false;
    double last_poll_s = 0.0;
    uint64_t frames_in = 0;        // delivered + duplicates + out of order, as last seen
    double last_heard_s = -1e300;  // host time frames_in last grew
  };
  void poll(Mcu& m, double t_s);
  void forward(Mcu& m, std::vector<uint8_t> msg);
  void collect(int mcu_index, double t_s);
  // One HEATER_REPORT / HEATER_FAULT from MCU mcu_index: its clock mapped to the loop's ticks by
  // to_host_s, its local heater index to the loop's; into the inbox.
  template <class ToHostS>
  void deliver(int mcu_index, const uint8_t* bytes, size_t n, ToHostS to_host_s);
  void poll_shared(Mcu& m, double t_s);
  void release_held(Mcu& m, uint16_t version);
  bool mcu_ready(const Mcu& m) const;

  std::vector<Mcu> mcus_;
  std::vector<HeaterRoute> heaters_, fans_;
  double host_hz_;
  double io_slice_s_;
  std::deque<std::vector<uint8_t>> inbox_;
  std::optional<std::string> fault_;
  std::string last_event_;
  bool drop_set_heater_ = false;
  double devices_ran_to_s_ = -1e300;  // run_devices_only()
  uint64_t set_heater_dropped_ = 0;
};

}  // namespace feedloop::engine
