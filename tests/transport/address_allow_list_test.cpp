#include "transport/address_allow_list.hpp"

#include <gtest/gtest.h>

namespace loopwire::transport {
namespace {

namespace ip = boost::asio::ip;

AddressAllowList list_of(const std::vector<std::string>& entries) {
    auto list = AddressAllowList::parse(entries);
    EXPECT_TRUE(list) << (list ? "" : list.error().message);
    return list ? *list : AddressAllowList{};
}

TEST(AddressAllowList, EmptyLetsEveryAddressIn) {
    const AddressAllowList list;
    EXPECT_TRUE(list.allows(ip::make_address("203.0.113.9")));
    EXPECT_TRUE(list.allows(ip::make_address("2001:db8::1")));
}

TEST(AddressAllowList, Ipv4NetworksAndSingleAddresses) {
    const auto list = list_of({"10.1.0.0/16", "192.168.1.20"});
    EXPECT_TRUE(list.allows(ip::make_address("10.1.0.1")));
    EXPECT_TRUE(list.allows(ip::make_address("10.1.255.254")));
    EXPECT_FALSE(list.allows(ip::make_address("10.2.0.1")));
    EXPECT_TRUE(list.allows(ip::make_address("192.168.1.20")));
    EXPECT_FALSE(list.allows(ip::make_address("192.168.1.21")));
    EXPECT_FALSE(list.allows(ip::make_address("::1"))) << "an IPv6 client matches only IPv6 entries";
}

TEST(AddressAllowList, LoopbackOneAddressNotTheNext) {
    const auto list = list_of({"127.0.0.1/32"});
    EXPECT_TRUE(list.allows(ip::make_address("127.0.0.1")));
    EXPECT_FALSE(list.allows(ip::make_address("127.0.0.2")));
}

TEST(AddressAllowList, Ipv6NetworksOnOddPrefixes) {
    const auto list = list_of({"fd00::/8", "2001:db8:abcd:12::/63"});
    EXPECT_TRUE(list.allows(ip::make_address("fd12:3456::1")));
    EXPECT_FALSE(list.allows(ip::make_address("fe80::1")));
    EXPECT_TRUE(list.allows(ip::make_address("2001:db8:abcd:13::7"))) << "/63 holds ...:12:: and ...:13::";
    EXPECT_FALSE(list.allows(ip::make_address("2001:db8:abcd:14::7")));
}

TEST(AddressAllowList, MappedIpv4ClientsMatchIpv4Entries) {
    const auto list = list_of({"10.0.0.0/8"});
    EXPECT_TRUE(list.allows(ip::make_address("::ffff:10.9.8.7")));
    EXPECT_FALSE(list.allows(ip::make_address("::ffff:11.9.8.7")));
}

TEST(AddressAllowList, HostBitsBelowThePrefixNameTheirNetwork) {
    const auto list = list_of({"10.1.2.3/16"});
    EXPECT_TRUE(list.allows(ip::make_address("10.1.200.1")));
}

TEST(AddressAllowList, ZeroPrefixIsEveryAddressOfItsFamily) {
    const auto list = list_of({"0.0.0.0/0"});
    EXPECT_TRUE(list.allows(ip::make_address("198.51.100.1")));
    EXPECT_FALSE(list.allows(ip::make_address("2001:db8::1")));
}

TEST(AddressAllowList, MalformedEntriesAreNamed) {
    for (const std::string bad : {"10.1.0.0/33", "10.1.0", "plant-net", "fd00::/129", "", "10.0.0.0/8/8"}) {
        auto list = AddressAllowList::parse({"127.0.0.1", bad});
        ASSERT_FALSE(list) << bad;
        EXPECT_NE(list.error().message.find("\"" + bad + "\""), std::string::npos) << list.error().message;
        EXPECT_NE(list.error().message.find("CIDR"), std::string::npos);
    }
}

}  // namespace
}  // namespace loopwire::transport
