// USB transport error paths (no hardware here): opening a VID:PID that is not present gives a
// clear error that names the device and says what to check; reads and writes on a closed
// transport are errors, not crashes.
#include <gtest/gtest.h>

#include "drivers/transport/usb_transport.hpp"

namespace feedloop::drivers {
namespace {

TEST(Usb, NoDeviceIsAClearError) {
  UsbParams p;
  p.vendor_id = 0xfeed;
  p.product_id = 0x0b0b;
  p.serial = "none";
  UsbTransport t(p);
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  const std::string m = st.error().message;
  std::printf("error: %s\n", m.c_str());
  // Either libusb works and finds no such device, or libusb itself is unavailable here.
  const bool no_device = m.find("no USB device usb feed:0b0b serial none") != std::string::npos &&
                         m.find("plugged in") != std::string::npos;
  const bool no_libusb = m.find("cannot initialise libusb") != std::string::npos;
  EXPECT_TRUE(no_device || no_libusb) << m;
  EXPECT_FALSE(t.connected());
  uint8_t b[4] = {1, 2, 3, 4};
  EXPECT_FALSE(t.write(b, 4).ok());
  EXPECT_FALSE(t.read(b, 4).ok());
}

TEST(Usb, ErrorCountsTheDevicesThatAreThere) {
  auto r = UsbTransport::list_devices();
  if (!r.ok()) GTEST_SKIP() << "libusb unavailable here: " << r.error().message;
  UsbParams p;
  p.vendor_id = 0xfeed;
  p.product_id = 0x0b0c;
  UsbTransport t(p);
  const Status st = t.open();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("(" + std::to_string(r->size()) + " USB device(s) present)"), std::string::npos)
      << st.error().message;
}

}  // namespace
}  // namespace feedloop::drivers
