#include "engine/mcu_transport.hpp"

#include "drivers/transport/serial_transport.hpp"
#include "drivers/transport/usb_transport.hpp"

namespace feedloop::engine {

std::unique_ptr<drivers::Transport> make_hardware_transport(const config::McuConfig& mc, int io_priority) {
  if (mc.transport == config::TransportType::serial) {
    drivers::QueuedTransportParams io = drivers::SerialTransport::serial_io_params();
    io.rt_priority = io_priority;
    return std::make_unique<drivers::SerialTransport>(mc.serial.device, static_cast<unsigned>(mc.serial.baud), io);
  }
  if (mc.transport == config::TransportType::usb) {
    drivers::UsbParams up;
    up.vendor_id = static_cast<uint16_t>(mc.usb.vid);
    up.product_id = static_cast<uint16_t>(mc.usb.pid);
    up.serial = mc.usb.serial;
    up.io.rt_priority = io_priority;
    return std::make_unique<drivers::UsbTransport>(up);
  }
  return nullptr;
}

}  // namespace feedloop::engine
