#pragma once
// A gate on a simulated line's replies, for tests of what one line's trouble does to another:
// while held, every reply of the given unit from the gateway's simulated devices waits (the
// fault injector runs outside the virtual bus's lock and may take its time), so the requests
// to that unit stay on the wire until the test releases them. Declare it before the gateway
// that uses it, and a HeldReplies::Release after the gateway, so the gate opens before the
// gateway stops whatever way the test ends.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>

#include "transport/virtual_bus.hpp"

namespace loopwire::support {

class HeldReplies {
public:
    explicit HeldReplies(std::uint8_t unit) : unit_(unit) {}

    // For GatewayOptions::virtual_bus_faults. A reply waits at most `longest`: a test that
    // forgets to release ends, slowly, rather than hangs.
    transport::FaultInjector injector(std::chrono::seconds longest = std::chrono::seconds(60)) {
        return [this, longest](const std::string& from, ByteView bytes) {
            if (from == "simulated devices" && !bytes.empty() && bytes[0] == unit_) {
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
    // Whether a reply is waiting at the gate now: a request of the unit is on the wire.
    bool holding_a_reply() {
        std::lock_guard lock(mutex_);
        return waiting_ > 0;
    }

    struct Release {
        HeldReplies& gate;
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
