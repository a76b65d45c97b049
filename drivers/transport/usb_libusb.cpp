// The real USB backend: libusb-1.0 with asynchronous bulk transfers (see usb_backend.hpp). Each
// UsbTransfer keeps its libusb_transfer across submits (allocated at its first submit, freed by
// release()); libusb itself allocates its URBs per submit, on the I/O thread that submits.
#include <libusb.h>

#include <sys/time.h>  // timeval

#include "drivers/transport/usb_backend.hpp"

namespace feedloop::drivers {

namespace {

class LibusbBackend final : public UsbBackend {
 public:
  ~LibusbBackend() override {
    release_list();
    if (ctx_ != nullptr) libusb_exit(ctx_);
  }
  int init() override {
    if (ctx_ != nullptr) return 0;
    const int rc = libusb_init(&ctx_);
    if (rc != 0) ctx_ = nullptr;
    return rc;
  }
  int list(std::vector<UsbDeviceEntry>& out) override {
    out.clear();
    release_list();
    const ssize_t n = libusb_get_device_list(ctx_, &list_);
    if (n < 0) {
      list_ = nullptr;
      return static_cast<int>(n);
    }
    count_ = n;
    for (ssize_t i = 0; i < n; ++i) {
      libusb_device_descriptor d{};
      UsbDeviceEntry e;
      if (libusb_get_device_descriptor(list_[i], &d) == 0) {
        e.vendor_id = d.idVendor;
        e.product_id = d.idProduct;
        e.serial_index = d.iSerialNumber;
      }
      e.bus = libusb_get_bus_number(list_[i]);
      e.address = libusb_get_device_address(list_[i]);
      out.push_back(e);
    }
    return 0;
  }
  int open(size_t index, UsbHandle* handle) override {
    if (list_ == nullptr || static_cast<ssize_t>(index) >= count_) return LIBUSB_ERROR_NOT_FOUND;
    libusb_device_handle* h = nullptr;
    const int rc = libusb_open(list_[index], &h);
    if (rc == 0) *handle = reinterpret_cast<UsbHandle>(h);
    return rc;
  }
  int serial_number(UsbHandle handle, uint8_t serial_index, std::string& out) override {
    unsigned char buf[128] = {};
    const int len = libusb_get_string_descriptor_ascii(native(handle), serial_index, buf, sizeof buf);
    if (len < 0) return len;
    out.assign(reinterpret_cast<const char*>(buf), static_cast<size_t>(len));
    return 0;
  }
  int claim_interface(UsbHandle handle, int interface_number) override {
    libusb_set_auto_detach_kernel_driver(native(handle), 1);
    return libusb_claim_interface(native(handle), interface_number);
  }
  void close(UsbHandle handle, int claimed_interface) override {
    if (claimed_interface >= 0) libusb_release_interface(native(handle), claimed_interface);
    libusb_close(native(handle));
  }
  int submit(UsbHandle handle, UsbTransfer& t) override {
    auto* x = static_cast<libusb_transfer*>(t.backend);
    if (x == nullptr) {
      x = libusb_alloc_transfer(0);
      if (x == nullptr) return LIBUSB_ERROR_NO_MEM;
      t.backend = x;
    }
    libusb_fill_bulk_transfer(x, native(handle), t.endpoint, t.buffer, t.length, &LibusbBackend::on_done, &t,
                              0 /* no timeout */);
    return libusb_submit_transfer(x);
  }
  void cancel(UsbTransfer& t) override {
    if (t.backend != nullptr) libusb_cancel_transfer(static_cast<libusb_transfer*>(t.backend));
  }
  void release(UsbTransfer& t) override {
    if (t.backend != nullptr) libusb_free_transfer(static_cast<libusb_transfer*>(t.backend));
    t.backend = nullptr;
  }
  void handle_events(double max_wait_s) override {
    if (ctx_ == nullptr) return;
    const long us = max_wait_s > 0.0 ? static_cast<long>(max_wait_s * 1e6) : 0;  // 0: what is pending
    timeval tv{us / 1'000'000, us % 1'000'000};
    libusb_handle_events_timeout_completed(ctx_, &tv, nullptr);
  }
  std::string error_text(int rc) const override {
    return std::string(libusb_error_name(rc)) + " (" + libusb_strerror(rc) + ")";
  }

 private:
  static libusb_device_handle* native(UsbHandle h) { return reinterpret_cast<libusb_device_handle*>(h); }
  static void LIBUSB_CALL on_done(libusb_transfer* x) {
    auto& t = *static_cast<UsbTransfer*>(x->user_data);
    t.transferred = x->actual_length;
    switch (x->status) {
      case LIBUSB_TRANSFER_COMPLETED: t.status = UsbTransferStatus::kCompleted; break;
      case LIBUSB_TRANSFER_TIMED_OUT: t.status = UsbTransferStatus::kTimedOut; break;
      case LIBUSB_TRANSFER_CANCELLED: t.status = UsbTransferStatus::kCancelled; break;
      case LIBUSB_TRANSFER_STALL: t.status = UsbTransferStatus::kStall; break;
      case LIBUSB_TRANSFER_NO_DEVICE: t.status = UsbTransferStatus::kNoDevice; break;
      case LIBUSB_TRANSFER_OVERFLOW: t.status = UsbTransferStatus::kOverflow; break;
      default: t.status = UsbTransferStatus::kError; break;
    }
    if (t.done != nullptr) t.done(t);
  }
  void release_list() {
    if (list_ != nullptr) libusb_free_device_list(list_, 1);
    list_ = nullptr;
    count_ = 0;
  }
  libusb_context* ctx_ = nullptr;
  libusb_device** list_ = nullptr;
  ssize_t count_ = 0;
};

}  // namespace

std::unique_ptr<UsbBackend> make_libusb_backend() { return std::make_unique<LibusbBackend>(); }

}  // namespace feedloop::drivers
