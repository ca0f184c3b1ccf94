#include "transport/address_allow_list.hpp"

#include <algorithm>
#include <optional>

#include <fmt/format.h>

namespace loopwire::transport {
namespace {

namespace ip = boost::asio::ip;

struct Parsed {
    std::optional<ip::network_v4> v4;
    std::optional<ip::network_v6> v6;
};

// "a.b.c.d/n", "x::y/n", or a bare address (a /32 or /128). Host bits set below the prefix
// ("10.1.2.3/16") are taken as the network they belong to, as ip(8) and most firewalls do.
Result<Parsed> parse_entry(std::string_view text) {
    const std::string entry(text);
    boost::system::error_code error;
    const bool has_prefix = entry.find('/') != std::string::npos;
    if (entry.find(':') == std::string::npos) {
        auto network = has_prefix ? ip::make_network_v4(entry, error) : ip::network_v4(ip::make_address_v4(entry, error), 32);
        if (!error) return Parsed{network.canonical(), std::nullopt};
    } else {
        auto network = has_prefix ? ip::make_network_v6(entry, error) : ip::network_v6(ip::make_address_v6(entry, error), 128);
        if (!error) return Parsed{std::nullopt, network.canonical()};
    }
    return make_error(ErrorKind::usage,
                      fmt::format("\"{}\" is not an address or a network: write an IPv4 or IPv6 address, or a network "
                                  "in CIDR notation such as \"10.1.0.0/16\" or \"fd00::/8\"",
                                  entry));
}

bool in(const ip::network_v4& network, const ip::address_v4& address) {
    if (network.prefix_length() == 0) return true;
    const auto mask = network.netmask().to_uint();
    return (address.to_uint() & mask) == network.network().to_uint();
}

bool in(const ip::network_v6& network, const ip::address_v6& address) {
    const auto net = network.network().to_bytes();
    const auto bytes = address.to_bytes();
    unsigned left = network.prefix_length();
    for (std::size_t i = 0; i < bytes.size() && left > 0; ++i) {
        const unsigned bits = std::min(left, 8U);
        const auto mask = static_cast<std::uint8_t>(0xFF << (8 - bits));
        if ((bytes[i] & mask) != (net[i] & mask)) return false;
        left -= bits;
    }
    return true;
}

}  // namespace

Result<AddressAllowList> AddressAllowList::parse(const std::vector<std::string>& entries) {
    AddressAllowList list;
    for (const auto& entry : entries) {
        auto parsed = parse_entry(entry);
        if (!parsed) return parsed.error();
        if (parsed->v4) list.v4_.push_back(*parsed->v4);
        if (parsed->v6) list.v6_.push_back(*parsed->v6);
    }
    return list;
}

bool AddressAllowList::allows(const ip::address& address) const {
    if (empty()) return true;
    if (address.is_v6() && address.to_v6().is_v4_mapped()) {
        return allows(ip::make_address_v4(ip::v4_mapped, address.to_v6()));
    }
    if (address.is_v4()) {
        return std::any_of(v4_.begin(), v4_.end(), [&](const auto& network) { return in(network, address.to_v4()); });
    }
    return std::any_of(v6_.begin(), v6_.end(), [&](const auto& network) { return in(network, address.to_v6()); });
}

Result<void> check_allow_entry(std::string_view entry) {
    auto parsed = parse_entry(entry);
    if (!parsed) return parsed.error();
    return {};
}

}  // namespace loopwire::transport
