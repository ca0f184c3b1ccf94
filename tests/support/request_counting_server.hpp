#pragma once
// A Modbus TCP server for tests of how requests reach a device: it reads until it has `count`
// requests, noting how many bytes each read brought (one read of all of them: they came in one
// write), then answers each with its start address as the value, and hands the connection over
// for the test to keep open while the master reads.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <vector>

#include "codec/pdu.hpp"
#include "codec/tcp.hpp"
#include "session/master.hpp"
#include "transport/tcp.hpp"

namespace loopwire::testing {

struct ServedRequests {
    std::vector<std::size_t> reads;  // the bytes each read brought
    // Open while the test holds it: the master reads the replies before the connection closes.
    std::unique_ptr<transport::ByteStream> connection;
};

inline ServedRequests serve_requests(transport::TcpListener& listener, std::size_t count) {
    ServedRequests served;
    std::vector<std::size_t>& reads = served.reads;
    auto client = listener.accept(std::chrono::seconds(5));
    if (!client.ok() || !*client) return served;
    codec::MbapDecoder decoder;
    std::vector<codec::Frame> requests;
    std::array<std::uint8_t, 1024> buffer{};
    while (requests.size() < count) {
        auto n = (*client)->read_some(buffer, std::chrono::seconds(5));
        if (!n.ok() || *n == 0) return served;
        reads.push_back(*n);
        auto frames = decoder.feed(ByteView(buffer.data(), *n));
        if (!frames.ok()) return served;
        requests.insert(requests.end(), frames->begin(), frames->end());
    }
    Bytes replies;
    for (const auto& request : requests) {
        auto decoded = codec::decode_request(request.pdu);
        if (!decoded.ok()) return served;
        auto pdu = codec::encode_reply({3, codec::ReplyKind::normal, 0, decoded->address, 1, {decoded->address}});
        const Bytes frame = codec::mbap_encode(request.transaction, request.unit, *pdu);
        replies.insert(replies.end(), frame.begin(), frame.end());
    }
    (void)(*client)->write(replies);
    served.connection = std::move(*client);
    return served;
}

// `count` reads of one register each, at addresses from `first`, sent on a master all from one
// handler of a loop, as a round of the gateway's handlers sends them; then their replies checked
// against what serve_requests answers (each its own address).
class RoundOfReads {
public:
    RoundOfReads(std::uint16_t first, std::size_t count) : first_(first), replies_(count) {}

    // The handler that sends them, for the loop to run.
    std::function<void()> sender(session::Master& master) {
        return [this, &master] {
            for (std::size_t i = 0; i < replies_.size(); ++i) {
                const auto address = static_cast<std::uint16_t>(first_ + i);
                master.execute_async(1, codec::read_request(codec::FunctionCode::read_holding_registers, address, 1),
                                     [this, i](Result<codec::Reply> reply) { replies_[i].set_value(std::move(reply)); });
            }
        };
    }

    void expect_answered() {
        for (std::size_t i = 0; i < replies_.size(); ++i) {
            auto reply = replies_[i].get_future().get();
            ASSERT_TRUE(reply.ok()) << reply.error().message;
            EXPECT_EQ(reply->values.at(0), first_ + i);
        }
    }

private:
    std::uint16_t first_;
    std::vector<std::promise<Result<codec::Reply>>> replies_;
};

}  // namespace loopwire::testing
