// Who may use the web server (Moonraker's [authorization]: trusted_clients and the API key).
#pragma once

#include <boost/asio/ip/address.hpp>

#include <string>
#include <string_view>
#include <vector>

#include "core/result.hpp"

namespace feedloop::web {

class AccessPolicy {
 public:
  // `trusted`: CIDR ranges ("192.168.1.0/24", "::1/128") or single addresses.
  static Result<AccessPolicy> create(const std::vector<std::string>& trusted, std::string api_key);
  // Loopback is always trusted (as Moonraker does for local clients). Others need a trusted range
  // or the API key (X-Api-Key header, or ?token= in the URL for WebSocket upgrades).
  bool allowed(const boost::asio::ip::address& remote, std::string_view api_key) const;

 private:
  struct Range {
    boost::asio::ip::address base;
    unsigned prefix = 0;
  };
  std::vector<Range> ranges_;
  std::string api_key_;
};

}  // namespace feedloop::web
