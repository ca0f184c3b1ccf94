#include "session/linking_frame_codec.hpp"

#include <fmt/format.h>

#include "codec/linking.hpp"

namespace loopwire::session {
namespace {

using codec::FrameEvents;
using codec::LinkingCommand;

Bytes read_reply_pdu(std::uint16_t value) {
    Bytes pdu{0x03, 0x02};
    append_be16(pdu, value);
    return pdu;
}

Bytes address_value_pdu(std::uint8_t function, std::uint16_t address, std::uint16_t value) {
    Bytes pdu{function};
    append_be16(pdu, address);
    append_be16(pdu, value);
    return pdu;
}

Bytes single_write_multiple_pdu(std::uint16_t address, std::uint16_t value) {
    Bytes pdu = address_value_pdu(0x10, address, 1);
    pdu.push_back(0x02);
    append_be16(pdu, value);
    return pdu;
}

// What was last asked, so the reply (which does not name its command) can be turned back into
// the PDU the other side expects.
struct Exchange {
    LinkingCommand command = LinkingCommand::read;
    std::uint8_t function = 0x03;
    std::uint16_t address = 0;
    std::uint16_t data = 0;
};

class LinkingFrameCodec final : public FrameCodec {
public:
    LinkingFrameCodec(codec::Direction direction, bool ram_only)
        : receives_replies_(direction == codec::Direction::reply),
          ram_only_(ram_only),
          decoder_(receives_replies_) {}

    Result<Bytes> encode(std::uint8_t unit, ByteView pdu, std::uint16_t) override {
        return receives_replies_ ? encode_request(unit, pdu) : encode_reply(unit, pdu);
    }

    Result<FrameEvents> feed(ByteView bytes, Instant) override {
        FrameEvents events;
        for (auto& event : decoder_.feed(bytes)) {
            if (event.discarded) {
                events.emplace_back(codec::DiscardedBytes{*event.discarded, event.reason});
            }
            if (event.frame) events.push_back(translate(*event.frame));
        }
        return events;
    }

    void reset() override { decoder_.reset(); }

private:
    Result<Bytes> encode_request(std::uint8_t unit, ByteView pdu) {
        auto request = codec::decode_request(pdu);
        if (!request) {
            return make_error(ErrorKind::usage,
                              fmt::format("the Linking protocol carries one register read or write per "
                                          "request; this PDU is not one ({})",
                                          request.error().message));
        }
        Exchange exchange{LinkingCommand::read, request->function, request->address, 0};
        if (request->function == 0x03 && request->count == 1) {
            exchange.command = LinkingCommand::read;
        } else if (request->function == 0x06) {
            exchange.command = ram_only_ ? LinkingCommand::modify_ram : LinkingCommand::write_eeprom;
            exchange.data = request->values.at(0);
        } else if (request->function == 0x10 && request->count == 1) {
            exchange.command = LinkingCommand::write_eeprom;
            exchange.data = request->values.at(0);
        } else {
            return make_error(ErrorKind::usage,
                              fmt::format("the Linking protocol carries one register per request "
                                          "(read holding registers with quantity 1, or write one "
                                          "register); {} of {} is not possible",
                                          codec::function_name(request->function), request->count));
        }
        pending_ = exchange;
        return codec::encode_linking_request({exchange.command, unit, exchange.address, exchange.data});
    }

    Result<Bytes> encode_reply(std::uint8_t unit, ByteView pdu) {
        auto reply = codec::decode_reply(pdu);
        if (!reply) return reply.error();
        if (reply->kind == codec::ReplyKind::exception) {
            return make_error(ErrorKind::usage, "the Linking protocol has no exception reply");
        }
        std::uint16_t data = pending_.data;
        if (reply->function == 0x03 || reply->function == 0x06) data = reply->values.at(0);
        return codec::encode_linking_reply({unit, pending_.address, data});
    }

    codec::FrameEvent translate(const Bytes& frame) {
        return receives_replies_ ? translate_reply(frame) : translate_request(frame);
    }

    codec::FrameEvent translate_request(const Bytes& frame) {
        auto request = codec::decode_linking_request(frame);
        if (!request) return codec::DiscardedBytes{frame, request.error().message};
        pending_ = Exchange{request->command, 0, request->address, request->data};
        Bytes pdu;
        switch (request->command) {
            case LinkingCommand::read: pdu = address_value_pdu(0x03, request->address, 1); break;
            case LinkingCommand::modify_ram:
                pdu = address_value_pdu(0x06, request->address, request->data);
                break;
            case LinkingCommand::write_eeprom:
                pdu = single_write_multiple_pdu(request->address, request->data);
                break;
        }
        return codec::Frame{request->id, std::move(pdu), 0, frame};
    }

    codec::FrameEvent translate_reply(const Bytes& frame) {
        auto reply = codec::decode_linking_reply(frame);
        if (!reply) return codec::DiscardedBytes{frame, reply.error().message};
        if (reply->address != pending_.address) {
            return codec::DiscardedBytes{
                frame, fmt::format("Linking reply for address {} while {} was asked for",
                                   reply->address, pending_.address)};
        }
        Bytes pdu;
        if (pending_.command == LinkingCommand::read) {
            pdu = read_reply_pdu(reply->data);
        } else if (pending_.function == 0x06) {
            pdu = address_value_pdu(0x06, reply->address, reply->data);
        } else {
            pdu = address_value_pdu(0x10, reply->address, 1);
        }
        return codec::Frame{reply->id, std::move(pdu), 0, frame};
    }

    bool receives_replies_;
    bool ram_only_;
    codec::LinkingDecoder decoder_;
    Exchange pending_;
};

}  // namespace

std::unique_ptr<FrameCodec> make_linking_frame_codec(codec::Direction direction, bool ram_only_writes) {
    return std::make_unique<LinkingFrameCodec>(direction, ram_only_writes);
}

}  // namespace loopwire::session
