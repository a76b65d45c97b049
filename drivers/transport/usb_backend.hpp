// The seam between UsbTransport and libusb: the few device operations the transport needs, with
// libusb's return conventions (0 or a negative LIBUSB_ERROR_* code). Transfers are asynchronous
// (libusb_submit_transfer): submit() returns at once and the transfer completes later, inside
// handle_events(), which calls its done() on the thread that handles the events (the transport's
// I/O thread). make_libusb_backend() is the real one (libusb-1.0); tests substitute a fake device
// (tests/drivers/usb_test.cpp) so that enumeration, permission errors, unplug mid-stream, replug
// and a device that stops reading are testable without hardware.
// Owner: the UsbTransport that holds it (its I/O thread once the transport is open).
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

enum class UsbTransferStatus { kCompleted, kTimedOut, kCancelled, kStall, kNoDevice, kOverflow, kError };

// One bulk transfer, owned by the transport (fixed, reused): the buffer stays valid and the
// object untouched until done() was called.
struct UsbTransfer {
  uint8_t endpoint = 0;           // 0x80 bit: IN
  uint8_t* buffer = nullptr;
  int length = 0;                 // bytes to send (OUT) or room (IN)
  int transferred = 0;            // set before done()
  UsbTransferStatus status = UsbTransferStatus::kCompleted;
  void (*done)(UsbTransfer&) = nullptr;
  void* user = nullptr;           // the transport's
  void* backend = nullptr;        // the backend's (libusb_transfer*), kept across submits
};

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
  // Releases the interface (claimed >= 0) and closes the handle (no transfer may be in flight).
  virtual void close(UsbHandle handle, int claimed_interface) = 0;
  // Starts a bulk transfer without a timeout; 0 (done() follows from handle_events) or
  // LIBUSB_ERROR_* (NO_DEVICE once the device is gone; done() does not follow).
  virtual int submit(UsbHandle handle, UsbTransfer& transfer) = 0;
  // Asks a submitted transfer to stop; it completes (kCancelled, or as it was) in handle_events.
  virtual void cancel(UsbTransfer& transfer) = 0;
  // Frees what the backend keeps for the transfer (not in flight).
  virtual void release(UsbTransfer& /*transfer*/) {}
  // Processes events (completions call done()) for up to max_wait_s.
  virtual void handle_events(double max_wait_s) = 0;
  // "LIBUSB_ERROR_ACCESS (Access denied (insufficient permissions))".
  virtual std::string error_text(int rc) const = 0;
};

std::unique_ptr<UsbBackend> make_libusb_backend();

}  // namespace feedloop::drivers
