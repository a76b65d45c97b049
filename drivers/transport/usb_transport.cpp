// USB bulk transport over a UsbBackend (libusb-1.0 in production): see usb_transport.hpp.
#include "drivers/transport/usb_transport.hpp"

#include <libusb.h>  // LIBUSB_ERROR_* codes

#include <algorithm>  // std::min
#include <cstdio>
#include <cstring>    // memcpy

namespace feedloop::drivers {

namespace {
std::string hex4(uint16_t v) {
  char b[8];
  std::snprintf(b, sizeof b, "%04x", v);
  return b;
}
}  // namespace

UsbTransport::UsbTransport(UsbParams params, std::unique_ptr<UsbBackend> backend)
    : QueuedTransport(params.io), p_(std::move(params)), usb_(std::move(backend)) {
  for (Slot& s : in_) {
    s.t.endpoint = p_.endpoint_in;
    s.t.buffer = s.buf;
    s.t.done = &UsbTransport::on_done;
    s.t.user = &s;
  }
  for (Slot& s : out_) {
    s.t.endpoint = p_.endpoint_out;
    s.t.buffer = s.buf;
    s.t.done = &UsbTransport::on_done;
    s.t.user = &s;
  }
}

UsbTransport::~UsbTransport() {
  shutdown();
  for (Slot& s : in_) usb_->release(s.t);
  for (Slot& s : out_) usb_->release(s.t);
}

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

Status UsbTransport::device_open() {
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
  if (handle_ != nullptr) {
    in_head_ = in_count_ = 0;
    submit_in();
    if (in_count_ < kInTransfers) {  // the device went away between claim and submit
      const std::string why = describe() + ": cannot start reading (the device is gone?)";
      device_close();
      return Error{why, {}};
    }
    return {};
  }
  if (!access_problem.empty()) return Error{access_problem, {}};
  if (matches > 0)
    return Error{"no USB device " + describe() + " with serial '" + p_.serial + "' (" + std::to_string(matches) +
                     " device(s) with that VID:PID have other serial numbers)",
                 {}};
  return Error{"no USB device " + describe() + " found (" + std::to_string(entries.size()) +
                   " USB device(s) present); is the MCU plugged in and powered? `lsusb` lists what is there",
               {}};
}

void UsbTransport::on_done(UsbTransfer& t) {
  Slot& s = *static_cast<Slot*>(t.user);
  s.in_flight = false;
  s.done = true;
  s.stamp_ns = mono_ns();
}

bool UsbTransport::submit(Slot& s, bool in) {
  s.t.length = in ? kTransferBytes : s.t.length;
  s.t.transferred = 0;
  s.done = false;
  const int rc = usb_->submit(handle_, s.t);
  if (rc == 0) {
    s.in_flight = true;
    return true;
  }
  if (rc == LIBUSB_ERROR_NO_DEVICE)
    link_failed(describe() + " unplugged (USB " + (in ? "read" : "write") + ": " + usb_->error_text(rc) + ")");
  else
    link_failed("USB " + std::string(in ? "read from " : "write to ") + describe() + " failed: " + usb_->error_text(rc));
  return false;
}

// Every IN slot not holding data is in flight.
void UsbTransport::submit_in() {
  while (in_count_ < kInTransfers) {
    Slot& s = in_[static_cast<size_t>((in_head_ + in_count_) % kInTransfers)];
    if (!submit(s, /*in=*/true)) return;
    ++in_count_;
  }
}

namespace {
const char* status_text(UsbTransferStatus s) {
  switch (s) {
    case UsbTransferStatus::kCompleted: return "completed";
    case UsbTransferStatus::kTimedOut: return "timed out";
    case UsbTransferStatus::kCancelled: return "cancelled";
    case UsbTransferStatus::kStall: return "endpoint stalled";
    case UsbTransferStatus::kNoDevice: return "LIBUSB_ERROR_NO_DEVICE";
    case UsbTransferStatus::kOverflow: return "overflow (the device sent more than asked)";
    case UsbTransferStatus::kError: return "transfer error";
  }
  return "?";
}
}  // namespace

// Completed IN transfers, oldest first (their bytes in order), into the receive queue.
void UsbTransport::process_in() {
  while (in_count_ > 0) {
    Slot& s = in_[static_cast<size_t>(in_head_)];
    if (s.done) {
      s.done = false;
      switch (s.t.status) {
        case UsbTransferStatus::kCompleted: s.holds_data = s.t.transferred > 0; break;
        case UsbTransferStatus::kTimedOut:
        case UsbTransferStatus::kCancelled: break;
        case UsbTransferStatus::kNoDevice:
          link_failed(describe() + " unplugged (USB read: LIBUSB_ERROR_NO_DEVICE)");
          return;
        default:
          link_failed("USB read from " + describe() + " failed: " + status_text(s.t.status));
          return;
      }
    } else if (!s.holds_data) {
      return;  // the oldest is still in flight
    }
    if (s.holds_data) {
      uint8_t* chunk = rx_claim();
      if (chunk == nullptr) return;  // receive queue full: the device waits (NAK) meanwhile
      const size_t n = static_cast<size_t>(std::min(s.t.transferred, static_cast<int>(kRxChunkBytes)));
      std::memcpy(chunk, s.buf, n);
      rx_commit(n, s.stamp_ns);
      s.holds_data = false;
    }
    in_head_ = (in_head_ + 1) % kInTransfers;
    --in_count_;
  }
}

void UsbTransport::process_out() {
  for (Slot& s : out_) {
    if (!s.done) continue;
    s.done = false;
    if (s.t.status == UsbTransferStatus::kCompleted && s.t.transferred == s.t.length) continue;
    if (s.t.status == UsbTransferStatus::kCancelled) continue;
    if (s.t.status == UsbTransferStatus::kNoDevice) {
      link_failed(describe() + " unplugged (USB write: LIBUSB_ERROR_NO_DEVICE)");
    } else {
      link_failed("USB write to " + describe() + " failed: " +
                  (s.t.status == UsbTransferStatus::kCompleted
                       ? std::to_string(s.t.transferred) + " of " + std::to_string(s.t.length) + " bytes sent"
                       : std::string(status_text(s.t.status))));
    }
    return;
  }
}

// Queued frames packed into free OUT transfers (whole frames, up to kTransferBytes each).
void UsbTransport::fill_out() {
  for (Slot& s : out_) {
    if (s.in_flight || s.done) continue;
    int used = 0;
    while (const TxFrame* f = tx_front()) {
      if (used + f->n > kTransferBytes) break;
      tx_departs(f->ticket);
      std::memcpy(s.buf + used, f->bytes, f->n);
      used += f->n;
      tx_pop();
    }
    if (used == 0) return;
    s.t.length = used;
    if (!submit(s, /*in=*/false)) return;
  }
  if (tx_front() != nullptr) note_tx_blocked();  // every OUT transfer pending: the device is slow
}

void UsbTransport::device_io(double max_wait_s) {
  process_in();
  process_out();
  if (!connected()) return;
  submit_in();
  fill_out();
  usb_->handle_events(max_wait_s);
  process_in();
  process_out();
  if (!connected()) return;
  submit_in();
  fill_out();
}

void UsbTransport::device_close() {
  if (handle_ == nullptr) return;
  // Every transfer in flight is cancelled and completes before the handle goes.
  for (Slot& s : in_)
    if (s.in_flight) usb_->cancel(s.t);
  for (Slot& s : out_)
    if (s.in_flight) usb_->cancel(s.t);
  const int64_t end = mono_ns() + 1'000'000'000;
  auto any_in_flight = [&] {
    for (const Slot& s : in_)
      if (s.in_flight) return true;
    for (const Slot& s : out_)
      if (s.in_flight) return true;
    return false;
  };
  while (any_in_flight() && mono_ns() < end) usb_->handle_events(0.01);
  for (Slot* group : {in_.data(), out_.data()}) {
    const int count = group == in_.data() ? kInTransfers : kOutTransfers;
    for (int i = 0; i < count; ++i) group[i].in_flight = group[i].done = group[i].holds_data = false;
  }
  in_head_ = in_count_ = 0;
  usb_->close(handle_, p_.interface_number);
  handle_ = nullptr;
}

}  // namespace feedloop::drivers
