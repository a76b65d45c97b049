#include "web/access.hpp"

#include <boost/asio/ip/network_v4.hpp>
#include <boost/asio/ip/network_v6.hpp>

namespace feedloop::web {

namespace ip = boost::asio::ip;

Result<AccessPolicy> AccessPolicy::create(const std::vector<std::string>& trusted,
                                          std::string api_key) {
  AccessPolicy p;
  p.api_key_ = std::move(api_key);
  for (const std::string& t : trusted) {
    boost::system::error_code ec;
    Range r;
    if (t.find('/') == std::string::npos) {
      r.base = ip::make_address(t, ec);
      r.prefix = r.base.is_v4() ? 32 : 128;
    } else if (t.find(':') != std::string::npos) {
      const ip::network_v6 n = ip::make_network_v6(t, ec);
      if (!ec) r = Range{n.network(), n.prefix_length()};
    } else {
      const ip::network_v4 n = ip::make_network_v4(t, ec);
      if (!ec) r = Range{n.network(), n.prefix_length()};
    }
    if (ec) return Error{"web.trusted_clients: '" + t + "' is not an address range"};
    p.ranges_.push_back(r);
  }
  return p;
}

namespace {
bool in_range(const ip::address_v6::bytes_type& a, const ip::address_v6::bytes_type& base,
              unsigned prefix) {
  for (unsigned bit = 0; bit < prefix; ++bit) {
    const unsigned byte = bit / 8, mask = 0x80u >> (bit % 8);
    if ((a[byte] & mask) != (base[byte] & mask)) return false;
  }
  return true;
}
ip::address_v6 as_v6(const ip::address& a) {
  return a.is_v6() ? a.to_v6() : ip::make_address_v6(ip::v4_mapped, a.to_v4());
}
}  // namespace

bool AccessPolicy::allowed(const ip::address& remote, std::string_view api_key) const {
  if (remote.is_loopback() || (remote.is_v6() && remote.to_v6().is_v4_mapped() &&
                               ip::make_address_v4(ip::v4_mapped, remote.to_v6()).is_loopback()))
    return true;
  if (!api_key_.empty() && api_key == api_key_) return true;
  const auto a = as_v6(remote).to_bytes();
  for (const Range& r : ranges_) {
    const unsigned prefix = r.base.is_v4() ? r.prefix + 96 : r.prefix;
    if (in_range(a, as_v6(r.base).to_bytes(), prefix)) return true;
  }
  return false;
}

}  // namespace feedloop::web
