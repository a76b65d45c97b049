// USB bulk transport over a UsbBackend (libusb-1.0 in production): see usb_transport.hpp.
#include "drivers/transport/usb_transport.hpp"

#include <libusb.h>  // LIBUSB_ERROR_* codes

#include <cstdio>

namespace feedloop::drivers {

namespace {
std::string hex4(uint16_t v) {
  char b[8];
  std::snprintf(b, sizeof b, "%04x", v);
  return b;
}
}  // namespace

UsbTransport::UsbTransport(UsbParams params, std::unique_ptr<UsbBackend> backend)
    : p_(std::move(params)), usb_(std::move(backend)) {}

UsbTransport::~UsbTransport() { close(); }

std::string UsbTransport::describe() const {
  std::string s = "usb " + hex4(p_.vendor_id) + ":" + hex4(p_.product_id);
  if (!p_.serial.empty()) s += " serial " + p_.serial;
  return s;
}

Status UsbTransport::init_backend() {
  if (initialised_) return {};
  const int rc = usb_->init();
  if (rc != 0)
    return Error{"cannot initialise libusb: " + usb_->error_text(rc) +
                     " (no USB support in this system or container? /dev/bus/usb must be accessible)",
                 {}};
  initialised_ = true;
  return {};
}

Result<std::vector<UsbDeviceInfo>> UsbTransport::list_devices(UsbBackend* backend) {
  std::unique_ptr<UsbBackend> own;
  if (backend == nullptr) {
    own = make_libusb_backend();
    backend = own.get();
  }
  if (const int rc = backend->init(); rc != 0) return Error{"cannot initialise libusb: " + backend->error_text(rc), {}};
  std::vector<UsbDeviceEntry> entries;
  if (const int rc = backend->list(entries); rc != 0)
    return Error{"cannot list USB devices: " + backend->error_text(rc), {}};
  std::vector<UsbDeviceInfo> out;
  for (size_t i = 0; i < entries.size(); ++i) {
    const UsbDeviceEntry& e = entries[i];
    UsbDeviceInfo info{e.vendor_id, e.product_id, e.bus, e.address, {}};
    UsbHandle h = nullptr;
    if (e.serial_index != 0 && backend->open(i, &h) == 0) {
      backend->serial_number(h, e.serial_index, info.serial);
      backend->close(h, -1);
    }
    out.push_back(info);
  }
  return out;
}

Status UsbTransport::open() {
  close();
  if (Status st = init_backend(); !st.ok()) return st;
  std::vector<UsbDeviceEntry> entries;
  if (const int rc = usb_->list(entries); rc != 0) return Error{"cannot list USB devices: " + usb_->error_text(rc), {}};
  int matches = 0;
  std::string access_problem;
  for (size_t i = 0; i < entries.size() && handle_ == nullptr; ++i) {
    const UsbDeviceEntry& d = entries[i];
    if (d.vendor_id != p_.vendor_id || d.product_id != p_.product_id) continue;
    ++matches;
    const std::string where = describe() + " at bus " + std::to_string(d.bus) + " address " + std::to_string(d.address);
    UsbHandle h = nullptr;
    const int rc = usb_->open(i, &h);
    if (rc != 0) {
      access_problem = "cannot open " + where + ": " + usb_->error_text(rc);
      if (rc == LIBUSB_ERROR_ACCESS)
        access_problem += "; permission denied: install a udev rule for " + hex4(p_.vendor_id) + ":" +
                          hex4(p_.product_id) + " (docs/protocol.md, section 8) or add the user to the group "
                          "that owns the device";
      continue;
    }
    if (!p_.serial.empty()) {
      std::string serial;
      if (d.serial_index == 0 || usb_->serial_number(h, d.serial_index, serial) != 0 || serial != p_.serial) {
        usb_->close(h, -1);
        continue;
      }
    }
    const int crc = usb_->claim_interface(h, p_.interface_number);
    if (crc != 0) {
      access_problem = "cannot claim interface " + std::to_string(p_.interface_number) + " of " + where + ": " +
                       usb_->error_text(crc) + (crc == LIBUSB_ERROR_BUSY ? "; another program is using the MCU" : "");
      usb_->close(h, -1);
      continue;
    }
    handle_ = h;
  }
  if (handle_ != nullptr) return {};
  if (!access_problem.empty()) return Error{access_problem, {}};
  if (matches > 0)
    return Error{"no USB device " + describe() + " with serial '" + p_.serial + "' (" + std::to_string(matches) +
                     " device(s) with that VID:PID have other serial numbers)",
                 {}};
  return Error{"no USB device " + describe() + " found (" + std::to_string(entries.size()) +
                   " USB device(s) present); is the MCU plugged in and powered? `lsusb` lists what is there",
               {}};
}

void UsbTransport::close() {
  if (handle_ != nullptr) {
    usb_->close(handle_, p_.interface_number);
    handle_ = nullptr;
  }
}

Status UsbTransport::write(const uint8_t* data, size_t n) {
  if (handle_ == nullptr) return Error{describe() + " is not open", {}};
  int done = 0;
  const int rc = usb_->bulk_transfer(handle_, p_.endpoint_out, const_cast<uint8_t*>(data), static_cast<int>(n), &done,
                                     p_.write_timeout_ms);
  if (rc == 0 && static_cast<size_t>(done) == n) return {};
  if (rc == LIBUSB_ERROR_NO_DEVICE) {
    close();
    return Error{describe() + " unplugged (USB write: " + usb_->error_text(rc) + ")", {}};
  }
  if (rc == LIBUSB_ERROR_IO || rc == LIBUSB_ERROR_PIPE) close();
  return Error{"USB write to " + describe() + " failed: " +
                   (rc == 0 ? std::to_string(done) + " of " + std::to_string(n) + " bytes sent" : usb_->error_text(rc)),
               {}};
}

Result<size_t> UsbTransport::read(uint8_t* buf, size_t cap) {
  if (handle_ == nullptr) return Error{describe() + " is not open", {}};
  int got = 0;
  const int rc = usb_->bulk_transfer(handle_, p_.endpoint_in, buf, static_cast<int>(cap), &got, p_.read_timeout_ms);
  if (rc == LIBUSB_ERROR_TIMEOUT || rc == 0) return static_cast<size_t>(got);
  if (rc == LIBUSB_ERROR_NO_DEVICE) {
    close();
    return Error{describe() + " unplugged (USB read: " + usb_->error_text(rc) + ")", {}};
  }
  return Error{"USB read from " + describe() + " failed: " + usb_->error_text(rc), {}};
}

void UsbTransport::poll(double /*now_s*/, double max_wait_s) {
  if (initialised_) usb_->handle_events(max_wait_s);
}

}  // namespace feedloop::drivers
