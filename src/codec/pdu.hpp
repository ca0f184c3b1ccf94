#pragma once
// Modbus PDUs (function code + data) for function codes 1, 2, 3, 4, 5, 6, 15 and 16:
// requests, normal replies and exception replies, with full validation. Sans-I/O: pure
// functions of bytes.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/bytes.hpp"
#include "common/result.hpp"

namespace loopwire::codec {

enum class FunctionCode : std::uint8_t {
    read_coils = 1,
    read_discrete_inputs = 2,
    read_holding_registers = 3,
    read_input_registers = 4,
    write_single_coil = 5,
    write_single_register = 6,
    write_multiple_coils = 15,
    write_multiple_registers = 16,
};

bool is_supported_function(std::uint8_t function);
// "read holding registers" etc.; "function 43" for codes loopwire does not know.
std::string function_name(std::uint8_t function);

// Standard exception codes loopwire names. Other codes (AC20: 9, 10, 50-55, 101-208) are kept
// as plain numbers for device profiles to name.
enum class ExceptionCode : std::uint8_t {
    illegal_function = 1,
    illegal_data_address = 2,
    illegal_data_value = 3,
    server_device_failure = 4,
    acknowledge = 5,
    server_device_busy = 6,
};
// "illegal data address" for the named codes, std::nullopt for the rest.
std::optional<std::string> exception_name(std::uint8_t code);
// "2 (illegal data address)" or "101" — for messages.
std::string describe_exception(std::uint8_t code);

// Limits of the Modbus application protocol (V1.1b3, 6.x): what a valid PDU may carry.
inline constexpr std::uint16_t max_read_bits = 2000;
inline constexpr std::uint16_t max_read_registers = 125;
inline constexpr std::uint16_t max_write_bits = 1968;
inline constexpr std::uint16_t max_write_registers = 123;
inline constexpr std::size_t max_pdu_size = 253;

enum class Direction { request, reply };

// A request as the master means it. For reads, `values` is empty. For writes, `values` holds
// the register values, or the coil states as 0/1; `count` equals values.size().
// For FC5 the single coil state is values[0] (0 or 1); for FC6 the register is values[0].
struct Request {
    std::uint8_t function = 0;
    std::uint16_t address = 0;
    std::uint16_t count = 0;
    std::vector<std::uint16_t> values;

    bool operator==(const Request&) const = default;
};

enum class ReplyKind { normal, exception };

// A reply. For FC1/2 `values` holds byte_count*8 bit states (padding included: a reply does not
// say how many were asked for; match_reply() trims to the request). For FC3/4 the registers.
// For FC5/6 address and values[0] echo the request (FC5 values[0] is 0/1). For FC15/16 address
// and count echo the request and values is empty. For exceptions only `exception_code` counts.
struct Reply {
    std::uint8_t function = 0;  // without the 80h exception flag
    ReplyKind kind = ReplyKind::normal;
    std::uint8_t exception_code = 0;
    std::uint16_t address = 0;
    std::uint16_t count = 0;
    std::vector<std::uint16_t> values;

    bool operator==(const Reply&) const = default;
};

// Builders for the common requests; they do not validate (encode_request does).
Request read_request(FunctionCode function, std::uint16_t address, std::uint16_t count);
Request write_single_coil(std::uint16_t address, bool on);
Request write_single_register(std::uint16_t address, std::uint16_t value);
Request write_multiple_coils(std::uint16_t address, std::vector<std::uint16_t> states);
Request write_multiple_registers(std::uint16_t address, std::vector<std::uint16_t> values);
Reply exception_reply(std::uint8_t function, std::uint8_t code);

// Encoding validates quantities (1..max), value ranges (coil states 0/1) and address overflow
// (address + count - 1 <= FFFFh); an invalid request is ErrorKind::usage.
Result<Bytes> encode_request(const Request& request);
Result<Bytes> encode_reply(const Reply& reply);

// Decoding validates everything a receiver can check: known function, exact length, byte count
// consistent with quantity, quantity limits, coil values 0000h/FF00h, padding bits ignored.
// Unknown function codes are ErrorKind::malformed with a message naming the code.
Result<Request> decode_request(ByteView pdu);
Result<Reply> decode_reply(ByteView pdu);

// How long the PDU that starts with `prefix` will be, so a framer can delimit frames by length
// when timing is lost. nullopt: more bytes are needed to tell. 0: the function code gives no
// way to tell (unknown function); the caller must fall back to silence.
std::optional<std::size_t> expected_pdu_length(Direction direction, ByteView prefix);

// The reply answers the request: same function, address/quantity/value echoes, byte count
// matching the quantity asked for. On success FC1/2 values are trimmed to request.count.
// Exception replies for the same function pass (the caller turns them into errors).
Result<Reply> match_reply(const Request& request, Reply reply);

// Bit packing: lowest address in bit 0 of the first byte, padding bits zero.
Bytes pack_bits(const std::vector<std::uint16_t>& states);
std::vector<std::uint16_t> unpack_bits(ByteView packed, std::size_t count);

}  // namespace loopwire::codec
