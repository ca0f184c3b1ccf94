#pragma once
// One simulated controller served from its profile: the rules the profile data states
// (function codes, per-request limits, unmapped addresses, mirrors, read-only words, ranges,
// special values, broadcast). Device behaviour the data cannot express (AC20 modes and locks,
// TC10 alarms, the ramp/soak program) belongs in a subclass that overrides the hooks below.
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>

#include "device/device_memory.hpp"
#include "device/profile.hpp"
#include "session/unit_handler.hpp"

namespace loopwire::device {

class SimulatedDevice : public session::RequestHandler {
public:
    explicit SimulatedDevice(std::shared_ptr<const Profile> profile);

    // Silence and limits come before decoding: the AC20 says nothing at all to a function
    // code it does not implement, and a count over a device's limit gets its own exception.
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override;

    const Profile& profile() const { return *profile_; }

protected:
    codec::Reply serve(const codec::Request& request) override;

    // Hooks for per-device models, called with the device locked.
    // An exception code to refuse a write the profile's rules allow (modes, locks), or nullopt.
    virtual std::optional<std::uint8_t> accept_write(const Parameter& parameter, std::uint16_t raw,
                                                     const RawValues& known);
    // What a read returns for a stored word (process values, bits that clear when read).
    virtual std::uint16_t on_read(const Parameter& parameter, std::uint16_t stored);
    // After a write has been stored.
    virtual void after_write(const Parameter& parameter, std::uint16_t raw);

private:
    std::optional<Bytes> refuse(std::uint8_t function, std::uint8_t code) const;
    std::optional<std::uint8_t> over_limit(ByteView request_pdu) const;
    Table table_for(std::uint8_t function) const;
    codec::Reply read(const codec::Request& request);
    codec::Reply write(const codec::Request& request);

    std::shared_ptr<const Profile> profile_;
    DeviceMemory memory_;
    std::mutex mutex_;  // one device, several links or TCP connections
};

}  // namespace loopwire::device
