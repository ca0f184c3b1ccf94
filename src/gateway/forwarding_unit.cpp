#include "gateway/forwarding_unit.hpp"

#include <array>
#include <algorithm>
#include <future>

#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

constexpr std::uint8_t exception_flag = 0x80;
constexpr std::uint8_t illegal_function = 0x01;
constexpr std::uint8_t target_failed_to_respond = 0x0B;

// Modbus application protocol V1.1b3, 6: read coils, discrete inputs, holding and input
// registers (1-4), read exception status (7), get comm event counter and log (11, 12), report
// server id (17), read file record (20), read FIFO queue (24), encapsulated interface /
// device identification (43). Everything else may change the device, user-defined codes
// included (nobody can tell what they do), so a read-only gateway refuses it.
constexpr std::array<std::uint8_t, 11> reading_functions{1, 2, 3, 4, 7, 11, 12, 17, 20, 24, 43};

Bytes exception_reply(std::uint8_t function, std::uint8_t code) {
    return Bytes{static_cast<std::uint8_t>(function | exception_flag), code};
}

}  // namespace

bool only_reads(std::uint8_t function) {
    return std::find(reading_functions.begin(), reading_functions.end(), function) != reading_functions.end();
}

Bytes failure_reply(std::uint8_t function, const Error& why) {
    return exception_reply(function, why.kind == ErrorKind::usage ? illegal_function : target_failed_to_respond);
}

ForwardingUnit::ForwardingUnit(std::shared_ptr<LineScheduler> line, ForwardingSettings settings,
                               std::shared_ptr<Clock> clock, GatewayLog log)
    : line_(std::move(line)), settings_(settings), clock_(std::move(clock)), log_(std::move(log)) {}

std::optional<Bytes> ForwardingUnit::refusal(ByteView request_pdu) const {
    if (settings_.writes_allowed || only_reads(request_pdu[0])) return std::nullopt;
    if (log_) {
        log_(fmt::format("refused function {} to unit {}: this gateway is read-only (modbus_tcp.writes = false)",
                         request_pdu[0], settings_.line_unit));
    }
    return exception_reply(request_pdu[0], illegal_function);
}

void ForwardingUnit::handle_async(Bytes request_pdu, bool broadcast, Origin origin, ReplyCallback reply) {
    if (request_pdu.empty()) return reply(std::nullopt);
    if (auto refused = refusal(request_pdu)) return reply(broadcast ? std::nullopt : std::move(refused));
    if (broadcast && !settings_.carries_broadcasts) return reply(std::nullopt);
    const std::uint8_t function = request_pdu[0];
    LineRequest request;
    request.unit = broadcast ? std::uint8_t{0} : settings_.line_unit;
    request.priority = only_reads(function) ? Priority::client : Priority::write;
    request.pdu = std::move(request_pdu);
    request.client = origin;
    request.deadline = clock_->now() + settings_.queue_limit;
    request.done = [function, broadcast, reply = std::move(reply)](Result<Bytes> answered) {
        if (broadcast) return reply(std::nullopt);  // nobody answers a broadcast (2.1 of the serial spec)
        reply(answered ? std::move(*answered) : failure_reply(function, answered.error()));
    };
    line_->submit(std::move(request));
}

std::optional<Bytes> ForwardingUnit::handle(ByteView request_pdu, bool broadcast) {
    std::promise<std::optional<Bytes>> answered;
    auto future = answered.get_future();
    handle_async(Bytes(request_pdu.begin(), request_pdu.end()), broadcast, 0,
                 [&answered](std::optional<Bytes> reply) { answered.set_value(std::move(reply)); });
    return future.get();
}

}  // namespace loopwire::gateway
