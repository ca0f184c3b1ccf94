#pragma once
// Which client addresses may use a front: `[modbus_tcp] allow` and `write_allow`, `[http] allow`.
// Entries are networks in CIDR notation ("10.1.0.0/16", "fd00::/8") or single addresses
// ("192.168.1.20", "::1"). An empty list lets every address in: the fronts listen on loopback
// unless configured otherwise, and a list is what a site adds when it opens them wider.
#include <string>
#include <string_view>
#include <vector>

#include <boost/asio/ip/address.hpp>
#include <boost/asio/ip/network_v4.hpp>
#include <boost/asio/ip/network_v6.hpp>

#include "common/result.hpp"

namespace loopwire::transport {

class AddressAllowList {
public:
    AddressAllowList() = default;  // empty: every address

    // The list from its entries; an error names the entry that is not a network or an address.
    static Result<AddressAllowList> parse(const std::vector<std::string>& entries);

    bool empty() const { return v4_.empty() && v6_.empty(); }
    // Whether `address` is in one of the networks. An IPv4 client reaching a dual-stack
    // listener arrives as ::ffff:a.b.c.d and is matched against the IPv4 entries.
    bool allows(const boost::asio::ip::address& address) const;

    bool operator==(const AddressAllowList&) const = default;

private:
    std::vector<boost::asio::ip::network_v4> v4_;
    std::vector<boost::asio::ip::network_v6> v6_;
};

// One entry alone: a network, or an address as the network of that address only.
Result<void> check_allow_entry(std::string_view entry);

}  // namespace loopwire::transport
