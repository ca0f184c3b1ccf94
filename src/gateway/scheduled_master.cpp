#include "gateway/scheduled_master.hpp"

#include <future>

#include "session/reply_check.hpp"

namespace loopwire::gateway {

ScheduledMaster::ScheduledMaster(std::shared_ptr<LineScheduler> line, std::string name, Priority priority,
                                 std::chrono::milliseconds request_limit, std::shared_ptr<Clock> clock)
    : line_(std::move(line)), name_(std::move(name)), priority_(priority), request_limit_(request_limit), clock_(std::move(clock)) {}

void ScheduledMaster::forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) {
    LineRequest request;
    request.unit = unit;
    request.pdu = std::move(pdu);
    request.priority = priority_;
    request.deadline = clock_->now() + request_limit_;
    request.done = std::move(done);
    line_->submit(std::move(request));
}

Result<Bytes> ScheduledMaster::forward(std::uint8_t unit, ByteView pdu) {
    std::promise<Result<Bytes>> answered;
    auto future = answered.get_future();
    forward_async(unit, Bytes(pdu.begin(), pdu.end()), [&answered](Result<Bytes> reply) { answered.set_value(std::move(reply)); });
    return future.get();
}

// The line's master checked that the reply answers the PDU; the typed request is decoded from
// it as the line's own master would (session/reply_check.hpp).
void ScheduledMaster::execute_async(std::uint8_t unit, codec::Request request, Completion done) {
    auto pdu = codec::encode_request(request);
    if (!pdu) return done(pdu.error());
    forward_async(unit, std::move(*pdu), [unit, request = std::move(request), done = std::move(done)](Result<Bytes> answered) {
        done(session::typed_reply(unit, request, std::move(answered)));
    });
}

Result<codec::Reply> ScheduledMaster::execute(std::uint8_t unit, const codec::Request& request) {
    std::promise<Result<codec::Reply>> answered;
    auto future = answered.get_future();
    execute_async(unit, request, [&answered](Result<codec::Reply> reply) { answered.set_value(std::move(reply)); });
    return future.get();
}

}  // namespace loopwire::gateway
