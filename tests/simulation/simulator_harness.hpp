#pragma once
// Device-side tests go through the wire (docs/DESIGN.md): a request is encoded, the simulator
// answers through handle(), the reply is decoded. The harness owns the simulator (the
// device's behaviour model, from models::make_simulated_device) and a clock the test moves by
// hand, so timeouts and the process are deterministic.
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "codec/pdu.hpp"
#include "common/bytes.hpp"
#include "devices/registry.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device::testing {

using Words = std::vector<std::uint16_t>;

// A clock that moves only when told; shared with the simulator through the environment.
struct ManualClock {
    std::shared_ptr<SimulationClock::time_point> time = std::make_shared<SimulationClock::time_point>();
    std::function<SimulationClock::time_point()> function() const {
        return [time = time] { return *time; };
    }
    void advance(double seconds) {
        *time += std::chrono::duration_cast<SimulationClock::duration>(std::chrono::duration<double>(seconds));
    }
};

// Which simulator: the device's behaviour model, or only the rules its profile states.
enum class Model { behaviour, profile_only };

class Simulated {
public:
    explicit Simulated(const std::string& id, Model model = Model::behaviour, SimulationEnvironment environment = {})
        : clock_(), device_(make(id, std::move(environment), model)) {}

    // The reply PDU's bytes as hex ("86 03"), or "silence".
    std::string send(const codec::Request& request, bool broadcast = false) {
        auto pdu = codec::encode_request(request);
        EXPECT_TRUE(pdu.ok());
        return send_pdu(*pdu, broadcast);
    }
    std::string send_pdu(const Bytes& pdu, bool broadcast = false) {
        auto reply = device_->handle(pdu, broadcast);
        return reply ? to_hex(*reply) : "silence";
    }
    Words read(std::uint16_t address, std::uint16_t count,
               codec::FunctionCode function = codec::FunctionCode::read_holding_registers) {
        auto pdu = device_->handle(*codec::encode_request(codec::read_request(function, address, count)), false);
        if (!pdu) return {};
        auto reply = codec::decode_reply(*pdu);
        EXPECT_TRUE(reply.ok() && reply->kind == codec::ReplyKind::normal) << to_hex(*pdu);
        if (!reply.ok() || reply->kind != codec::ReplyKind::normal) return {};
        reply->values.resize(count);
        return reply->values;
    }
    std::uint16_t word(std::uint16_t address) {
        auto words = read(address, 1);
        return words.empty() ? 0xDEAD : words[0];
    }
    bool bit(std::uint16_t address) {
        auto bits = read(address, 1, codec::FunctionCode::read_coils);
        return !bits.empty() && bits[0] != 0;
    }
    // The hex reply to writing one word (FC6), for comparison with echo_of().
    std::string write(std::uint16_t address, std::uint16_t raw) { return send(codec::write_single_register(address, raw)); }

    // Moves the clock the simulator sees; the process catches up at the next request.
    void wait(double seconds) { clock_.advance(seconds); }

    SimulatedDevice& device() { return *device_; }

private:
    std::shared_ptr<SimulatedDevice> make(const std::string& id, SimulationEnvironment environment, Model model) {
        environment.now = clock_.function();
        auto profile = builtin(id);
        if (model == Model::profile_only) return std::make_shared<SimulatedDevice>(profile, std::move(environment));
        return models::make_simulated_device(profile, std::move(environment));
    }

    ManualClock clock_;
    std::shared_ptr<SimulatedDevice> device_;
};

// The normal reply to `request`: writes echo address and value (FC5/6) or quantity (FC15/16).
inline std::string echo_of(const codec::Request& request) {
    codec::Reply reply{request.function, codec::ReplyKind::normal, 0, request.address, request.count, {}};
    if (request.function == 5 || request.function == 6) reply.values = request.values;
    return to_hex(*codec::encode_reply(reply));
}

inline std::uint16_t raw(int value) { return static_cast<std::uint16_t>(static_cast<std::int16_t>(value)); }

}  // namespace loopwire::device::testing
