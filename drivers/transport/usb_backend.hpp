// The seam between UsbTransport and libusb: the few device operations the transport needs, with
// libusb's return conventions (0 or a negative LIBUSB_ERROR_* code). make_libusb_backend() is the
// real one (libusb-1.0); tests substitute a fake device (tests/drivers/usb_test.cpp) so that
// enumeration, permission errors, unplug mid-stream and replug are testable without hardware.
// Owner: the UsbTransport that holds it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace feedloop::drivers {

struct UsbDeviceEntry {
  uint16_t vendor_id = 0, product_id = 0;
  int bus = 0, address = 0;
  uint8_t serial_index = 0;  // string descriptor index of the serial number (0: none)
};

struct UsbHandleTag;
using UsbHandle = UsbHandleTag*;  // an open device (opaque; the backend's own)

class UsbBackend {
 public:
  virtual ~UsbBackend() = default;
  // Once before anything else; 0 or LIBUSB_ERROR_*.
  virtual int init() = 0;
  // The devices present now (out replaced); 0 or LIBUSB_ERROR_*. Indexes stay valid for open()
  // until the next list().
  virtual int list(std::vector<UsbDeviceEntry>& out) = 0;
  virtual int open(size_t index, UsbHandle* handle) = 0;
  // The serial number string (descriptor `serial_index`); 0 or LIBUSB_ERROR_*.
  virtual int serial_number(UsbHandle handle, uint8_t serial_index, std::string& out) = 0;
  // Detaches a kernel driver if needed and claims the interface; 0 or LIBUSB_ERROR_*.
  virtual int claim_interface(UsbHandle handle, int interface_number) = 0;
  // Releases the interface (claimed >= 0) and closes the handle.
  virtual void close(UsbHandle handle, int claimed_interface) = 0;
  // One bulk transfer (libusb_bulk_transfer's contract); 0 or LIBUSB_ERROR_* (TIMEOUT with
  // *transferred bytes moved, NO_DEVICE once the device is gone).
  virtual int bulk_transfer(UsbHandle handle, uint8_t endpoint, uint8_t* data, int length, int* transferred,
                            unsigned timeout_ms) = 0;
  // Lets libusb process events for up to max_wait_s.
  virtual void handle_events(double max_wait_s) = 0;
  // "LIBUSB_ERROR_ACCESS (Access denied (insufficient permissions))".
  virtual std::string error_text(int rc) const = 0;
};

std::unique_ptr<UsbBackend> make_libusb_backend();

}  // namespace feedloop::drivers
