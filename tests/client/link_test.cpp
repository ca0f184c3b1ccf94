// Links as the CLI opens them (client/link.hpp): Linking links told apart, malformed URLs
// refused as usage errors before anything is opened.
#include <gtest/gtest.h>

#include "client/link.hpp"

namespace loopwire::device {
namespace {

TEST(ClientLink, TellsLinkingLinksApart) {
    auto linking = is_linking_link("linking:/dev/ttyS1?baud=9600");
    ASSERT_TRUE(linking) << linking.error().message;
    EXPECT_TRUE(*linking);
    for (const char* url : {"rtu:/dev/ttyUSB0?baud=19200&parity=even", "tcp://127.0.0.1:502", "rtu+tcp://host:4001"}) {
        auto other = is_linking_link(url);
        ASSERT_TRUE(other) << url << ": " << other.error().message;
        EXPECT_FALSE(*other) << url;
    }
}

TEST(ClientLink, AMalformedUrlIsAUsageError) {
    auto checked = is_linking_link("serial:/dev/ttyUSB0");
    ASSERT_FALSE(checked);
    EXPECT_EQ(checked.error().kind, ErrorKind::usage);
    auto checked_only = check_link_url("serial:/dev/ttyUSB0");
    ASSERT_FALSE(checked_only);
    EXPECT_EQ(checked_only.error().message, checked.error().message);
    EXPECT_TRUE(check_link_url("tcp://127.0.0.1:502"));
    auto opened = open_link("serial:/dev/ttyUSB0", {});
    ASSERT_FALSE(opened);
    EXPECT_EQ(opened.error().message, checked.error().message);
}

}  // namespace
}  // namespace loopwire::device
