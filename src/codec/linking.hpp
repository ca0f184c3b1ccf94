#pragma once
// The ramp/soak controller's "Linking" protocol (its manual, chapter 6): 7-byte requests
// Command, ID, Address (2), Data (2), Sum and 8-byte replies 07h 4Dh ID Address (2) Data (2)
// Sum. The sum is the low 8 bits of the byte sum from Command through Data (the 07h header is
// not included, §6.7.1).
#include <cstdint>
#include <optional>

#include "common/bytes.hpp"
#include "common/result.hpp"

namespace loopwire::codec {

enum class LinkingCommand : std::uint8_t {
    read = 0x52,          // 'R': read a register
    modify_ram = 0x4D,    // 'M': write to RAM only, lost at power-off
    write_eeprom = 0x57,  // 'W': write to RAM and EEPROM
};

struct LinkingRequest {
    LinkingCommand command = LinkingCommand::read;
    std::uint8_t id = 1;
    std::uint16_t address = 0;
    std::uint16_t data = 0;
    bool operator==(const LinkingRequest&) const = default;
};

struct LinkingReply {
    std::uint8_t id = 1;
    std::uint16_t address = 0;
    std::uint16_t data = 0;
    bool operator==(const LinkingReply&) const = default;
};

inline constexpr std::size_t linking_request_size = 7;
inline constexpr std::size_t linking_reply_size = 8;

std::uint8_t linking_sum(ByteView bytes);

Bytes encode_linking_request(const LinkingRequest& request);
Bytes encode_linking_reply(const LinkingReply& reply);
// Exactly one frame; errors name the bad part (size, command, header, sum).
Result<LinkingRequest> decode_linking_request(ByteView frame);
Result<LinkingReply> decode_linking_reply(ByteView frame);

// Streaming decoder for either direction: fixed-size frames, resynchronising on the command
// byte (requests) or the 07h 4Dh header (replies) after noise.
struct LinkingEvent {
    std::optional<Bytes> frame;       // a frame whose sum checks
    std::optional<Bytes> discarded;   // bytes thrown away
    std::string reason;
};

class LinkingDecoder {
public:
    explicit LinkingDecoder(bool decode_replies);
    std::vector<LinkingEvent> feed(ByteView bytes);
    void reset() { buffer_.clear(); }

private:
    bool replies_;
    Bytes buffer_;
};

}  // namespace loopwire::codec
