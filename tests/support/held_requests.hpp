#pragma once
// A gate on a line's requests to one unit, for tests of what one line's trouble does to another:
// while held, every request the gateway writes to the given unit waits at its line (the fault
// injector runs in the writing thread, outside the virtual bus's lock, and may take its time),
// so that line stays busy with it until the test releases it, as with a device that takes its
// time to answer. The request is held and not the reply: the simulated devices of every virtual
// line answer from one shared thread (simulation/simulated_lines.hpp), which a held reply would
// hold for every line. Declare it before the gateway that uses it, and a
// HeldRequests::Release after the gateway, so the gate opens before the gateway stops whatever
// way the test ends.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>

#include "transport/virtual_bus.hpp"

namespace loopwire::support {

class HeldRequests {
public:
    explicit HeldRequests(std::uint8_t unit) : unit_(unit) {}

    // For GatewayOptions::virtual_bus_faults. A request waits at most `longest`: a test that
    // forgets to release ends, slowly, rather than hangs.
    transport::FaultInjector injector(std::chrono::seconds longest = std::chrono::seconds(60)) {
        return [this, longest](const std::string& from, ByteView bytes) {
            if (from == "gateway" && !bytes.empty() && bytes[0] == unit_) {
                std::unique_lock lock(mutex_);
                if (held_) ++waiting_;
                opened_.wait_for(lock, longest, [this] { return !held_; });
                if (waiting_ > 0) --waiting_;
            }
            return transport::BusFault{};
        };
    }

    void hold() {
        std::lock_guard lock(mutex_);
        held_ = true;
    }
    void release() {
        {
            std::lock_guard lock(mutex_);
            held_ = false;
        }
        opened_.notify_all();
    }
    // Whether a request to the unit is waiting at the gate now: its line is busy with it.
    bool holding_a_request() {
        std::lock_guard lock(mutex_);
        return waiting_ > 0;
    }

    struct Release {
        HeldRequests& gate;
        ~Release() { gate.release(); }
    };

private:
    std::uint8_t unit_;
    std::mutex mutex_;
    std::condition_variable opened_;
    bool held_ = false;
    int waiting_ = 0;
};

}  // namespace loopwire::support
