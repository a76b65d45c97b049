// USB bulk transport: finds the MCU by VID/PID (and serial number when given), detaches a kernel
// driver if needed, claims the interface and moves frames over a pair of bulk endpoints. An
// unplug shows up as LIBUSB_ERROR_NO_DEVICE: connected() turns false and read()/write() report
// the disconnect; open() finds the device again after a replug (McuSession retries it). Errors
// say what is wrong and what to do (no device, permissions -> udev rule, interface busy).
// Device access goes through a UsbBackend (usb_backend.hpp): libusb-1.0 by default, a fake in
// tests. Owner: the I/O thread.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/transport.hpp"
#include "drivers/transport/usb_backend.hpp"

namespace feedloop::drivers {

struct UsbParams {
  uint16_t vendor_id = 0x1d50;   // OpenMoko's VID range, as many open firmwares use
  uint16_t product_id = 0x614e;
  std::string serial;            // empty: the first matching device
  int interface_number = 0;
  uint8_t endpoint_out = 0x01;
  uint8_t endpoint_in = 0x81;
  unsigned write_timeout_ms = 100;
  unsigned read_timeout_ms = 1;  // a read waits this long for a packet (libusb: 0 would be forever)
};

struct UsbDeviceInfo {
  uint16_t vendor_id = 0, product_id = 0;
  int bus = 0, address = 0;
  std::string serial;  // empty when it could not be read (permissions)
};

class UsbTransport final : public Transport {
 public:
  explicit UsbTransport(UsbParams params, std::unique_ptr<UsbBackend> backend = make_libusb_backend());
  ~UsbTransport() override;
  UsbTransport(const UsbTransport&) = delete;
  UsbTransport& operator=(const UsbTransport&) = delete;

  Status open() override;
  void close() override;
  bool connected() const override { return handle_ != nullptr; }
  Status write(const uint8_t* data, size_t n) override;
  Result<size_t> read(uint8_t* buf, size_t cap) override;
  void poll(double now_s, double max_wait_s) override;
  std::string describe() const override;

  // Every USB device the backend (libusb by default) can see, for `feedloop` diagnostics.
  static Result<std::vector<UsbDeviceInfo>> list_devices(UsbBackend* backend = nullptr);

 private:
  Status init_backend();
  UsbParams p_;
  std::unique_ptr<UsbBackend> usb_;
  bool initialised_ = false;
  UsbHandle handle_ = nullptr;
};

}  // namespace feedloop::drivers
