// A device's status and its one vocabulary (client/device_status.hpp): the words every front
// shows (API, MQTT, /metrics, CSV, dashboard) are fixed, and each reads back as its status.
#include <gtest/gtest.h>

#include <set>
#include <sstream>
#include <string>
#include <string_view>

#include "client/device_status.hpp"

namespace loopwire::device {
namespace {

TEST(DeviceStatus, EachStatusHasItsFixedWord) {
    EXPECT_EQ(status_text(DeviceStatus::waiting), "waiting");
    EXPECT_EQ(status_text(DeviceStatus::ok), "ok");
    EXPECT_EQ(status_text(DeviceStatus::partial), "partial");
    EXPECT_EQ(status_text(DeviceStatus::no_reply), "no-reply");
    EXPECT_EQ(status_text(DeviceStatus::line_down), "line-down");
    EXPECT_EQ(status_text(DeviceStatus::stale), "stale");
    EXPECT_EQ(status_text(DeviceStatus::wrong_device), "wrong-device");
}

TEST(DeviceStatus, EveryWordReadsBackAsItsStatus) {
    std::set<std::string_view> words;
    for (const DeviceStatus status : all_device_statuses) {
        const auto parsed = parse_device_status(status_text(status));
        ASSERT_TRUE(parsed.has_value()) << status_text(status);
        EXPECT_EQ(*parsed, status) << status_text(status);
        words.insert(status_text(status));
    }
    EXPECT_EQ(words.size(), std::size(all_device_statuses)) << "two statuses share a word";
    EXPECT_EQ(words, (std::set<std::string_view>{"waiting", "ok", "partial", "no-reply", "line-down", "stale", "wrong-device"}));
}

TEST(DeviceStatus, OtherTextIsNoStatus) {
    for (const std::string_view text : {"", "OK", "no_reply", "line down", "online", "error", "under-range", "ok "}) {
        EXPECT_FALSE(parse_device_status(text).has_value()) << '"' << text << '"';
    }
}

TEST(DeviceStatus, AnsweredAndPolled) {
    for (const DeviceStatus status : all_device_statuses) {
        EXPECT_EQ(answered(status), status == DeviceStatus::ok || status == DeviceStatus::partial) << status;
        EXPECT_EQ(polled(status), status != DeviceStatus::waiting) << status;
    }
}

TEST(DeviceStatus, PrintsAsItsWord) {
    std::ostringstream out;
    out << DeviceStatus::no_reply;
    EXPECT_EQ(out.str(), "no-reply");
}

}  // namespace
}  // namespace loopwire::device
