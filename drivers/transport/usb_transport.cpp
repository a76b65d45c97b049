// USB bulk transport with libusb-1.0: see usb_transport.hpp.
#include "drivers/transport/usb_transport.hpp"

#include <libusb.h>

#include <cstdio>

namespace feedloop::drivers {

namespace {
std::string hex4(uint16_t v) {
  char b[8];
  std::snprintf(b, sizeof b, "%04x", v);
  return b;
}
std::string usb_error(int rc) { return std::string(libusb_error_name(rc)) + " (" + libusb_strerror(rc) + ")"; }
}  // namespace

UsbTransport::UsbTransport(UsbParams params) : p_(std::move(params)) {}

UsbTransport::~UsbTransport() {
  close();
  if (ctx_ != nullptr) libusb_exit(ctx_);
}

std::string UsbTransport::describe() const {
  std::string s = "usb " + hex4(p_.vendor_id) + ":" + hex4(p_.product_id);
  if (!p_.serial.empty()) s += " serial " + p_.serial;
  return s;
}

Status UsbTransport::init_context() {
  if (ctx_ != nullptr) return {};
  const int rc = libusb_init(&ctx_);
  if (rc != 0) {
    ctx_ = nullptr;
    return Error{"cannot initialise libusb: " + usb_error(rc) +
                     " (no USB support in this system or container? /dev/bus/usb must be accessible)",
                 {}};
  }
  return {};
}

Result<std::vector<UsbDeviceInfo>> UsbTransport::list_devices() {
  libusb_context* ctx = nullptr;
  int rc = libusb_init(&ctx);
  if (rc != 0) return Error{"cannot initialise libusb: " + usb_error(rc), {}};
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  std::vector<UsbDeviceInfo> out;
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != 0) continue;
    UsbDeviceInfo info{d.idVendor, d.idProduct, libusb_get_bus_number(list[i]), libusb_get_device_address(list[i]), {}};
    libusb_device_handle* h = nullptr;
    if (d.iSerialNumber != 0 && libusb_open(list[i], &h) == 0) {
      unsigned char buf[128] = {};
      if (libusb_get_string_descriptor_ascii(h, d.iSerialNumber, buf, sizeof buf) > 0)
        info.serial = reinterpret_cast<const char*>(buf);
      libusb_close(h);
    }
    out.push_back(info);
  }
  if (n >= 0) libusb_free_device_list(list, 1);
  libusb_exit(ctx);
  if (n < 0) return Error{"cannot list USB devices: " + usb_error(static_cast<int>(n)), {}};
  return out;
}

Status UsbTransport::open() {
  close();
  if (Status st = init_context(); !st.ok()) return st;
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx_, &list);
  if (n < 0) return Error{"cannot list USB devices: " + usb_error(static_cast<int>(n)), {}};
  int matches = 0;
  std::string access_problem;
  for (ssize_t i = 0; i < n && handle_ == nullptr; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != 0) continue;
    if (d.idVendor != p_.vendor_id || d.idProduct != p_.product_id) continue;
    ++matches;
    libusb_device_handle* h = nullptr;
    const int rc = libusb_open(list[i], &h);
    if (rc != 0) {
      access_problem = "cannot open " + describe() + " at bus " + std::to_string(libusb_get_bus_number(list[i])) +
                       " address " + std::to_string(libusb_get_device_address(list[i])) + ": " + usb_error(rc);
      if (rc == LIBUSB_ERROR_ACCESS)
        access_problem += "; permission denied: install a udev rule for this VID:PID (docs/protocol.md) "
                          "or add the user to the group that owns the device";
      continue;
    }
    if (!p_.serial.empty()) {
      unsigned char buf[128] = {};
      const int len = d.iSerialNumber ? libusb_get_string_descriptor_ascii(h, d.iSerialNumber, buf, sizeof buf) : 0;
      if (len <= 0 || p_.serial != reinterpret_cast<const char*>(buf)) {
        libusb_close(h);
        continue;
      }
    }
    libusb_set_auto_detach_kernel_driver(h, 1);
    const int crc = libusb_claim_interface(h, p_.interface_number);
    if (crc != 0) {
      access_problem = "cannot claim interface " + std::to_string(p_.interface_number) + " of " + describe() + ": " +
                       usb_error(crc) + (crc == LIBUSB_ERROR_BUSY ? "; another program is using the MCU" : "");
      libusb_close(h);
      continue;
    }
    handle_ = h;
  }
  libusb_free_device_list(list, 1);
  if (handle_ != nullptr) return {};
  if (!access_problem.empty()) return Error{access_problem, {}};
  if (matches > 0)
    return Error{"no USB device " + describe() + " with serial '" + p_.serial + "' (" + std::to_string(matches) +
                     " device(s) with that VID:PID have other serial numbers)",
                 {}};
  return Error{"no USB device " + describe() + " found (" + std::to_string(n) +
                   " USB device(s) present); is the MCU plugged in and powered? `lsusb` lists what is there",
               {}};
}

void UsbTransport::close() {
  if (handle_ != nullptr) {
    libusb_release_interface(handle_, p_.interface_number);
    libusb_close(handle_);
    handle_ = nullptr;
  }
}

Status UsbTransport::write(const uint8_t* data, size_t n) {
  if (handle_ == nullptr) return Error{describe() + " is not open", {}};
  int done = 0;
  const int rc = libusb_bulk_transfer(handle_, p_.endpoint_out, const_cast<uint8_t*>(data), static_cast<int>(n),
                                      &done, p_.write_timeout_ms);
  if (rc != 0 || static_cast<size_t>(done) != n) {
    if (rc == LIBUSB_ERROR_NO_DEVICE || rc == LIBUSB_ERROR_IO || rc == LIBUSB_ERROR_PIPE) close();
    return Error{"USB write to " + describe() + " failed: " + usb_error(rc), {}};
  }
  return {};
}

Result<size_t> UsbTransport::read(uint8_t* buf, size_t cap) {
  if (handle_ == nullptr) return Error{describe() + " is not open", {}};
  int got = 0;
  const int rc = libusb_bulk_transfer(handle_, p_.endpoint_in, buf, static_cast<int>(cap), &got, 1);
  if (rc == LIBUSB_ERROR_TIMEOUT || rc == 0) return static_cast<size_t>(got);
  if (rc == LIBUSB_ERROR_NO_DEVICE) {
    close();
    return Error{describe() + " unplugged", {}};
  }
  return Error{"USB read from " + describe() + " failed: " + usb_error(rc), {}};
}

void UsbTransport::poll(double /*now_s*/, double max_wait_s) {
  if (ctx_ == nullptr || max_wait_s <= 0.0) return;
  timeval tv{0, static_cast<long>(max_wait_s * 1e6)};
  libusb_handle_events_timeout_completed(ctx_, &tv, nullptr);
}

}  // namespace feedloop::drivers
