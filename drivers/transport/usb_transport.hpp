// USB bulk transport: finds the MCU by VID/PID (and serial number when given), detaches a kernel
// driver if needed, claims the interface and moves frames over a pair of bulk endpoints with
// asynchronous transfers on the transport's I/O thread (queued_transport.hpp): kInTransfers IN
// transfers are always submitted (each completion is a chunk stamped with its arrival, then
// resubmitted), queued frames are packed into up to kOutTransfers OUT transfers of 512 bytes, and
// the thread sleeps in libusb's event handling between. No synchronous transfer, no timeout per
// cycle. A device that stops reading keeps its OUT transfers pending: the send queue fills and
// try_write() reports back pressure. An unplug shows up as LIBUSB_ERROR_NO_DEVICE: connected()
// turns false with "... unplugged"; open() (McuSession retries it) has the I/O thread find the
// device again after a replug. Errors say what is wrong and what to do (no device, permissions ->
// udev rule, interface busy).
// Device access goes through a UsbBackend (usb_backend.hpp): libusb-1.0 by default, a fake in
// tests. Owner: the caller's side one thread (the servo thread); the device the I/O thread.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/transport/queued_transport.hpp"
#include "drivers/transport/usb_backend.hpp"

namespace feedloop::drivers {

struct UsbParams {
  uint16_t vendor_id = 0x1d50;   // OpenMoko's VID range, as many open firmwares use
  uint16_t product_id = 0x614e;
  std::string serial;            // empty: the first matching device
  int interface_number = 0;
  uint8_t endpoint_out = 0x01;
  uint8_t endpoint_in = 0x81;
  QueuedTransportParams io = usb_io_params();
  static QueuedTransportParams usb_io_params() {
    QueuedTransportParams p;
    p.thread_name = "fl-io-usb";
    return p;
  }
};

struct UsbDeviceInfo {
  uint16_t vendor_id = 0, product_id = 0;
  int bus = 0, address = 0;
  std::string serial;  // empty when it could not be read (permissions)
};

class UsbTransport final : public QueuedTransport {
 public:
  static constexpr int kInTransfers = 4;
  static constexpr int kOutTransfers = 8;
  static constexpr int kTransferBytes = 512;  // a high-speed bulk packet; full speed: 8 packets

  explicit UsbTransport(UsbParams params, std::unique_ptr<UsbBackend> backend = make_libusb_backend());
  ~UsbTransport() override;

  std::string describe() const override;

  // Every USB device the backend (libusb by default) can see, for `feedloop` diagnostics.
  static Result<std::vector<UsbDeviceInfo>> list_devices(UsbBackend* backend = nullptr);

 protected:
  Status device_open() override;
  void device_close() override;
  void device_io(double max_wait_s) override;

 private:
  struct Slot {
    UsbTransfer t;
    bool in_flight = false;
    bool done = false;          // completed, not yet processed
    bool holds_data = false;    // IN: received bytes waiting for room in the receive queue
    int64_t stamp_ns = 0;       // completion (IN: arrival of the bytes)
    uint8_t buf[kTransferBytes] = {};
  };
  static void on_done(UsbTransfer& t);
  Status init_backend();
  bool submit(Slot& s, bool in);
  void submit_in();
  void process_in();
  void process_out();
  void fill_out();

  UsbParams p_;
  std::unique_ptr<UsbBackend> usb_;
  bool initialised_ = false;
  UsbHandle handle_ = nullptr;
  std::array<Slot, kInTransfers> in_{};   // a ring in submission order (bulk IN completes in order)
  int in_head_ = 0, in_count_ = 0;
  std::array<Slot, kOutTransfers> out_{};
};

}  // namespace feedloop::drivers
