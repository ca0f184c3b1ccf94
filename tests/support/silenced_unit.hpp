#pragma once
// A unit that stops answering, for tests of what one line's trouble does to another: while
// silenced, every request the gateway writes to the unit is lost on the bus (the device never
// hears it), so its line waits out the line's timeout for each, as with a device that is gone or
// far slower than its timeout. Lost, not held back: the thread that writes a line's requests is
// the lines' loop (session/line_loop.hpp), shared by every line, so a fault injector that made
// it wait would hold every line, which no device can do. Declare it before the gateway that
// uses it.
#include <cstdint>
#include <mutex>
#include <string>

#include "transport/virtual_bus.hpp"

namespace loopwire::support {

class SilencedUnit {
public:
    explicit SilencedUnit(std::uint8_t unit) : unit_(unit) {}

    // For GatewayOptions::virtual_bus_faults.
    transport::FaultInjector injector() {
        return [this](const std::string& from, ByteView bytes) {
            transport::BusFault fault;
            if (from == "gateway" && !bytes.empty() && bytes[0] == unit_) {
                std::lock_guard lock(mutex_);
                fault.drop = silenced_;
                if (silenced_) ++lost_;
            }
            return fault;
        };
    }

    void silence() {
        std::lock_guard lock(mutex_);
        silenced_ = true;
    }
    void answer_again() {
        std::lock_guard lock(mutex_);
        silenced_ = false;
    }
    // Requests to the unit lost since it was first silenced: its line has been kept waiting.
    int lost() {
        std::lock_guard lock(mutex_);
        return lost_;
    }

private:
    std::uint8_t unit_;
    std::mutex mutex_;
    bool silenced_ = false;
    int lost_ = 0;
};

}  // namespace loopwire::support
