#pragma once
// A polled device's status: one vocabulary for every front. The words are what the HTTP API,
// MQTT (the value's meta; its status topic maps them, gateway/mqtt_bridge.cpp), /metrics, the
// monitor's CSV and JSON records and the dashboard show, so they never change.
#include <iosfwd>
#include <optional>
#include <string_view>

namespace loopwire::device {

enum class DeviceStatus {
    waiting,    // not polled this sample: in back-off after failing, or not polled yet
    ok,         // every value read
    partial,    // the device answered but some values failed (exception, undecodable word)
    no_reply,   // this sample's poll timed out
    line_down,  // the link the device is on failed or is down, so it could not be asked
    stale,      // the gateway's: its last poll answered but the next is long overdue (gateway/value_cache.hpp)
    // The unit answers as another device: its identification words (client/identity_check.hpp)
    // read something else than the profile expects: its values are not shown, and nothing is
    // written to it.
    wrong_device,
};

// Every status, in declaration order.
inline constexpr DeviceStatus all_device_statuses[] = {DeviceStatus::waiting,   DeviceStatus::ok,
                                                       DeviceStatus::partial,   DeviceStatus::no_reply,
                                                       DeviceStatus::line_down, DeviceStatus::stale,
                                                       DeviceStatus::wrong_device};

// The status's word: "waiting", "ok", "partial", "no-reply", "line-down", "stale", "wrong-device".
constexpr std::string_view status_text(DeviceStatus status) {
    switch (status) {
        case DeviceStatus::waiting: return "waiting";
        case DeviceStatus::ok: return "ok";
        case DeviceStatus::partial: return "partial";
        case DeviceStatus::no_reply: return "no-reply";
        case DeviceStatus::line_down: return "line-down";
        case DeviceStatus::stale: return "stale";
        case DeviceStatus::wrong_device: return "wrong-device";
    }
    return "waiting";  // not reached: every status is handled above
}

// The status a word names; none for any other text.
std::optional<DeviceStatus> parse_device_status(std::string_view text);

// The device answered its latest poll and that poll is not overdue: its values were read (some
// may have failed). Only these can go stale (gateway/value_cache.hpp); a value such a poll did
// not give failed on its own (device::value_status).
constexpr bool answered(DeviceStatus status) { return status == DeviceStatus::ok || status == DeviceStatus::partial; }

// The poller asked for the device this sample (it may not have answered, or its line may have
// been down): false only for a device skipped in back-off, of which nothing new was learned.
constexpr bool polled(DeviceStatus status) { return status != DeviceStatus::waiting; }

// For test failure messages: the status's word.
std::ostream& operator<<(std::ostream& out, DeviceStatus status);

}  // namespace loopwire::device
